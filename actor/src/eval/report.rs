//! The evaluation's results: per route and agent, and the paper's Table I beside them, as JSON
//! (`{"agents":[...]}`) and as a readable or Markdown table.

use serde::Serialize;
use sim_core::config::Variant;

use crate::eval::greedy::{CheckpointInfo, EPSILON};
use crate::eval::table::{Align, write_table};

/// Outcomes of one agent on one route.
#[derive(Debug, Clone, Serialize)]
pub struct RouteResult {
    pub route: &'static str,
    pub runs: u32,
    pub mean_return: f64,
    pub min_return: f64,
    pub max_return: f64,
    pub completed: u32,
    pub completion_rate: f64,
    pub collisions: u32,
    pub collision_rate: f64,
    /// What was hit, one entry per collision.
    pub collision_kinds: Vec<&'static str>,
    /// Mean over runs of the mean distance to the closest waypoint, metres.
    pub mean_d: f64,
    /// Mean over runs of the mean speed, km/h.
    pub mean_speed_kmh: f64,
    pub mean_steps: f64,
    /// The paper's Table I (Hybrid-DQN, human average), for reference.
    pub paper_hybrid_dqn: Option<f32>,
    pub paper_human: Option<f32>,
    /// Each run's return and whether it arrived, in run order (seeds S, S+1, ...): what
    /// confidence intervals over runs are computed from.
    pub run_returns: Vec<f64>,
    pub run_completed: Vec<bool>,
}

/// One agent's evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct AgentReport {
    pub name: String,
    /// `model_based` or `checkpoint`.
    pub kind: &'static str,
    /// `hybrid` or `end_to_end` for checkpoints.
    pub variant: Option<Variant>,
    pub checkpoint: Option<CheckpointInfo>,
    /// The camera the agent drives from, e.g. `84x84 gray`.
    pub camera: Option<String>,
    pub epsilon: f32,
    pub seed: u64,
    pub traffic_vehicles: usize,
    /// Mean of the routes' mean returns.
    pub mean_return: f64,
    /// Routes completed in more than half of their runs.
    pub routes_completed_majority: usize,
    pub routes: Vec<RouteResult>,
}

/// The whole evaluation: `{"town":"...","agents":[...]}`.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// The town driven: its map's name (`default_town`, `held_out_town`, or a map file's).
    pub town: String,
    pub agents: Vec<AgentReport>,
}

/// The readable table (or Markdown): one block per route, one row per agent, the paper's Table I
/// beside it; then the agents over all routes.
#[must_use]
pub fn table(report: &Report, markdown: bool) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let Some(first) = report.agents.first() else { return out };
    let header = [
        "route",
        "agent",
        "mean return",
        "completed",
        "collisions",
        "mean d (m)",
        "speed (km/h)",
        "steps",
        "paper Hybrid-DQN",
        "paper human",
    ];
    let mut rows: Vec<[String; 10]> = Vec::new();
    let opt = |x: Option<f32>| x.map_or_else(|| "—".to_owned(), |v| format!("{v:.1}"));
    for (i, r0) in first.routes.iter().enumerate() {
        for (j, a) in report.agents.iter().enumerate() {
            let r = &a.routes[i];
            let first_row = j == 0 || markdown;
            rows.push([
                if first_row { r0.route.to_owned() } else { String::new() },
                a.name.clone(),
                format!("{:.1}", r.mean_return),
                format!("{}/{}", r.completed, r.runs),
                format!("{}/{}", r.collisions, r.runs),
                format!("{:.2}", r.mean_d),
                format!("{:.1}", r.mean_speed_kmh),
                format!("{:.0}", r.mean_steps),
                if first_row { opt(r.paper_hybrid_dqn) } else { String::new() },
                if first_row { opt(r.paper_human) } else { String::new() },
            ]);
        }
    }
    let paper_mean = |f: fn(&RouteResult) -> Option<f32>| -> Option<f32> {
        let v: Option<Vec<f32>> = first.routes.iter().map(f).collect();
        v.filter(|v| !v.is_empty()).map(|v| v.iter().sum::<f32>() / v.len() as f32)
    };
    for (j, a) in report.agents.iter().enumerate() {
        let first_row = j == 0 || markdown;
        let runs: u32 = a.routes.iter().map(|r| r.runs).sum();
        rows.push([
            if first_row { "mean of the routes".to_owned() } else { String::new() },
            a.name.clone(),
            format!("{:.1}", a.mean_return),
            format!("{}/{}", a.routes.iter().map(|r| r.completed).sum::<u32>(), runs),
            format!("{}/{}", a.routes.iter().map(|r| r.collisions).sum::<u32>(), runs),
            format!("{:.2}", a.routes.iter().map(|r| r.mean_d).sum::<f64>() / a.routes.len().max(1) as f64),
            format!("{:.1}", a.routes.iter().map(|r| r.mean_speed_kmh).sum::<f64>() / a.routes.len().max(1) as f64),
            format!("{:.0}", a.routes.iter().map(|r| r.mean_steps).sum::<f64>() / a.routes.len().max(1) as f64),
            if first_row { opt(paper_mean(|r| r.paper_hybrid_dqn)) } else { String::new() },
            if first_row { opt(paper_mean(|r| r.paper_human)) } else { String::new() },
        ]);
    }
    let (l, r) = (Align::Left, Align::Right);
    write_table(&mut out, header, [l, l, r, r, r, r, r, r, r, r], &rows, markdown);
    let _ = writeln!(out);
    for a in &report.agents {
        let what = match (&a.kind, &a.checkpoint) {
            (_, Some(c)) => format!(
                "{} agent, {} camera, checkpoint {} (learner step {}, {} env steps, {} episodes)",
                a.variant.map_or("?", |v| match v {
                    Variant::Hybrid => "hybrid",
                    Variant::EndToEnd => "end-to-end",
                }),
                a.camera.as_deref().unwrap_or("no"),
                c.weights.display(),
                c.learner_step.map_or("?".into(), |x| x.to_string()),
                c.env_steps.map_or("?".into(), |x| x.to_string()),
                c.episodes.map_or("?".into(), |x| x.to_string()),
            ),
            _ => "A* planner + pure pursuit + speed control (`actor drive --policy expert`)".to_owned(),
        };
        let routes = a.routes.len();
        let _ = writeln!(
            out,
            "{}{}: {what}; routes completed in most runs: {}/{routes}",
            if markdown { "- " } else { "" },
            a.name,
            a.routes_completed_majority
        );
    }
    let _ = writeln!(
        out,
        "{}Town `{}`; greedy (ε = {EPSILON}), {} run(s) per route with seeds {}.., {} traffic cars; every agent scored with the paper's reward (r_w included). Paper columns: Table I of Yurtsever et al. 2020 (CARLA, human drivers).",
        if markdown { "\n" } else { "" },
        report.town,
        first.routes.first().map_or(0, |r| r.runs),
        first.seed,
        first.traffic_vehicles
    );
    out
}
