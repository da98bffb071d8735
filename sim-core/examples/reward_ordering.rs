//! Prints, as a markdown table, how the paper's reward and the progress reward rank the reference
//! behaviours of `sim_core::reward_ordering` on both embedded towns: the mean discounted return
//! (γ of the presets) of driving round the hazard, stopping short of it and waiting, and driving
//! into it on the hazard suite's stalled-car, construction and pedestrian-crossing episodes, and
//! of the blind planner and standing still on the clean evaluation routes; how each behaviour's
//! episodes ended; and whether the means fall in that order (and in how many episodes they do).
//! Both rewards are the hybrid variant's.
//!
//! `cargo run --release -p sim-core --example reward_ordering`

use sim_core::reward::RewardConfig;
use sim_core::reward_ordering::{Case, GAMMA, Tally, ranked_in_order, score_case};
use sim_core::town::Town;

/// Seeds per case and town (per evaluation route on the clean routes).
const SEEDS: u64 = 10;

fn main() {
    println!("Mean discounted return (γ = {GAMMA}) over {SEEDS} seeds per town and case (clean: per evaluation route);");
    println!("after each mean, how its episodes ended: arrived / collided / timed out. Hazard cases: avoid, stop,");
    println!("crash; clean routes: planner, stand still. \"ordered\": the means fall in that order (episodes where");
    println!("the returns of that seed do, too).\n");
    println!("| town | case | reward | avoid / planner | stop / stand still | crash | ordered |");
    println!("|---|---|---|---|---|---|---|");
    for name in ["default_town", "held_out_town"] {
        let town = Town::embedded(name).expect("an embedded town");
        for case in Case::ALL {
            for (reward_name, reward) in [("paper", RewardConfig::paper()), ("progress", RewardConfig::progress())] {
                let tallies = score_case(&town, case, reward, SEEDS, GAMMA).expect("reference episodes run");
                let mut cells: Vec<String> = tallies.iter().map(cell).collect();
                cells.resize(3, "–".into());
                let ordered = if ranked_in_order(&tallies) { "yes" } else { "**no**" };
                let (held, of) = per_episode_order(&tallies);
                println!("| {name} | {} | {reward_name} | {} | {ordered} ({held}/{of}) |", case.name(), cells.join(" | "));
            }
        }
    }
}

/// "mean (arrived/collided/timed out)".
fn cell(t: &Tally) -> String {
    let (a, c, tr) = t.ends();
    format!("{:.1} ({a}/{c}/{tr})", t.mean())
}

/// In how many of the episodes the behaviours' returns fall in order, of how many.
fn per_episode_order(tallies: &[Tally]) -> (usize, usize) {
    let n = tallies.first().map_or(0, |t| t.episodes.len());
    let held =
        (0..n).filter(|&i| tallies.windows(2).all(|w| w[0].episodes[i].discounted_return > w[1].episodes[i].discounted_return)).count();
    (held, n)
}
