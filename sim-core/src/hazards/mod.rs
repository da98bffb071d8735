//! Hazards the planner does not know: a stalled car, a walker stepping out from behind a parked
//! car, a cut-in, a hard-braking leader, a construction closure, an oncoming overtaker, a car
//! running the junction the ego crosses (after
//! CARLA scenario_runner's `srunner/scenarios/`). One per episode at most, placed on the ego's
//! route at a seeded distance ahead (`spawn.rs`), drawn from the episode's own hazard stream so
//! that an episode without one is bit-identical to one with hazards off.
//!
//! Their cars live in [`Traffic`] (other cars queue behind them and the model-based driver's
//! car-following sees them as it sees any car); their walkers and props (cones, a barrier, the
//! occluding parked car) live here. The route, `d` and the path features never know any of it.

pub mod config;
pub mod cut_in;
pub mod episodes;
pub mod kind;
pub mod prop;
pub mod runner;
pub mod spawn;
pub mod walker;

use serde::Serialize;

pub use self::config::HazardsConfig;
pub use self::kind::HazardKind;
pub use self::prop::{Prop, PropKind};
use self::walker::Walker;
use crate::collision::{CollisionKind, Obb};
use crate::map::LaneId;
use crate::route::Route;
use crate::town::Town;
use crate::traffic::Traffic;
use crate::vehicle::VehicleState;

/// The scripted behaviour of a hazard.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Script {
    /// Nothing moves (stalled car).
    Static,
    /// A construction closure of `lane`, its barrier at `barrier` along the lane: traffic stopped
    /// behind it turns off.
    Closure { lane: LaneId, barrier: f32 },
    /// The walkers start when the ego is `trigger_time` seconds from the crossing.
    Crossing { trigger_time: f32 },
    /// The leader brakes at its limit on reaching the hazard point, stands `stop_time` s, drives on.
    HardBrake { stop_time: f32, stopped_for: f32, released: bool },
    /// The car in the adjacent lane sets its speed by the ego's (`cut_in.rs`) and moves into
    /// `lane` once its rear is `gap` metres ahead of the ego's front along the route. `phase`: 0
    /// timing, 1 changing lanes, 2 done (driving on as traffic; also if the ego passes it first).
    CutIn { lane: LaneId, gap: f32, phase: u8, side: f32 },
    /// The oncoming car pulls `width` metres to its left (into the ego's lane) when near, holds
    /// for 30 m of its travel, and returns. `phase`: 0 waiting, 1 out, 2 returning, 3 done.
    Overtake { width: f32, out_for: f32, phase: u8 },
    /// The runner waits at rest on `approach`, starts when the ego is as many seconds from the
    /// crossing point (`along` its `connector`) as it needs to get there accelerating to `speed`,
    /// and takes `connector` without a reservation. `phase`: 0 waiting, 1 running, 2 across
    /// (driving on as traffic).
    JunctionRunner { approach: LaneId, connector: LaneId, along: f32, speed: f32, phase: u8 },
}

/// The hazard of an episode.
#[derive(Debug, Clone, PartialEq)]
pub struct Hazard {
    pub kind: HazardKind,
    /// Route arc length of the hazard's point (the stalled car, the crossing, the closure's start).
    pub s: f32,
    pub walkers: Vec<Walker>,
    pub props: Vec<Prop>,
    /// Its car's index in `Traffic::cars`, if it has one.
    pub car: Option<usize>,
    pub(crate) script: Script,
    /// Whether its script has fired (the walker started, the leader braked, the car cut in).
    pub triggered: bool,
}

/// The hazard as `StepInfo` reports it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HazardInfo {
    pub kind: HazardKind,
    /// Route distance from the start, metres.
    pub distance: f32,
    pub triggered: bool,
}

/// A car stopped this close behind a closure's barrier turns off, metres (centre to barrier).
const TURN_OFF_ROOM: f32 = 9.0;
/// Lateral speed of a scripted lane change, m/s.
const LANE_CHANGE_SPEED: f32 = 1.75;

impl Hazard {
    /// What `StepInfo` reports.
    #[must_use]
    pub fn info(&self) -> HazardInfo {
        HazardInfo { kind: self.kind, distance: self.s, triggered: self.triggered }
    }

    /// Advances the script by `dt` before traffic moves: triggers, forced accelerations, lane
    /// changes, walking. `ego_s` is the ego's arc length along `route`.
    pub fn step(&mut self, town: &Town, route: &Route, traffic: &mut Traffic, ego: &VehicleState, ego_s: f32, dt: f32) {
        let half = traffic.params.length / 2.0;
        match &mut self.script {
            Script::Static | Script::Closure { .. } => {}
            Script::Crossing { trigger_time } => {
                let to_go = self.s - ego_s - half;
                if !self.triggered && to_go < ego.speed.max(1.0) * *trigger_time {
                    self.triggered = true;
                    for w in &mut self.walkers {
                        w.walking = true;
                    }
                }
            }
            Script::HardBrake { stop_time, stopped_for, released } => {
                let Some(i) = self.car else { return };
                let c = &mut traffic.cars[i];
                if !c.active || *released {
                    return;
                }
                // On reaching the hazard point (measured along the ego's heading: cheap, and the
                // leader drives the route's lane ahead of it).
                if !self.triggered && (c.pos - route.path.point_at(self.s)).dot(route.path.tangent_at(self.s)) >= 0.0 {
                    self.triggered = true;
                }
                if self.triggered {
                    if c.speed > 0.0 {
                        // At its limit: the stop in this step, never below zero.
                        c.forced_accel = Some(-traffic.idm.max_decel.min(c.speed / dt));
                    } else {
                        c.forced_accel = Some(0.0);
                        *stopped_for += dt;
                        if *stopped_for >= *stop_time {
                            c.forced_accel = None;
                            *released = true;
                        }
                    }
                }
            }
            Script::CutIn { lane, gap, phase, side } => {
                let Some(i) = self.car else { return };
                if !traffic.cars[i].active {
                    return;
                }
                match *phase {
                    0 => {
                        // Bumper to bumper along the route (its lane runs beside the route's).
                        let window = (route.path.segment_at(ego_s), route.path.segment_at(ego_s + cut_in::WINDOW) + 1);
                        let car_s = route.path.project_range(traffic.cars[i].pos, window.0, window.1).s;
                        let ahead = car_s - ego_s - 2.0 * half;
                        if ahead <= 0.0 {
                            // The ego got past it: it drives on as traffic.
                            *phase = 2;
                            traffic.cars[i].forced_accel = None;
                        } else if ahead <= *gap {
                            *phase = 1;
                            self.triggered = true;
                            let c = &mut traffic.cars[i];
                            // It keeps the speed it changes lanes at, then drives on at it.
                            c.forced_accel = Some(0.0);
                            c.desired_speed = c.speed;
                            let p = town.map.lanes[*lane].path.project(c.pos);
                            let lateral = *side * p.distance;
                            traffic.move_to_lane(town, i, *lane, p.s, lateral);
                        } else {
                            let c = &mut traffic.cars[i];
                            let wanted = cut_in::wanted_speed(ahead, *gap, ego.speed, town.map.lanes[c.lane].speed_limit);
                            c.forced_accel = Some(((wanted - c.speed) / dt).clamp(-cut_in::ACCEL, cut_in::ACCEL));
                        }
                    }
                    1 => {
                        let c = &mut traffic.cars[i];
                        let step = LANE_CHANGE_SPEED * dt;
                        c.lateral = if c.lateral.abs() <= step { 0.0 } else { c.lateral - step * c.lateral.signum() };
                        if c.lateral == 0.0 {
                            c.forced_accel = None;
                            *phase = 2;
                        }
                    }
                    _ => {}
                }
            }
            Script::Overtake { width, out_for, phase } => {
                let Some(i) = self.car else { return };
                let c = &mut traffic.cars[i];
                if !c.active {
                    return;
                }
                let step = LANE_CHANGE_SPEED * dt;
                if c.speed < 0.5 && c.forced_accel.is_some() {
                    // Held at a stop line (its speed imposed would keep it there for good): it
                    // drives as traffic from then on, waiting for its reservation and moving on.
                    c.forced_accel = None;
                }
                match *phase {
                    0 => {
                        let gap = (c.pos - ego.pos).dot(ego.forward());
                        if gap < (ego.speed + c.speed) * 3.5 + 10.0 {
                            *phase = 1;
                            self.triggered = true;
                        }
                    }
                    1 => {
                        c.lateral = (c.lateral + step).min(*width);
                        *out_for += c.speed * dt;
                        if *out_for > 30.0 {
                            *phase = 2;
                        }
                    }
                    2 => {
                        c.lateral = (c.lateral - step).max(0.0);
                        if c.lateral == 0.0 {
                            *phase = 3;
                            c.forced_accel = None;
                        }
                    }
                    _ => {}
                }
            }
            Script::JunctionRunner { approach, connector, along, speed, phase } => {
                let Some(i) = self.car else { return };
                let c = &mut traffic.cars[i];
                if !c.active {
                    return;
                }
                // Its centre's distance to the crossing point, and the ego's time to it.
                let to_go = if c.lane == *approach { town.map.lanes[c.lane].path.length() - c.s + *along } else { *along - c.s };
                let ego_time = (self.s - ego_s) / ego.speed.max(1.0) + runner::LAG;
                match *phase {
                    0 if ego_time <= runner::time_from_rest(to_go, *speed, runner::RUNNER_ACCEL) => {
                        *phase = 1;
                        self.triggered = true;
                    }
                    1 => {
                        // Timed to meet the ego (which slows for a turn) until it commits.
                        let wanted =
                            if to_go > runner::COMMIT_DISTANCE { (to_go / ego_time).clamp(runner::MIN_SPEED, *speed) } else { *speed };
                        c.forced_accel = Some(((wanted - c.speed) / dt).clamp(-runner::RUNNER_ACCEL, runner::RUNNER_ACCEL));
                        // Into the junction without asking, at the line: a reservation taken
                        // earlier would hold the ego at its own line instead.
                        if c.lane == *approach && town.map.lanes[c.lane].path.length() - c.s < c.speed * dt * 2.0 + 0.5 {
                            c.hold = Some(*connector);
                        }
                        if c.lane != *approach && c.lane != *connector {
                            *phase = 2;
                            c.forced_accel = None;
                        }
                    }
                    _ => {}
                }
            }
        }
        for w in &mut self.walkers {
            w.step(dt);
        }
        traffic.yield_to.clear();
        traffic.yield_to.extend(self.walkers.iter().map(Walker::body));
        if self.kind == HazardKind::Construction
            && let Some(first) = self.props.first()
        {
            traffic.yield_to.push(first.body);
            // A car that has come to a stop at the barrier turns off there (it leaves and re-enters
            // elsewhere, as at a dead end): cars that cannot change lanes would otherwise queue
            // back through the junction behind and lock it for good.
            if let Script::Closure { lane, barrier } = self.script {
                let stopped: Vec<usize> = (0..traffic.cars.len())
                    .filter(|&i| {
                        let c = &traffic.cars[i];
                        c.active && !c.parked && c.lane == lane && c.speed < 0.1 && c.s < barrier && c.s > barrier - TURN_OFF_ROOM
                    })
                    .collect();
                for i in stopped {
                    traffic.remove(i);
                }
            }
        }
    }

    /// What of the hazard `body` overlaps, if anything (its cars are checked with traffic).
    #[must_use]
    pub fn hit(&self, body: &Obb) -> Option<CollisionKind> {
        if self.walkers.iter().any(|w| body.intersects(&w.body())) {
            return Some(CollisionKind::Pedestrian);
        }
        self.props.iter().find(|p| body.intersects(&p.body)).map(|p| p.kind.collision())
    }

    /// Feeds the hash of the dynamic state.
    pub(crate) fn hash_into(&self, write: &mut impl FnMut(u64)) {
        write(self.kind as u64);
        write(u64::from(self.triggered));
        for w in &self.walkers {
            write(u64::from(w.pos.x.to_bits()));
            write(u64::from(w.pos.y.to_bits()));
        }
        for p in &self.props {
            write(u64::from(p.body.centre.x.to_bits()));
        }
    }
}
