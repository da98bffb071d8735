//! Reference behaviours for checking how a reward ranks outcomes: on a hazard episode, driving
//! round the hazard (`model-based-avoid`), stopping short of it and waiting, and driving into it;
//! on a clean route, the blind planner and standing still. Each episode's discounted return is
//! the one a trained agent's reward would give it: always measured on the blind A* planner's
//! waypoints, as the agent is trained.
//!
//! The drivers are reference behaviours, not agents: the stopping and crashing drivers read the
//! hazard's position (ground truth no reward or agent sees) to stop short of it or to keep going
//! into it. The test `reward_ordering` and the example of the same name share them.

use std::sync::Arc;

use crate::collision::CollisionKind;
use crate::config::EnvConfig;
use crate::env::{Env, EnvError};
use crate::expert::Expert;
use crate::hazards::episodes::use_suite_episodes;
use crate::hazards::{HazardKind, HazardsConfig};
use crate::planner::PlannerKind;
use crate::reward::RewardConfig;
use crate::scenario::{EvalRoute, Scenario};
use crate::town::Town;
use crate::vehicle::Action;

/// The discount of the training presets.
pub const GAMMA: f64 = 0.99;

/// What a set of reference episodes drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Case {
    /// The hazard suite's episodes (random routes, `hazards::episodes`) with this kind, each
    /// driven by [`Behaviour::Avoid`], [`Behaviour::Stop`] and [`Behaviour::Crash`].
    Hazard(HazardKind),
    /// The evaluation routes without hazards, each driven by [`Behaviour::Planner`] and
    /// [`Behaviour::StandStill`].
    Clean,
}

impl Case {
    /// The cases checked: a car stopped in the lane, a lane closure and a walker crossing (the
    /// hazards a driver must stop for or drive round), and the clean routes.
    pub const ALL: [Case; 4] = [
        Case::Hazard(HazardKind::StalledCar),
        Case::Hazard(HazardKind::Construction),
        Case::Hazard(HazardKind::PedestrianCrossing),
        Case::Clean,
    ];

    /// The name in reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Case::Hazard(k) => k.name(),
            Case::Clean => "clean routes",
        }
    }

    /// The behaviours compared, best first: the order a reward should rank them in.
    #[must_use]
    pub fn behaviours(self) -> &'static [Behaviour] {
        match self {
            Case::Hazard(_) => &[Behaviour::Avoid, Behaviour::Stop, Behaviour::Crash],
            Case::Clean => &[Behaviour::Planner, Behaviour::StandStill],
        }
    }

    /// The scoring environment's configuration with `reward`: the default world without a camera
    /// and the blind `astar` planner, on the case's episodes.
    #[must_use]
    pub fn config(self, reward: RewardConfig) -> EnvConfig {
        let mut cfg = EnvConfig { camera: None, reward, planner: PlannerKind::Astar, ..EnvConfig::default() };
        if let Case::Hazard(kind) = self {
            cfg.hazards = HazardsConfig::only(kind);
            use_suite_episodes(&mut cfg);
        }
        cfg
    }

    /// The episodes of seeds `0..seeds`: a random route each for a hazard kind, every evaluation
    /// route each for the clean case.
    #[must_use]
    pub fn episodes(self, seeds: u64) -> Vec<(u64, Scenario)> {
        match self {
            Case::Hazard(_) => (0..seeds).map(|s| (s, Scenario::Random)).collect(),
            Case::Clean => EvalRoute::ALL.iter().flat_map(|&r| (0..seeds).map(move |s| (s, Scenario::Eval(r)))).collect(),
        }
    }
}

/// A behaviour's scored episodes.
#[derive(Debug, Clone, PartialEq)]
pub struct Tally {
    pub behaviour: Behaviour,
    pub episodes: Vec<Scored>,
}

impl Tally {
    /// The mean discounted return.
    #[must_use]
    pub fn mean(&self) -> f64 {
        self.episodes.iter().map(|e| e.discounted_return).sum::<f64>() / self.episodes.len().max(1) as f64
    }

    /// How many episodes arrived, ended in a collision, and ran out of time.
    #[must_use]
    pub fn ends(&self) -> (usize, usize, usize) {
        let count = |f: fn(&End) -> bool| self.episodes.iter().filter(|e| f(&e.end)).count();
        (count(|e| *e == End::Arrived), count(|e| matches!(e, End::Collision(_))), count(|e| *e == End::Truncated))
    }
}

/// Drives `case`'s episodes of seeds `0..seeds` on `town` with each of its behaviours, scored
/// with `reward` discounted by `gamma`; the tallies in [`Case::behaviours`]' order.
pub fn score_case(town: &Arc<Town>, case: Case, reward: RewardConfig, seeds: u64, gamma: f64) -> Result<Vec<Tally>, EnvError> {
    let mut runs = ReferenceRuns::new(town, &case.config(reward))?;
    let episodes = case.episodes(seeds);
    case.behaviours()
        .iter()
        .map(|&behaviour| {
            let scored = episodes.iter().map(|&(seed, scenario)| runs.run(seed, scenario, behaviour, gamma)).collect::<Result<_, _>>()?;
            Ok(Tally { behaviour, episodes: scored })
        })
        .collect()
}

/// Whether the mean returns fall strictly in the tallies' order (best behaviour first).
#[must_use]
pub fn ranked_in_order(tallies: &[Tally]) -> bool {
    tallies.windows(2).all(|w| w[0].mean() > w[1].mean())
}

/// A reference behaviour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Behaviour {
    /// `model-based-avoid`: [`Expert::avoiding`] following the `astar+avoid` planner round
    /// obstacles, braking for walkers and hazard cars.
    Avoid,
    /// The blind planner's driver ([`Expert::default`]) until the hazard is within its braking
    /// distance and a margin, then full brake to a standstill, and waiting there.
    Stop,
    /// The blind planner's driver until the hazard is near, then holding v0 without braking, into
    /// the hazard.
    Crash,
    /// The blind planner's driver as it is (for clean routes).
    Planner,
    /// Full brake every step.
    StandStill,
}

impl Behaviour {
    /// The name in reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Behaviour::Avoid => "avoid",
            Behaviour::Stop => "stop",
            Behaviour::Crash => "crash",
            Behaviour::Planner => "planner",
            Behaviour::StandStill => "stand still",
        }
    }
}

/// How an episode ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    Arrived,
    Collision(CollisionKind),
    /// The time limit.
    Truncated,
}

/// One reference episode, scored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scored {
    /// Σ γ^t·r_t over the episode, t from 0, under the scoring environment's reward.
    pub discounted_return: f64,
    pub end: End,
    pub steps: u32,
    /// The largest distance between the scoring and the driving environments' egos, metres
    /// ([`Behaviour::Avoid`]; 0 otherwise). The planner changes no part of the world, so it
    /// is 0 unless that stops being true.
    pub shadow_gap: f32,
}

/// Braking assumed when deciding to stop, m/s²: below the vehicle's full brake, so that the
/// full brake then used stops with room to spare.
const STOP_DECEL: f32 = 4.0;
/// Room left before the hazard's first obstacle when stopped, metres, at least.
const STOP_MARGIN: f32 = 3.0;
/// How far before the hazard's route point its first obstacle may be, metres (a construction
/// closure's cone taper starts 4 m before its barrier).
const HAZARD_LEAD: f32 = 5.0;
/// Gap to the hazard below which the crashing driver stops braking for anything, metres: far
/// enough that the blind driver has not yet slowed for it.
const CRASH_COMMIT: f32 = 40.0;

/// Runs reference episodes: the scoring environment (its configuration's reward and planner,
/// which should be `astar`, as an agent is trained) and, for [`Behaviour::Avoid`], a driving
/// shadow on the `astar+avoid` planner, the same otherwise.
#[derive(Debug, Clone)]
pub struct ReferenceRuns {
    score: Env,
    shadow: Env,
}

impl ReferenceRuns {
    /// Environments on `town` with `cfg`.
    pub fn new(town: &Arc<Town>, cfg: &EnvConfig) -> Result<Self, EnvError> {
        let score = Env::new(town.clone(), cfg.clone())?;
        let shadow = Env::new(town.clone(), EnvConfig { planner: PlannerKind::AstarAvoid, ..cfg.clone() })?;
        Ok(Self { score, shadow })
    }

    /// Drives the episode of `seed` and `scenario` with `behaviour`, returning its return
    /// discounted by `gamma`.
    pub fn run(&mut self, seed: u64, scenario: Scenario, behaviour: Behaviour, gamma: f64) -> Result<Scored, EnvError> {
        self.score.reset(seed, scenario)?;
        let shadowed = behaviour == Behaviour::Avoid;
        if shadowed {
            self.shadow.reset(seed, scenario)?;
        }
        let (blind, avoiding) = (Expert::default(), Expert::avoiding());
        let (mut discounted_return, mut discount, mut shadow_gap) = (0.0, 1.0, 0.0f32);
        let mut braking = false;
        loop {
            let env = &self.score;
            let action = match behaviour {
                Behaviour::Avoid => avoiding.act(&self.shadow),
                Behaviour::Planner => blind.act(env),
                Behaviour::StandStill => Action::new(0.0, 1.0, 0.0),
                Behaviour::Stop => {
                    let a = blind.act(env);
                    let v = env.ego.speed;
                    braking |= hazard_gap(env).is_some_and(|g| g <= v * v / (2.0 * STOP_DECEL) + STOP_MARGIN);
                    if braking { Action::new(0.0, 1.0, a.steer) } else { a }
                }
                Behaviour::Crash => {
                    let a = blind.act(env);
                    if hazard_gap(env).is_some_and(|g| g <= CRASH_COMMIT) {
                        let throttle = if env.ego.speed < env.cfg.reward.v0() { 1.0 } else { 0.0 };
                        Action::new(throttle, 0.0, a.steer)
                    } else {
                        a
                    }
                }
            };
            let r = self.score.step(action)?;
            if shadowed {
                self.shadow.step(action)?;
                shadow_gap = shadow_gap.max(self.score.ego.pos.distance(self.shadow.ego.pos));
            }
            discounted_return += discount * f64::from(r.reward);
            discount *= gamma;
            if r.terminated || r.truncated {
                let end = match (r.info.collision, r.info.arrived) {
                    (Some(kind), _) => End::Collision(kind),
                    (None, true) => End::Arrived,
                    (None, false) => End::Truncated,
                };
                return Ok(Scored { discounted_return, end, steps: r.info.steps, shadow_gap });
            }
        }
    }
}

/// Route distance from the ego's front to the hazard's first obstacle, if the episode has a
/// hazard not yet passed.
fn hazard_gap(env: &Env) -> Option<f32> {
    let h = env.hazard.as_ref()?;
    let gap = h.s - HAZARD_LEAD - env.tracking.s - env.cfg.vehicle.length / 2.0;
    (h.s > env.tracking.s).then_some(gap)
}
