//! The curves of a plot: each run's metrics read back, and the series drawn from them (one per
//! group of runs and panel, on the grid of `grid.rs`).

use std::fs;
use std::ops::Range;
use std::path::Path;

use plotters::style::RGBColor;
use sim_core::hazards::HazardKind;

use super::error::PlotError;
use super::grid::{BandPoint, XAxis};
use learner::telemetry::records::{
    EPISODES_FILE, EVAL_FILE, EpisodeRecord, EvalRecord, TRAIN_FILE, TrainRecord, read_episodes, read_eval, read_train,
};

/// One run's data, read.
pub(super) struct Run {
    pub(super) name: String,
    pub(super) episodes: Vec<EpisodeRecord>,
    pub(super) train: Vec<TrainRecord>,
    /// Periodic greedy evaluations (`eval.jsonl`, empty when the run has none).
    pub(super) eval: Vec<EvalRecord>,
}

pub(super) fn read_run(dir: &Path) -> Result<Run, PlotError> {
    let episodes_path = dir.join(EPISODES_FILE);
    match fs::metadata(&episodes_path) {
        Ok(_) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(PlotError::MissingEpisodes { dir: dir.to_path_buf() }),
        Err(source) => return Err(PlotError::Io { path: episodes_path, source }),
    }
    let mut episodes = read_episodes(&episodes_path)?;
    episodes.sort_by_key(|e| e.episode_index);
    let train_path = dir.join(TRAIN_FILE);
    let mut train = if train_path.exists() { read_train(&train_path)? } else { Vec::new() };
    train.sort_by_key(|t| t.learner_step);
    let eval_path = dir.join(EVAL_FILE);
    let mut eval = if eval_path.exists() { read_eval(&eval_path)? } else { Vec::new() };
    eval.sort_by(|a, b| a.time_secs.total_cmp(&b.time_secs));
    Ok(Run { name: run_name(dir), episodes, train, eval })
}

/// The run directory's final path component (of its canonical path for `.` and the like).
pub(super) fn run_name(dir: &Path) -> String {
    let name = dir.file_name().map(|n| n.to_os_string()).or_else(|| dir.canonicalize().ok()?.file_name().map(|n| n.to_os_string()));
    match name {
        Some(n) => n.to_string_lossy().into_owned(),
        None => dir.display().to_string(),
    }
}

/// Appends " #2", " #3", … to names that an earlier one already has.
pub(super) fn disambiguate(names: &mut [String]) {
    let original = names.to_vec();
    for (i, name) in names.iter_mut().enumerate() {
        let earlier = original[..i].iter().filter(|n| **n == original[i]).count();
        if earlier > 0 {
            *name = format!("{} #{}", original[i], earlier + 1);
        }
    }
}

/// The effective moving-average window of a run of `n` episodes: `smoothing`, shrunk to half the
/// run (rounded up) for short runs so that they still draw a curve.
pub(super) fn effective_window(smoothing: usize, n: usize) -> usize {
    smoothing.min(n.div_ceil(2)).max(1)
}

/// Every curve of a plot, one series per group of runs in each panel, all on one x axis.
pub(super) struct Curves {
    /// The x axis and the range of every panel (the grid's).
    pub(super) x_axis: XAxis,
    pub(super) x: Range<f64>,
    /// Smoothed episode returns.
    pub(super) returns: Vec<Series>,
    pub(super) loss: Vec<Series>,
    pub(super) mean_q: Vec<Series>,
    /// Route types mastered by periodic greedy evaluations.
    pub(super) evals: Vec<Series>,
    /// Whether any run has periodic greedy evaluations (the fourth panel).
    pub(super) with_eval: bool,
    /// One panel per hazard kind of any run's episodes (none when no episode had a hazard).
    pub(super) hazards: Vec<HazardPanel>,
}

/// The panel of one hazard kind: per group of runs, the rolling share of the kind's episodes that
/// arrived (a solid line) and that collided (dashed).
pub(super) struct HazardPanel {
    /// The kind's name (`stalled_car`, …).
    pub(super) kind: String,
    pub(super) series: Vec<Series>,
}

/// One group's line in a panel.
pub(super) struct Series {
    pub(super) label: String,
    pub(super) colour: RGBColor,
    /// The line, in pieces broken where no run of the group has data: the mean over the runs, with
    /// their min and max.
    pub(super) pieces: Vec<Vec<BandPoint>>,
    /// Whether to shade the band between min and max (a group of several runs).
    pub(super) band: bool,
    /// Points marked with a dot as well (a single run's evaluations, few and discrete).
    pub(super) markers: Vec<(f64, f64)>,
    /// Whether the line is dashed (a second line of the same group in one panel).
    pub(super) dashed: bool,
}

impl Series {
    /// Every (x, y) drawn: the line's means, the band's edges, the markers.
    pub(super) fn points(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        let line = self.pieces.iter().flatten().flat_map(|p| [(p.x, p.mean), (p.x, p.min), (p.x, p.max)]);
        line.chain(self.markers.iter().copied())
    }

    /// The same series with `f` applied to every y (the loss panel's log scale).
    pub(super) fn map_y(&self, f: impl Fn(f64) -> f64) -> Series {
        let map = |b: &BandPoint| BandPoint { x: b.x, mean: f(b.mean), min: f(b.min), max: f(b.max) };
        Series {
            label: self.label.clone(),
            colour: self.colour,
            pieces: self.pieces.iter().map(|p| p.iter().map(map).collect()).collect(),
            band: self.band,
            markers: self.markers.iter().map(|&(x, y)| (x, f(y))).collect(),
            dashed: self.dashed,
        }
    }
}

/// The hazard kinds of the runs' episodes, each once: sim-core's kinds in their order, then any
/// other name (a newer simulator's) alphabetically.
pub(super) fn hazard_kinds<'a>(runs: impl Iterator<Item = &'a Run>) -> Vec<String> {
    let mut kinds: Vec<String> = runs.flat_map(|r| r.episodes.iter().filter_map(|e| e.hazard.clone())).collect();
    let order = |k: &String| (HazardKind::ALL.iter().position(|h| h.name() == k).unwrap_or(HazardKind::ALL.len()), k.clone());
    kinds.sort_by_key(order);
    kinds.dedup();
    kinds
}

/// The smallest and largest finite values, if any.
pub(super) fn bounds(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.filter(|v| v.is_finite()).fold(None, |acc, v| match acc {
        None => Some((v, v)),
        Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_runs_shrink_the_window() {
        assert_eq!(effective_window(50, 1000), 50);
        assert_eq!(effective_window(50, 100), 50);
        assert_eq!(effective_window(50, 99), 50);
        assert_eq!(effective_window(50, 30), 15);
        assert_eq!(effective_window(50, 1), 1);
        assert_eq!(effective_window(50, 0), 1);
    }

    #[test]
    fn bounds_skip_non_finite_values() {
        assert_eq!(bounds([3.0, f64::NAN, -1.0, 2.0].into_iter()), Some((-1.0, 3.0)));
        assert_eq!(bounds(std::iter::empty()), None);
    }

    #[test]
    fn hazard_kinds_come_in_the_simulators_order_once_each() {
        let episode = |hazard: Option<&str>| EpisodeRecord {
            time_secs: 0.0,
            episode_index: 1,
            actor_id: "a".into(),
            env: 0,
            episode_return: 0.0,
            steps: 1,
            arrived: false,
            collision: None,
            scenario: "random".into(),
            hazard: hazard.map(str::to_owned),
            outcome: String::new(),
            learner_step: 0,
            env_steps: 1,
        };
        let run = |hazards: &[Option<&str>]| Run {
            name: "r".into(),
            episodes: hazards.iter().map(|&h| episode(h)).collect(),
            train: Vec::new(),
            eval: Vec::new(),
        };
        let runs = [run(&[Some("cut_in"), None, Some("zeppelin"), Some("cut_in")]), run(&[Some("stalled_car"), Some("cut_in")])];
        assert_eq!(hazard_kinds(runs.iter()), ["stalled_car", "cut_in", "zeppelin"]);
        assert!(hazard_kinds([run(&[None, None])].iter()).is_empty());
    }

    #[test]
    fn duplicate_names_are_numbered() {
        let mut names: Vec<String> = ["a", "b", "a", "a"].map(String::from).to_vec();
        disambiguate(&mut names);
        assert_eq!(names, ["a", "b", "a #2", "a #3"]);
    }
}
