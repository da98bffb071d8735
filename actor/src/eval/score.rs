//! The field's driving score, after the CARLA leaderboard (`leaderboard/utils/statistics_manager.py`):
//! a run's driving score is its route completion times its infraction penalty, the product of one
//! factor per infraction — pedestrian collision 0.50, vehicle 0.60, static object 0.65, junction
//! right-of-way violation 0.70 (the leaderboard's red light), timeout 0.70 (its scenario timeout).
//! Off-road and blocked (no progress for 30 s) end the run without a factor: they cost the
//! completion that was not driven. Success is NoCrash's: arrival with no infraction.

use serde::Serialize;
use sim_core::collision::CollisionKind;

use super::behaviour::Behaviour;

/// An infraction of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Infraction {
    PedestrianCollision,
    VehicleCollision,
    StaticCollision,
    OffRoad,
    Blocked,
    Timeout,
    RightOfWay,
}

impl Infraction {
    /// Every kind, in report order.
    pub const ALL: [Infraction; 7] = [
        Infraction::PedestrianCollision,
        Infraction::VehicleCollision,
        Infraction::StaticCollision,
        Infraction::OffRoad,
        Infraction::Blocked,
        Infraction::Timeout,
        Infraction::RightOfWay,
    ];

    /// The name in reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Infraction::PedestrianCollision => "pedestrian_collision",
            Infraction::VehicleCollision => "vehicle_collision",
            Infraction::StaticCollision => "static_collision",
            Infraction::OffRoad => "off_road",
            Infraction::Blocked => "blocked",
            Infraction::Timeout => "timeout",
            Infraction::RightOfWay => "right_of_way",
        }
    }

    /// The leaderboard's penalty factor (1 for those that end the run instead).
    #[must_use]
    pub fn factor(self) -> f64 {
        match self {
            Infraction::PedestrianCollision => 0.50,
            Infraction::VehicleCollision => 0.60,
            Infraction::StaticCollision => 0.65,
            Infraction::RightOfWay | Infraction::Timeout => 0.70,
            Infraction::OffRoad | Infraction::Blocked => 1.0,
        }
    }

    /// The infraction a collision is.
    #[must_use]
    pub fn of_collision(kind: CollisionKind) -> Self {
        match kind {
            CollisionKind::Pedestrian => Infraction::PedestrianCollision,
            CollisionKind::Vehicle | CollisionKind::ParkedCar => Infraction::VehicleCollision,
            CollisionKind::Building | CollisionKind::Pole | CollisionKind::Pillar | CollisionKind::Construction => {
                Infraction::StaticCollision
            }
            CollisionKind::OffRoad => Infraction::OffRoad,
        }
    }
}

/// Seconds without progress after which a run is blocked.
pub const BLOCKED_SECONDS: f32 = 30.0;
/// Progress smaller than this does not count as progress, metres.
const PROGRESS_EPSILON: f32 = 0.5;

/// The score of one run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunScore {
    pub seed: u64,
    /// Fraction of the route driven, 0 to 1 (1 on arrival).
    pub route_completion: f64,
    pub infraction_penalty: f64,
    pub driving_score: f64,
    pub success: bool,
    pub infractions: Vec<Infraction>,
    /// Route length driven, km.
    pub km: f64,
    /// The paper's return.
    #[serde(rename = "return")]
    pub ret: f64,
    pub steps: u32,
    /// The hazard the run had (`null` for none) and whether it fired.
    pub hazard: Option<&'static str>,
    pub hazard_triggered: bool,
    /// How it drove around the hazard (`behaviour.rs`).
    pub behaviour: Behaviour,
}

/// The product of the infractions' factors.
#[must_use]
pub fn penalty(infractions: &[Infraction]) -> f64 {
    infractions.iter().map(|i| i.factor()).product()
}

/// Route completion × infraction penalty.
#[must_use]
pub fn driving_score(completion: f64, infractions: &[Infraction]) -> f64 {
    completion * penalty(infractions)
}

/// Follows a run step by step: its best progress along the route and whether it is blocked.
#[derive(Debug, Clone, Default)]
pub struct ProgressWatch {
    best: f32,
    stalled_for: f32,
}

impl ProgressWatch {
    /// Records the progress (metres along the route) after a step of `dt` seconds; returns
    /// whether the run is now blocked.
    pub fn record(&mut self, metres: f32, dt: f32) -> bool {
        if metres > self.best + PROGRESS_EPSILON {
            self.best = metres;
            self.stalled_for = 0.0;
        } else {
            self.stalled_for += dt;
        }
        self.stalled_for >= BLOCKED_SECONDS
    }
}

/// How a run ended, as the score needs it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunEnd {
    pub arrived: bool,
    pub collision: Option<CollisionKind>,
    /// It ran out of time without arriving.
    pub timed_out: bool,
    pub blocked: bool,
    pub right_of_way_violations: u32,
    /// Fraction of the route driven at the end.
    pub progress: f64,
    pub route_length_m: f64,
}

/// The infractions and scores of a run.
#[must_use]
pub fn score_run(end: &RunEnd) -> (f64, Vec<Infraction>, f64, f64, bool, f64) {
    let mut infractions: Vec<Infraction> = end.collision.map(Infraction::of_collision).into_iter().collect();
    infractions.extend(std::iter::repeat_n(Infraction::RightOfWay, end.right_of_way_violations as usize));
    if end.blocked {
        infractions.push(Infraction::Blocked);
    } else if end.timed_out {
        infractions.push(Infraction::Timeout);
    }
    let completion = if end.arrived { 1.0 } else { end.progress.clamp(0.0, 1.0) };
    let p = penalty(&infractions);
    let success = end.arrived && infractions.is_empty();
    (completion, infractions.clone(), p, driving_score(completion, &infractions), success, completion * end.route_length_m / 1000.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn end() -> RunEnd {
        RunEnd {
            arrived: false,
            collision: None,
            timed_out: false,
            blocked: false,
            right_of_way_violations: 0,
            progress: 0.0,
            route_length_m: 200.0,
        }
    }

    #[test]
    fn the_leaderboard_factors_multiply() {
        assert_eq!(penalty(&[]), 1.0);
        assert!((penalty(&[Infraction::PedestrianCollision, Infraction::VehicleCollision]) - 0.30).abs() < 1e-12);
        // 0.65 × 0.70 × 0.70 = 0.3185.
        let p = penalty(&[Infraction::StaticCollision, Infraction::Timeout, Infraction::RightOfWay]);
        assert!((p - 0.3185).abs() < 1e-12, "{p}");
        assert!((driving_score(0.8, &[Infraction::VehicleCollision]) - 0.48).abs() < 1e-12);
    }

    #[test]
    fn a_run_is_scored_as_the_leaderboard_scores_a_route() {
        // Arrived clean: completion 1 (the arrival radius counts as the end), success.
        let (c, inf, p, ds, ok, km) = score_run(&RunEnd { arrived: true, progress: 0.97, ..end() });
        assert_eq!((c, inf.len(), p, ds, ok), (1.0, 0, 1.0, 1.0, true));
        assert!((km - 0.2).abs() < 1e-12);
        // Hit a walker 40 % of the way: 0.4 × 0.5 = 0.2, no success.
        let (c, inf, _, ds, ok, km) = score_run(&RunEnd { collision: Some(CollisionKind::Pedestrian), progress: 0.4, ..end() });
        assert_eq!((c, inf, ok), (0.4, vec![Infraction::PedestrianCollision], false));
        assert!((ds - 0.2).abs() < 1e-12 && (km - 0.08).abs() < 1e-12);
        // Blocked behind a stalled car at 30 %: no factor, the completion it lost.
        let (_, inf, p, ds, _, _) = score_run(&RunEnd { blocked: true, timed_out: true, progress: 0.3, ..end() });
        assert_eq!((inf, p), (vec![Infraction::Blocked], 1.0));
        assert!((ds - 0.3).abs() < 1e-12);
        // Timed out at 90 % after entering a junction without right of way: 0.9 × 0.7 × 0.7.
        let (_, _, _, ds, _, _) = score_run(&RunEnd { timed_out: true, right_of_way_violations: 1, progress: 0.9, ..end() });
        assert!((ds - 0.441).abs() < 1e-12, "{ds}");
        // Parked cars and construction count as vehicle and static collisions.
        assert_eq!(Infraction::of_collision(CollisionKind::ParkedCar), Infraction::VehicleCollision);
        assert_eq!(Infraction::of_collision(CollisionKind::Construction), Infraction::StaticCollision);
    }

    #[test]
    fn blocked_is_thirty_seconds_without_progress() {
        let mut w = ProgressWatch::default();
        assert!(!w.record(10.0, 0.1));
        for _ in 0..299 {
            assert!(!w.record(10.2, 0.1));
        }
        assert!(w.record(10.2, 0.1), "300 steps of 0.1 s without 0.5 m of progress");
        let mut w = ProgressWatch::default();
        for k in 0..600 {
            assert!(!w.record(k as f32, 0.1), "moving: never blocked");
        }
    }
}
