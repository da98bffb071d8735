//! The curves of a plot: each run's metrics read back and turned into series (trailing moving
//! average of the return, normalised over all runs; loss and mean Q as recorded).

use std::fs;
use std::path::Path;

use plotters::style::RGBColor;

use super::error::PlotError;
use crate::records::{EPISODES_FILE, EVAL_FILE, EpisodeRecord, EvalRecord, TRAIN_FILE, TrainRecord, read_episodes, read_eval, read_train};

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

/// Appends " #2", " #3", … to names that an earlier run already has.
pub(super) fn disambiguate_names(runs: &mut [Run]) {
    let names: Vec<String> = runs.iter().map(|r| r.name.clone()).collect();
    for (i, run) in runs.iter_mut().enumerate() {
        let earlier = names[..i].iter().filter(|n| **n == names[i]).count();
        if earlier > 0 {
            run.name = format!("{} #{}", names[i], earlier + 1);
        }
    }
}

/// The effective moving-average window of a run of `n` episodes: `smoothing`, shrunk to half the
/// run (rounded up) for short runs so that they still draw a curve.
pub(super) fn effective_window(smoothing: usize, n: usize) -> usize {
    smoothing.min(n.div_ceil(2)).max(1)
}

/// Trailing moving average over full windows of `window` values: the point at `i` (for
/// `i >= window - 1`) is the mean of `values[i + 1 - window..=i]`.
pub(super) fn moving_average(values: &[f64], window: usize) -> Vec<f64> {
    assert!(window >= 1);
    if values.len() < window {
        return Vec::new();
    }
    let mut out = Vec::with_capacity(values.len() + 1 - window);
    let mut sum: f64 = values[..window].iter().sum();
    out.push(sum / window as f64);
    for i in window..values.len() {
        sum += values[i] - values[i - window];
        out.push(sum / window as f64);
    }
    out
}

/// Maps `v` from `[min, max]` to `[0, 1]`; to 0.5 when the range is empty.
pub(super) fn normalise(v: f64, min: f64, max: f64) -> f64 {
    if max > min { (v - min) / (max - min) } else { 0.5 }
}

/// Every curve of a plot, one series per run in each panel.
pub(super) struct Curves {
    /// Smoothed returns, normalised over all runs, and the bounds they were normalised with.
    pub(super) reward: Vec<Series>,
    pub(super) return_bounds: Option<(f64, f64)>,
    pub(super) loss: Vec<Series>,
    pub(super) mean_q: Vec<Series>,
    /// Route types mastered by periodic greedy evaluations, against minutes.
    pub(super) evals: Vec<Series>,
}

pub(super) struct Series {
    pub(super) label: String,
    pub(super) colour: RGBColor,
    pub(super) points: Vec<(f64, f64)>,
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
    fn moving_average_uses_full_windows() {
        assert_eq!(moving_average(&[1.0, 2.0, 3.0, 4.0], 2), vec![1.5, 2.5, 3.5]);
        assert_eq!(moving_average(&[1.0, 2.0, 3.0], 3), vec![2.0]);
        assert_eq!(moving_average(&[1.0, 2.0], 3), Vec::<f64>::new());
        assert_eq!(moving_average(&[5.0, 7.0], 1), vec![5.0, 7.0]);
    }

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
    fn normalisation_maps_to_unit_interval() {
        assert_eq!(normalise(5.0, 0.0, 10.0), 0.5);
        assert_eq!(normalise(-2.0, -2.0, 2.0), 0.0);
        assert_eq!(normalise(3.0, 3.0, 3.0), 0.5);
        assert_eq!(bounds([3.0, f64::NAN, -1.0, 2.0].into_iter()), Some((-1.0, 3.0)));
        assert_eq!(bounds(std::iter::empty()), None);
    }

    #[test]
    fn duplicate_names_are_numbered() {
        let run = |name: &str| Run { name: name.into(), episodes: Vec::new(), train: Vec::new(), eval: Vec::new() };
        let mut runs = vec![run("a"), run("b"), run("a"), run("a")];
        disambiguate_names(&mut runs);
        let names: Vec<_> = runs.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(names, ["a", "b", "a #2", "a #3"]);
    }
}
