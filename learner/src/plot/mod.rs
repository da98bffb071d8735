//! Learning curves of training runs, drawn to a PNG from the metrics the learner writes to its run
//! directory (`episodes.jsonl` and `train.jsonl`, JSON Lines).
//!
//! [`plot_runs`] draws three panels stacked vertically: the normalised smoothed episode return
//! against the episode index (the paper's Figure 5), the training loss and the mean Q-value
//! against the learner step. Text is drawn with a subset of DejaVu Sans embedded in the binary
//! (`assets/DejaVuSans-Plot.ttf`, made by `assets/make_plot_font.py`, license in
//! `assets/DejaVuSans-LICENSE.txt`), so plotting needs no system font or library.

mod draw;
mod error;
mod series;

use std::path::{Path, PathBuf};

use crate::records::TrainRecord;
use draw::{COLOURS, draw, register_font};
pub use error::PlotError;
use series::{Curves, Series, bounds, disambiguate_names, effective_window, moving_average, normalise, read_run};

/// Options of a plot.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlotOptions {
    /// Moving-average window of the return curve, in episodes (at least 1).
    pub smoothing: usize,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Default for PlotOptions {
    fn default() -> Self {
        Self { smoothing: 50, width: 1200, height: 900 }
    }
}

/// What was plotted.
#[derive(Debug, Clone, PartialEq)]
pub struct PlotSummary {
    /// One per run directory, in the order given.
    pub runs: Vec<RunSummary>,
}

/// What was plotted of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSummary {
    /// The name in the legend: the run directory's final path component.
    pub name: String,
    /// Episodes read from `episodes.jsonl`.
    pub episodes: usize,
    /// Records read from `train.jsonl` (0 if the run has none).
    pub train_points: usize,
    /// The last point of the smoothed return curve (not normalised); `None` with no episodes.
    pub final_smoothed_return: Option<f64>,
    /// Periodic greedy evaluations read from `eval.jsonl` (0 if the run has none).
    pub eval_points: usize,
    /// Minutes of training until a greedy evaluation first mastered at least
    /// [`COMPETENT_ROUTE_TYPES`] route types; `None` if none did.
    pub minutes_to_competence: Option<f64>,
}

/// Route types (of 7) a greedy evaluation must master for the agent to count as competent.
pub const COMPETENT_ROUTE_TYPES: u32 = 5;

/// Reads the metrics of each run directory and draws a PNG at `out` with three panels stacked
/// vertically:
/// 1. "Normalised reward vs episode", like the paper's Figure 5: for each run, the trailing moving
///    average of the episode return over `opts.smoothing` episodes (over full windows only; a run
///    shorter than twice the window uses half its length), normalised to [0, 1] by min–max over
///    all runs' smoothed curves together, against the episode index of the window's last episode;
/// 2. "Loss" from `train.jsonl` against the learner step (log scale if all values are positive);
/// 3. "Mean Q" from `train.jsonl` against the learner step.
///
/// One coloured line per run, the same colour in every panel, with a legend naming the run
/// directory's final path component. A run directory without `episodes.jsonl` is an error; one
/// without `train.jsonl` has no loss or Q curve. `out` must end in `.png`.
pub fn plot_runs(run_dirs: &[PathBuf], out: &Path, opts: &PlotOptions) -> Result<PlotSummary, PlotError> {
    if run_dirs.is_empty() {
        return Err(PlotError::NoRuns);
    }
    if opts.smoothing == 0 {
        return Err(PlotError::Options("smoothing must be at least 1 episode".into()));
    }
    if opts.width < 300 || opts.height < 300 || opts.width > 10_000 || opts.height > 10_000 {
        return Err(PlotError::Options(format!("image size {}x{} is outside 300x300..=10000x10000", opts.width, opts.height)));
    }
    if !out.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        return Err(PlotError::Options(format!("output {} must end in .png", out.display())));
    }
    register_font()?;

    let mut runs = run_dirs.iter().map(|d| read_run(d)).collect::<Result<Vec<_>, _>>()?;
    disambiguate_names(&mut runs);

    let mut summaries = Vec::with_capacity(runs.len());
    let mut reward = Vec::with_capacity(runs.len());
    let mut loss = Vec::with_capacity(runs.len());
    let mut mean_q = Vec::with_capacity(runs.len());
    let mut evals = Vec::with_capacity(runs.len());
    for (i, run) in runs.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let window = effective_window(opts.smoothing, run.episodes.len());
        let returns: Vec<f64> = run.episodes.iter().map(|e| e.episode_return).collect();
        let smoothed = moving_average(&returns, window);
        let points: Vec<(f64, f64)> = run.episodes[window - 1..]
            .iter()
            .zip(&smoothed)
            .map(|(e, &r)| (e.episode_index as f64, r))
            .filter(|p| p.1.is_finite())
            .collect();
        let label = if window < opts.smoothing && !run.episodes.is_empty() {
            format!("{} ({} episodes, window {window})", run.name, run.episodes.len())
        } else {
            format!("{} ({} episodes)", run.name, run.episodes.len())
        };
        summaries.push(RunSummary {
            name: run.name.clone(),
            episodes: run.episodes.len(),
            train_points: run.train.len(),
            final_smoothed_return: smoothed.last().copied(),
            eval_points: run.eval.len(),
            minutes_to_competence: run.eval.iter().find(|e| e.route_types_mastered >= COMPETENT_ROUTE_TYPES).map(|e| e.time_secs / 60.0),
        });
        evals.push(Series {
            label: run.name.clone(),
            colour,
            points: run.eval.iter().map(|e| (e.time_secs / 60.0, f64::from(e.route_types_mastered))).collect(),
        });
        reward.push(Series { label, colour, points });
        let train_series = |f: fn(&TrainRecord) -> Option<f64>| Series {
            label: run.name.clone(),
            colour,
            points: run.train.iter().filter_map(|t| Some((t.learner_step as f64, f(t).filter(|v| v.is_finite())?))).collect(),
        };
        loss.push(train_series(|t| t.loss));
        mean_q.push(train_series(|t| t.mean_q));
    }

    // Normalise the smoothed returns over all runs together.
    let return_bounds = bounds(reward.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    if let Some((min, max)) = return_bounds {
        for s in &mut reward {
            for p in &mut s.points {
                p.1 = normalise(p.1, min, max);
            }
        }
    }

    let curves = Curves { reward, return_bounds, loss, mean_q, evals };
    draw(out, (opts.width, opts.height), opts.smoothing, &curves)
        .map_err(|message| PlotError::Draw { path: out.to_path_buf(), message })?;
    Ok(PlotSummary { runs: summaries })
}
