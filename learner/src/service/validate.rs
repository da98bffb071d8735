//! Checking a batch whole before anything of it is stored: its shape against the run (image
//! size, actions, path features, finite numbers within the run's physical bounds, `bounds.rs`), and its place in the actor's stream (a known
//! environment, `seq` increasing, each environment's steps moving forward, not empty).

use proto::v1 as pb;
use sim_core::env::PATH_FEATURES;
use sim_core::hazards::HazardKind;

use crate::service::bounds::Bounds;
use crate::shared_state::ActorRecord;
use crate::telemetry::records::{OUTCOME_ARRIVED, OUTCOME_COLLISION, OUTCOME_TIMEOUT, OUTCOMES};

/// Most steps one batch may carry.
pub const MAX_STEPS_PER_BATCH: usize = 4096;

/// What a batch is checked against.
#[derive(Debug, Clone, Copy)]
pub struct Expect {
    pub frame_bytes: usize,
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub actions: u32,
    pub path_features: bool,
    /// Values of the vector sensor's reading (`[env.vector]`), 0 when the run has none.
    pub vector_len: usize,
    pub bounds: Bounds,
}

/// Why a batch was refused.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Reject {
    /// `INVALID_ARGUMENT`.
    Invalid(String),
    /// `RESOURCE_EXHAUSTED`.
    TooLarge(String),
}

/// Checks a whole batch of `actor` (its current registration); on success returns each
/// environment's new position, for [`accept`].
pub fn check(x: &Expect, actor: &ActorRecord, b: &pb::ExperienceBatch) -> Result<Vec<Option<(u64, u32)>>, Reject> {
    let invalid = |m: String| Err(Reject::Invalid(format!("batch {}: {m}", b.seq)));
    if b.steps.len() > MAX_STEPS_PER_BATCH {
        return Err(Reject::TooLarge(format!("batch {} has {} steps; at most {MAX_STEPS_PER_BATCH} are accepted", b.seq, b.steps.len())));
    }
    if b.steps.is_empty() {
        return invalid("has no steps; empty batches are refused (a batch carries at least one step)".into());
    }
    // Demonstrations come from demonstrators alone, and demonstrators send nothing else: the
    // replay keeps the two apart, and neither may pass for the other.
    match (b.demonstration, actor.demonstrator.is_empty()) {
        (true, true) => {
            return invalid(format!(
                "marked as demonstrations, but actor `{}` registered as a learning actor (RegisterRequest.demonstrator empty); \
                 only a registration as a demonstrator may send demonstrations",
                actor.name
            ));
        }
        (false, false) => {
            return invalid(format!(
                "not marked as demonstrations, but actor `{}` registered as a demonstrator (`{}`); a demonstrator's batches \
                 are demonstrations (ExperienceBatch.demonstration = true)",
                actor.name, actor.demonstrator
            ));
        }
        _ => {}
    }
    if let Some(last) = actor.last_seq
        && b.seq <= last
    {
        return invalid(format!("seq {} does not follow {last}: seq must increase from batch to batch", b.seq));
    }
    let mut positions = actor.env_positions.clone();
    for (i, s) in b.steps.iter().enumerate() {
        let Some(obs) = &s.obs else {
            return invalid(format!("step {i}: no observation"));
        };
        if s.env >= actor.envs {
            return invalid(format!(
                "step {i}: env {} is beyond the {} environments this actor registered (0..{})",
                s.env, actor.envs, actor.envs
            ));
        }
        let here = (s.episode, s.t);
        let last = &mut positions[s.env as usize];
        if let Some(prev) = *last
            && here <= prev
        {
            return invalid(format!(
                "step {i}: env {} goes back from episode {}, t {} to episode {}, t {} (steps of an environment must move forward)",
                s.env, prev.0, prev.1, here.0, here.1
            ));
        }
        *last = Some(here);
        if obs.image.len() != x.frame_bytes {
            return invalid(format!(
                "step {i}: image has {} bytes; this run's camera is {}x{}x{} = {} bytes",
                obs.image.len(),
                x.width,
                x.height,
                x.channels,
                x.frame_bytes
            ));
        }
        if s.t > 0 && s.action >= x.actions {
            return invalid(format!("step {i}: action {} is out of range 0..{}", s.action, x.actions));
        }
        match obs.path.len() {
            0 if x.path_features => {
                return invalid(format!(
                    "step {i}: no path features, and this run's network needs them (agent.path_features = true); update the actor"
                ));
            }
            0 | PATH_FEATURES => {}
            n => return invalid(format!("step {i}: {n} path features; expected {PATH_FEATURES} or none")),
        }
        if obs.vector.len() != x.vector_len {
            let run = if x.vector_len == 0 {
                "this run has no vector sensor".to_owned()
            } else {
                format!("this run's [env.vector] reads {} values", x.vector_len)
            };
            return invalid(format!("step {i}: vector has {} values; {run}", obs.vector.len()));
        }
        if let Some((k, v)) = obs.vector.iter().enumerate().find(|(_, v)| !v.is_finite() || v.abs() > x.bounds.vector) {
            return invalid(format!(
                "step {i}: vector value {k} is {v}; the vector sensor's values are finite and within [-{b}, {b}]",
                b = x.bounds.vector
            ));
        }
        let path = obs.path.iter().map(|&v| ("path", v));
        for (name, v) in [("reward", s.reward), ("speed", obs.speed), ("d", obs.d)].into_iter().chain(path) {
            if !v.is_finite() {
                return invalid(format!("step {i}: {name} is {v}, not a finite number"));
            }
        }
        if let Some(m) = beyond_bounds(&x.bounds, s, obs) {
            return invalid(format!("step {i}: {m}"));
        }
        if s.terminated && s.truncated {
            return invalid(format!("step {i}: terminated and truncated at once"));
        }
    }
    for (i, e) in b.episodes.iter().enumerate() {
        if !e.episode_return.is_finite() {
            return invalid(format!("episode summary {i}: return is {}, not a finite number", e.episode_return));
        }
        if e.episode_return.abs() > x.bounds.episode_return {
            return invalid(format!(
                "episode summary {i}: return {} is beyond what this run's reward can add up to in an episode (|return| <= {})",
                e.episode_return, x.bounds.episode_return
            ));
        }
        if let Some(m) = bad_summary_names(e) {
            return invalid(format!("episode summary {i}: {m}"));
        }
    }
    if !(b.epsilon.is_finite() && (0.0..=1.0).contains(&b.epsilon)) {
        return invalid(format!("epsilon {} is outside [0, 1]", b.epsilon));
    }
    Ok(positions)
}

/// What, if anything, is wrong with a summary's hazard and outcome: an unknown hazard kind or
/// outcome, or an outcome its `arrived` and `collision` contradict. Refused like the other
/// malformed fields of a batch (not sanitised): they name TensorBoard tags and plot panels, and an
/// actor of the same build never sends them; empty is accepted from actors that predate them.
fn bad_summary_names(e: &pb::EpisodeSummary) -> Option<String> {
    if !e.hazard.is_empty() && HazardKind::from_name(&e.hazard).is_none() {
        return Some(format!("unknown hazard `{}` (known: {}, or empty for none)", e.hazard.escape_debug(), HazardKind::names()));
    }
    let collided = !e.collision.is_empty();
    let consistent = match e.outcome.as_str() {
        "" => true,
        OUTCOME_ARRIVED => e.arrived && !collided,
        OUTCOME_COLLISION => !e.arrived && collided,
        OUTCOME_TIMEOUT => !e.arrived && !collided,
        other => {
            return Some(format!("unknown outcome `{}` (known: {}, or empty)", other.escape_debug(), OUTCOMES.join(", ")));
        }
    };
    (!consistent)
        .then(|| format!("outcome `{}` contradicts arrived = {} and collision `{}`", e.outcome, e.arrived, e.collision.escape_debug()))
}

/// Which number of a step, if any, is beyond the run's physical bounds, and by what bound.
fn beyond_bounds(b: &Bounds, s: &pb::Step, obs: &pb::Observation) -> Option<String> {
    if obs.speed.abs() > b.speed {
        return Some(format!(
            "speed {} m/s is beyond what the vehicle can reach (|speed| <= {} m/s: 2 x env.vehicle.max_speed + 1)",
            obs.speed, b.speed
        ));
    }
    if obs.d.abs() > b.distance {
        return Some(format!(
            "d {} m is beyond how far the vehicle can get from its route (|d| <= {} m: 2 x (the longest route + an episode at top speed) + 1)",
            obs.d, b.distance
        ));
    }
    if let Some(&lateral) = obs.path.first()
        && lateral.abs() > b.distance
    {
        return Some(format!(
            "path feature 0 (lateral offset) {lateral} m is beyond how far the vehicle can get from its route (|x| <= {} m)",
            b.distance
        ));
    }
    for (k, &a) in obs.path.iter().enumerate().skip(1) {
        if a.abs() > b.angle {
            return Some(format!("path feature {k} (an angle) {a} rad is beyond ±π (|x| <= {} rad)", b.angle));
        }
    }
    let (lo, hi) = b.reward;
    if !(lo..=hi).contains(&s.reward) {
        return Some(format!(
            "reward {} is beyond what this run's reward (env.reward, with its clip) can produce ([{lo}, {hi}] with margin)",
            s.reward
        ));
    }
    None
}

/// Records an accepted batch's place in the actor's stream.
pub fn accept(actor: &mut ActorRecord, b: &pb::ExperienceBatch, positions: Vec<Option<(u64, u32)>>) {
    actor.last_seq = Some(b.seq);
    actor.env_positions = positions;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn expect() -> Expect {
        Expect {
            frame_bytes: 4,
            width: 2,
            height: 2,
            channels: 1,
            actions: 6,
            path_features: false,
            vector_len: 0,
            bounds: Bounds::of(&sim_core::config::EnvConfig::default()),
        }
    }

    fn step(env: u32, episode: u64, t: u32) -> pb::Step {
        pb::Step {
            env,
            episode,
            t,
            obs: Some(pb::Observation { image: vec![0; 4], speed: 1.0, d: 0.5, path: vec![], vector: Vec::new() }),
            action: 1,
            ..pb::Step::default()
        }
    }

    fn batch(seq: u64, steps: Vec<pb::Step>) -> pb::ExperienceBatch {
        pb::ExperienceBatch { actor_id: "x".into(), seq, steps, epsilon: 0.5, ..pb::ExperienceBatch::default() }
    }

    fn refused(r: Result<Vec<Option<(u64, u32)>>, Reject>) -> String {
        match r {
            Err(Reject::Invalid(m)) => m,
            other => panic!("expected INVALID_ARGUMENT, got {other:?}"),
        }
    }

    #[test]
    fn a_batch_must_fit_the_actors_stream() {
        let mut a = ActorRecord::new("x".into(), "n".into(), 0, 2);
        let first = batch(5, vec![step(0, 0, 0), step(1, 0, 0), step(0, 0, 1)]);
        let pos = check(&expect(), &a, &first).unwrap();
        accept(&mut a, &first, pos);
        assert_eq!(a.env_positions, vec![Some((0, 1)), Some((0, 0))]);

        // An environment beyond the registered count.
        let m = refused(check(&expect(), &a, &batch(6, vec![step(2, 0, 0)])));
        assert_eq!(m, "batch 6: step 0: env 2 is beyond the 2 environments this actor registered (0..2)");
        // seq not increasing (repeated, or backwards).
        for seq in [5, 4] {
            let m = refused(check(&expect(), &a, &batch(seq, vec![step(0, 0, 2)])));
            assert_eq!(m, format!("batch {seq}: seq {seq} does not follow 5: seq must increase from batch to batch"));
        }
        // An environment going backwards, across batches and within one.
        let m = refused(check(&expect(), &a, &batch(6, vec![step(0, 0, 1)])));
        assert!(m.contains("env 0 goes back from episode 0, t 1 to episode 0, t 1"), "{m}");
        let m = refused(check(&expect(), &a, &batch(6, vec![step(1, 3, 0), step(1, 2, 9)])));
        assert!(m.contains("step 1: env 1 goes back from episode 3, t 0 to episode 2, t 9"), "{m}");
        // Empty.
        let m = refused(check(&expect(), &a, &batch(6, vec![])));
        assert!(m.contains("has no steps; empty batches are refused"), "{m}");
        // Refusals change nothing: the next good batch (gaps allowed: batches may be dropped)
        // is accepted.
        assert_eq!(a.last_seq, Some(5));
        check(&expect(), &a, &batch(9, vec![step(0, 1, 0), step(1, 0, 7)])).unwrap();
    }

    #[test]
    fn summaries_name_known_hazards_and_outcomes_that_fit_their_flags() {
        let a = ActorRecord::new("x".into(), "n".into(), 0, 1);
        let summary = |hazard: &str, outcome: &str, arrived: bool, collision: &str| pb::EpisodeSummary {
            hazard: hazard.into(),
            outcome: outcome.into(),
            arrived,
            collision: collision.into(),
            steps: 5,
            ..pb::EpisodeSummary::default()
        };
        let with =
            |e: pb::EpisodeSummary| check(&expect(), &a, &pb::ExperienceBatch { episodes: vec![e], ..batch(1, vec![step(0, 0, 1)]) });
        for e in [
            summary("stalled_car", "arrived", true, ""),
            summary("cut_in", "collision", false, "vehicle"),
            summary("", "timeout", false, ""),
            // From an actor that predates both fields.
            summary("", "", true, ""),
        ] {
            with(e.clone()).unwrap_or_else(|r| panic!("{e:?} refused: {r:?}"));
        }
        let m = refused(with(summary("meteor", "arrived", true, "")));
        assert!(m.starts_with("batch 1: episode summary 0: unknown hazard `meteor` (known: stalled_car, "), "{m}");
        let m = refused(with(summary("", "crashed", false, "vehicle")));
        assert_eq!(m, "batch 1: episode summary 0: unknown outcome `crashed` (known: arrived, collision, timeout, or empty)");
        let m = refused(with(summary("", "timeout", false, "building")));
        assert_eq!(m, "batch 1: episode summary 0: outcome `timeout` contradicts arrived = false and collision `building`");
        let m = refused(with(summary("hard_brake", "arrived", false, "")));
        assert!(m.contains("outcome `arrived` contradicts arrived = false"), "{m}");
    }

    #[test]
    fn physically_impossible_numbers_are_refused_naming_the_bound() {
        let a = ActorRecord::new("x".into(), "n".into(), 0, 1);
        let with = |f: &dyn Fn(&mut pb::Step)| {
            let mut s = step(0, 0, 1);
            f(&mut s);
            refused(check(&expect(), &a, &batch(1, vec![s])))
        };
        let m = with(&|s| s.obs.as_mut().unwrap().speed = 1e30);
        assert!(m.contains("speed 1000000000000000000000000000000 m/s is beyond") && m.contains("<= 61 m/s"), "{m}");
        let m = with(&|s| s.obs.as_mut().unwrap().d = -1e30);
        assert!(m.contains("d -1000000000000000000000000000000 m is beyond") && m.contains("<= 2101 m"), "{m}");
        let m = with(&|s| s.reward = 3e38);
        assert!(m.contains("reward 300000000000000000000000000000000000000 is beyond") && m.contains("201]"), "{m}");
        let m = with(&|s| s.obs.as_mut().unwrap().path = vec![0.0, 7.0, 0.0]);
        assert!(m.contains("path feature 1 (an angle) 7 rad"), "{m}");
        // The largest real values pass: top speed, arrival's reward.
        let mut s = step(0, 0, 1);
        s.obs.as_mut().unwrap().speed = 30.0;
        s.reward = 100.0;
        check(&expect(), &a, &batch(1, vec![s])).unwrap();
    }
}
