//! The `progress` reward ranks the reference behaviours (`sim_core::reward_ordering`) as driving
//! scores do, on both embedded towns: on the hazard suite's stalled-car, construction and
//! pedestrian-crossing episodes, driving round the hazard returns more than stopping short of it
//! and waiting, which returns more than driving into it; on the clean evaluation routes the blind
//! planner returns more than standing still. Returns are discounted by the presets' γ and measured
//! on the blind planner's waypoints, as the trained agent's reward is.

use sim_core::hazards::HazardKind;
use sim_core::reward::RewardConfig;
use sim_core::reward_ordering::{Case, GAMMA, Tally, ranked_in_order, score_case};
use sim_core::town::Town;

/// Seeds per case and town.
const SEEDS: u64 = 10;

/// Scores `case` on both towns and checks that the mean returns fall in its behaviours' order.
/// The `progress` defaults hold it with margin; nothing here is tuned to them.
fn assert_ranked(case: Case) {
    for name in ["default_town", "held_out_town"] {
        let town = Town::embedded(name).unwrap();
        let tallies = score_case(&town, case, RewardConfig::progress(), SEEDS, GAMMA).unwrap();
        let report = || describe(&tallies);
        assert!(ranked_in_order(&tallies), "{} on {}: {}", case.name(), name, report());
        // Episode by episode, too, for the last two: stopping safely beats crashing on every
        // route, and so does driving a clean route beat standing still. The avoiding driver is
        // compared on the mean only: it drives off the road or runs out of time now and then.
        let [.., worse, worst] = tallies.as_slice() else { unreachable!("a case compares at least two behaviours") };
        for (i, (a, b)) in worse.episodes.iter().zip(&worst.episodes).enumerate() {
            assert!(a.discounted_return > b.discounted_return, "{} on {}, episode {i}: {}", case.name(), name, report());
        }
        // The avoiding driver follows the shadow planner's waypoints; its world must be the
        // scoring environment's, step for step.
        for t in &tallies {
            assert!(t.episodes.iter().all(|e| e.shadow_gap == 0.0), "{} on {}: the shadow diverged: {}", case.name(), name, report());
        }
    }
}

fn describe(tallies: &[Tally]) -> String {
    let per_episode =
        |t: &Tally| t.episodes.iter().map(|e| format!("{:.1} {:?}", e.discounted_return, e.end)).collect::<Vec<_>>().join(", ");
    tallies.iter().map(|t| format!("\n  {}: mean {:.2}, ends {:?}: {}", t.behaviour.name(), t.mean(), t.ends(), per_episode(t))).collect()
}

#[test]
fn progress_ranks_passing_a_stalled_car_over_waiting_behind_it_over_hitting_it() {
    assert_ranked(Case::Hazard(HazardKind::StalledCar));
}

#[test]
fn progress_ranks_driving_round_a_closure_over_waiting_at_it_over_hitting_it() {
    assert_ranked(Case::Hazard(HazardKind::Construction));
}

#[test]
fn progress_ranks_braking_for_a_walker_over_waiting_for_good_over_hitting_them() {
    assert_ranked(Case::Hazard(HazardKind::PedestrianCrossing));
}

#[test]
fn progress_ranks_driving_a_clean_route_over_standing_still() {
    assert_ranked(Case::Clean);
}
