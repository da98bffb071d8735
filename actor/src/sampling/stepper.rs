//! An actor's stepping thread: N environments, one batched greedy forward pass for all of them
//! per step, ε-greedy or ε-z-greedy exploration (`explore.rs`), and the steps handed to the outbox
//! in batches. New weights are swapped in between steps; it waits on the learner only while one
//! that is taking batches has several waiting (`Link::wait_for_room`: the replay ratio's
//! backpressure). A demonstrator's thread drives with its teacher instead (`demonstrator.rs`):
//! no network, no exploration.

use std::sync::Arc;
use std::sync::atomic::Ordering;

use agent::config::RunConfig;
use agent::fastnet::Inference;
use anyhow::Result;
use proto::v1 as pb;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::env::{Env, StepInfo};
use sim_core::scenario::Scenario;
use sim_core::town::Town;

use crate::sampling::demonstrator::{Demonstrator, Teacher};
use crate::sampling::explore::Explorer;
use crate::sampling::outbox::{Link, ROOM_BATCHES};

/// The environments and the policy: runs until stop.
#[allow(clippy::too_many_arguments)]
pub fn step_loop(
    cfg: &RunConfig,
    town: &Arc<Town>,
    link: &Link,
    n: usize,
    seed: u64,
    index: u32,
    episode_stream: u64,
    batch_steps: usize,
    buffer_steps: usize,
    demonstrator: Option<Demonstrator>,
) -> Result<()> {
    anyhow::ensure!(cfg.env.camera.is_some() || cfg.env.vector.is_some(), "the run has neither a camera nor the vector sensor");
    let shape = cfg.net_shape();
    // One thread: an actor's batch is a few frames, and actors share the cores with each other
    // and the learner.
    let (mut net, arithmetic) = Inference::with_precision(shape, cfg.agent.seed, 1, cfg.agent.precision);
    tracing::info!(bf16 = arithmetic.bf16, "acting in {} ({})", arithmetic.arithmetic(), arithmetic.reason);
    let actions = cfg.agent.action_set.actions();
    let mut rng = episode_rng(seed, index, episode_stream);
    let mut envs: Vec<Env> = (0..n).map(|_| Env::new(town.clone(), cfg.env.clone())).collect::<Result<_, _>>()?;
    let mut teacher = demonstrator.map(|d| Teacher::new(d, cfg, town, n)).transpose()?;
    let mut explorer = Explorer::new(&cfg.agent, n);
    let mut episode = vec![0u64; n];
    let mut t = vec![0u32; n];
    let mut returns = vec![0f64; n];
    let mut pending: Vec<pb::Step> = Vec::new();
    let mut summaries: Vec<pb::EpisodeSummary> = Vec::new();
    // The wire form of an observation: the newest frame only (it takes the image the environment
    // already copied out when that is the frame); the learner's replay stacks frames itself.
    let wire = |o: sim_core::env::Observation, newest: &sim_core::camera::Image| -> pb::Observation {
        pb::Observation {
            image: match o.image {
                Some(i) if i.channels == newest.channels => i.data,
                Some(_) => newest.data.clone(),
                None => Vec::new(),
            },
            speed: o.speed,
            d: o.d.unwrap_or(0.0),
            path: o.path.map(Vec::from).unwrap_or_default(),
            vector: o.vector.unwrap_or_default(),
        }
    };
    let episode_seed = |rng: &mut ChaCha8Rng| rng.next_u64();
    for (k, env) in envs.iter_mut().enumerate() {
        let seed = episode_seed(&mut rng);
        if k == 0 {
            // Said once, so that a restart can be seen to continue with new episodes.
            tracing::info!(episode_stream, first_episode_seed = seed, "environments starting");
        }
        env.reset(seed, Scenario::Random)?;
        if let Some(t) = teacher.as_mut() {
            t.reset(k, seed, Scenario::Random)?;
        }
        pending.push(pb::Step { env: k as u32, episode: 0, t: 0, obs: Some(wire(env.observation(), env.image())), ..pb::Step::default() });
    }
    let mut total_steps = 0u64;
    while !link.stop.load(Ordering::SeqCst) {
        // A demonstrator waits rather than drops: its steps are not the run's, and the cores are
        // the learner's and the learning actors' (it also waits while the learner holds its
        // stream, which a learning actor waits for only while the learner acknowledges).
        if teacher.is_some()
            && (link.demo_pause.load(Ordering::SeqCst) || link.outbox.lock().expect("outbox lock").batches.len() > ROOM_BATCHES)
        {
            std::thread::sleep(std::time::Duration::from_millis(50));
            continue;
        }
        if let Some((version, params)) = link.fresh_weights.lock().expect("weights lock").take() {
            net.set_params(params);
            link.acting_version.store(version, Ordering::SeqCst);
        }
        // One batched forward pass for all environments (a demonstrator's teacher needs none).
        let (greedy, epsilon) = match &teacher {
            Some(t) => ((0..n).map(|k| t.act(k)).collect(), 0.0),
            None => {
                let scalars = agent::features::env_inputs(cfg, envs.iter());
                let greedy = net.greedy(envs.iter().map(|e| e.stacked_image().data.as_slice()), &scalars);
                (greedy, cfg.epsilon(index, link.run_env_steps(total_steps)))
            }
        };
        for (k, env) in envs.iter_mut().enumerate() {
            let a = if teacher.is_some() { greedy[k] } else { explorer.choose(k, greedy[k], epsilon, actions.len(), &mut rng) };
            let r = env.step(actions[a as usize])?;
            if let Some(t) = teacher.as_mut() {
                t.step(k, actions[a as usize])?;
            }
            t[k] += 1;
            returns[k] += f64::from(r.reward);
            pending.push(pb::Step {
                env: k as u32,
                episode: episode[k],
                t: t[k],
                obs: Some(wire(r.observation, env.image())),
                action: a,
                reward: r.reward,
                terminated: r.terminated,
                truncated: r.truncated,
            });
            if r.terminated || r.truncated {
                summaries.push(summary(k as u32, episode[k], returns[k], t[k], r.truncated, &r.info));
                episode[k] += 1;
                t[k] = 0;
                returns[k] = 0.0;
                explorer.episode_ended(k);
                let seed = episode_seed(&mut rng);
                env.reset(seed, Scenario::Random)?;
                if let Some(t) = teacher.as_mut() {
                    t.reset(k, seed, Scenario::Random)?;
                }
                pending.push(pb::Step {
                    env: k as u32,
                    episode: episode[k],
                    t: 0,
                    obs: Some(wire(env.observation(), env.image())),
                    ..pb::Step::default()
                });
            }
        }
        total_steps += n as u64;
        link.env_steps.store(total_steps, Ordering::SeqCst);
        if pending.len() >= batch_steps {
            let steps = std::mem::take(&mut pending);
            let eps = std::mem::take(&mut summaries);
            let version = link.acting_version.load(Ordering::SeqCst);
            link.outbox.lock().expect("outbox lock").push_bounded((steps, eps, epsilon, version), buffer_steps);
            link.wait_for_room();
        }
    }
    // Hand over what is left for the final flush.
    if !pending.is_empty() {
        let mut ob = link.outbox.lock().expect("outbox lock");
        ob.steps += pending.len();
        ob.batches.push_back((
            pending,
            summaries,
            if teacher.is_some() { 0.0 } else { cfg.epsilon(index, link.run_env_steps(total_steps)) },
            link.acting_version.load(Ordering::SeqCst),
        ));
    }
    Ok(())
}

/// The summary of a finished episode from its final step: whether that step was truncated (else
/// it was terminated) and its info. The hazard is the final step's info's (an episode keeps its
/// hazard from reset to its end); the outcome is the step's: arrived or collision when
/// terminated, timeout when truncated.
pub fn summary(env: u32, episode: u64, episode_return: f64, steps: u32, truncated: bool, info: &StepInfo) -> pb::EpisodeSummary {
    let outcome = if truncated {
        pb::outcome::TIMEOUT
    } else if info.arrived {
        pb::outcome::ARRIVED
    } else {
        pb::outcome::COLLISION
    };
    pb::EpisodeSummary {
        env,
        episode,
        episode_return: episode_return as f32,
        steps,
        arrived: info.arrived,
        collision: info.collision.map(|c| c.name().to_owned()).unwrap_or_default(),
        scenario: "random".into(),
        hazard: info.hazard.map(|h| h.kind.name().to_owned()).unwrap_or_default(),
        outcome: outcome.to_owned(),
    }
}

/// The random stream of an actor's episode seeds and exploration: from the run's seed, the
/// actor's index and the learner's `episode_stream` for this registration. Stream 0 (a fresh run's
/// first life of the actor) is the stream actors have always drawn from; a restarted actor gets
/// another one, so that it does not replay its first life's routes and traffic.
pub fn episode_rng(seed: u64, index: u32, episode_stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (u64::from(index) << 32));
    rng.set_stream(episode_stream);
    rng
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summaries_carry_the_episodes_hazard_and_how_it_ended() {
        use sim_core::collision::CollisionKind;
        use sim_core::config::EnvConfig;
        use sim_core::hazards::{HazardKind, HazardsConfig};
        use sim_core::vehicle::Action;

        // Standing still behind a stalled car: the episode runs into its short time limit.
        let cfg = EnvConfig { time_limit: 20, hazards: HazardsConfig::only(HazardKind::StalledCar), ..EnvConfig::default() };
        let mut env = Env::new(Town::default_town(), cfg).unwrap();
        env.reset(3, Scenario::Random).unwrap();
        let last = loop {
            let r = env.step(Action::new(0.0, 1.0, 0.0)).unwrap();
            if r.terminated || r.truncated {
                break r;
            }
        };
        assert!(last.truncated, "{last:?}");
        let s = summary(2, 7, -1.5, 20, last.truncated, &last.info);
        assert_eq!((s.env, s.episode, s.episode_return, s.steps), (2, 7, -1.5, 20));
        assert_eq!((s.hazard.as_str(), s.outcome.as_str(), s.arrived, s.collision.as_str()), ("stalled_car", "timeout", false, ""));

        // The same step, ended otherwise.
        let ended = |arrived: bool, collision: Option<CollisionKind>| {
            let mut info = last.info.clone();
            (info.arrived, info.collision) = (arrived, collision);
            summary(0, 0, 0.0, 1, false, &info)
        };
        let s = ended(true, None);
        assert_eq!((s.outcome.as_str(), s.arrived), ("arrived", true));
        let s = ended(false, Some(CollisionKind::Vehicle));
        assert_eq!((s.outcome.as_str(), s.collision.as_str()), ("collision", "vehicle"));
        let mut plain = last.info.clone();
        plain.hazard = None;
        assert_eq!(summary(0, 0, 0.0, 1, true, &plain).hazard, "", "no hazard: empty");
    }

    #[test]
    fn stream_zero_is_the_original_stream_and_others_differ() {
        let draw = |mut r: ChaCha8Rng| (0..4).map(|_| r.next_u64()).collect::<Vec<_>>();
        let original = draw(ChaCha8Rng::seed_from_u64(7 ^ (3u64 << 32)));
        assert_eq!(draw(episode_rng(7, 3, 0)), original, "a fresh run's episodes are unchanged");
        let restarted = draw(episode_rng(7, 3, 1 + (5000 << 16 | 2)));
        assert_ne!(restarted, original);
        assert_ne!(restarted, draw(episode_rng(7, 3, 1 + (5000 << 16 | 3))));
    }
}
