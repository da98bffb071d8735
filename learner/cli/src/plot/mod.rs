//! Learning curves of training runs, drawn to a PNG from the metrics the learner writes to its run
//! directory (`episodes.jsonl`, `train.jsonl`, `eval.jsonl`, JSON Lines).
//!
//! [`plot_groups`] draws panels stacked vertically on one x axis (minutes of training or
//! environment steps): the smoothed episode return, the training loss, the mean Q-value and, when
//! the runs have them, the periodic greedy evaluations and, per hazard kind of the training
//! episodes, the shares that arrived and collided. A line is one run, or one agent over
//! several seeds (a [`RunGroup`]) drawn as the mean with a min–max band. Text is drawn with a
//! subset of DejaVu Sans embedded in the binary (`assets/DejaVuSans-Plot.ttf`, made by
//! `assets/make_plot_font.py`, license in `assets/DejaVuSans-LICENSE.txt`), so plotting needs no
//! system font or library.

mod draw;
mod error;
mod grid;
mod groups;
mod series;

use std::path::{Path, PathBuf};

use draw::{COLOURS, draw, register_font};
pub use error::PlotError;
pub use grid::XAxis;
use grid::{GRID_POINTS, Grid, band, resample, smooth, trailing_mean};
pub use groups::RunGroup;
use learner::telemetry::records::{EpisodeRecord, TrainRecord};
use series::{Curves, HazardPanel, Run, Series, disambiguate, effective_window, hazard_kinds, read_run};

/// Options of a plot.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlotOptions {
    /// Moving-average window of the return curve, in episodes (at least 1).
    pub smoothing: usize,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels, for up to four panels; a run with hazard panels gets a taller
    /// image, each panel as high as one of four.
    pub height: u32,
    /// The x axis of every panel.
    pub x: XAxis,
}

impl Default for PlotOptions {
    fn default() -> Self {
        Self { smoothing: 50, width: 1200, height: 900, x: XAxis::Minutes }
    }
}

/// What was plotted.
#[derive(Debug, Clone, PartialEq)]
pub struct PlotSummary {
    /// One per run directory, in the order given (the runs of a group together).
    pub runs: Vec<RunSummary>,
    /// One per line: per group of runs, in the order given.
    pub groups: Vec<GroupSummary>,
    /// The hazard kinds that got a panel: every kind of any run's episodes, in sim-core's order
    /// (empty when no episode had a hazard: no hazard panel).
    pub hazard_kinds: Vec<String>,
}

/// What was plotted of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSummary {
    /// The run directory's final path component (numbered " #2", … when two runs share one).
    pub name: String,
    /// The legend name of the run's group ([`GroupSummary::label`]).
    pub group: String,
    /// Episodes read from `episodes.jsonl`.
    pub episodes: usize,
    /// Records read from `train.jsonl` (0 if the run has none).
    pub train_points: usize,
    /// The last point of the run's smoothed return curve (see [`plot_groups`]); `None` with no
    /// episodes.
    pub final_smoothed_return: Option<f64>,
    /// Periodic greedy evaluations read from `eval.jsonl` (0 if the run has none).
    pub eval_points: usize,
    /// Minutes of training until a greedy evaluation first mastered at least
    /// [`COMPETENT_ROUTE_TYPES`] route types; `None` if none did.
    pub minutes_to_competence: Option<f64>,
}

/// What was plotted of one group of runs (one line).
#[derive(Debug, Clone, PartialEq)]
pub struct GroupSummary {
    /// The name in the legend: the label given, or the run's name for a single run directory
    /// (numbered " #2", … when two lines share one).
    pub label: String,
    /// Runs in the group (seeds).
    pub runs: usize,
    /// The mean over the runs of their final smoothed return (runs without one left out); `None`
    /// if none has one.
    pub mean_final_smoothed_return: Option<f64>,
    /// Runs whose greedy evaluations reached competence ([`RunSummary::minutes_to_competence`]).
    pub competent_runs: usize,
    /// The mean minutes to competence over the competent runs; `None` if none is.
    pub mean_minutes_to_competence: Option<f64>,
}

/// Route types (of 7) a greedy evaluation must master for the agent to count as competent.
pub const COMPETENT_ROUTE_TYPES: u32 = 5;

/// [`plot_groups`] with one line per run directory.
pub fn plot_runs(run_dirs: &[PathBuf], out: &Path, opts: &PlotOptions) -> Result<PlotSummary, PlotError> {
    let groups: Vec<RunGroup> = run_dirs.iter().map(|d| RunGroup::single(d.clone())).collect();
    plot_groups(&groups, out, opts)
}

/// Reads the metrics of each group's run directories and draws a PNG at `out` with panels stacked
/// vertically, all against the same x axis (`opts.x`: minutes of training from `time_secs`, or
/// environment steps from `env_steps`, over the range of every record of every run):
/// 1. "Smoothed episode return": for each run, the trailing moving average of the episode return
///    over `opts.smoothing` episodes (over full windows only; a run shorter than twice the window
///    uses half its length), widened to every episode of the last grid cell when that holds more
///    (dense runs do not alias);
/// 2. "Loss" from `train.jsonl` (log scale if all values are positive), with, for runs that
///    trained on demonstrations, their large-margin loss (`margin_loss`) dashed beside it;
/// 3. "Mean Q" from `train.jsonl`;
/// 4. with any `eval.jsonl`, the route types the periodic greedy evaluations mastered (a single
///    run's evaluations marked with dots);
/// 5. per hazard kind of any run's episodes (`hazard` in `episodes.jsonl`), one panel: the
///    trailing share of that kind's episodes that arrived (solid) and that collided (dashed), over
///    `opts.smoothing` of them (shrunk as for the return). None for runs without hazard episodes.
///
/// Clean lines: each run's curve is resampled onto a common grid of [`GRID_POINTS`] x values,
/// interpolating linearly between its points (loss, mean Q and evaluations are averaged over a
/// grid cell, not smoothed further). Consecutive points further apart than 3 grid cells (or 5
/// times the run's median spacing, if wider) are a gap: the line breaks there, and the moving
/// average fills again after it. Data narrower than a grid cell is not drawn; non-finite values
/// are skipped.
///
/// One colour per group, the same in every panel, with a legend naming it: a single run by its
/// directory's final path component, a labelled group as "LABEL (N seeds)". A group of several runs
/// draws, at each grid point, the mean over the runs that have data there and a shaded band from
/// their minimum to their maximum.
///
/// A run directory without `episodes.jsonl` is an error; one without `train.jsonl` has no loss or
/// Q curve. `out` must end in `.png`.
pub fn plot_groups(groups: &[RunGroup], out: &Path, opts: &PlotOptions) -> Result<PlotSummary, PlotError> {
    if groups.is_empty() {
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

    let mut runs: Vec<Vec<Run>> =
        groups.iter().map(|g| g.dirs().iter().map(|d| read_run(d)).collect::<Result<Vec<_>, _>>()).collect::<Result<_, _>>()?;
    let mut names: Vec<String> = runs.iter().flatten().map(|r| r.name.clone()).collect();
    disambiguate(&mut names);
    for (run, name) in runs.iter_mut().flatten().zip(names) {
        run.name = name;
    }
    let mut labels: Vec<String> =
        groups.iter().zip(&runs).map(|(g, group_runs)| g.label().map_or_else(|| group_runs[0].name.clone(), str::to_string)).collect();
    disambiguate(&mut labels);

    let x = opts.x;
    let xs = runs.iter().flatten().flat_map(|r| {
        let episodes = r.episodes.iter().map(move |e| x.of(e.time_secs, e.env_steps));
        let train = r.train.iter().map(move |t| x.of(t.time_secs, t.env_steps));
        episodes.chain(train).chain(r.eval.iter().map(move |e| x.of(e.time_secs, e.env_steps)))
    });
    let grid = Grid::spanning(xs, GRID_POINTS);

    let kinds = hazard_kinds(runs.iter().flatten());
    let mut hazards: Vec<HazardPanel> = kinds.iter().map(|k| HazardPanel { kind: k.clone(), series: Vec::new() }).collect();
    let mut summary = PlotSummary { runs: Vec::new(), groups: Vec::new(), hazard_kinds: kinds.clone() };
    let (mut returns, mut loss, mut mean_q, mut evals) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (i, ((group, group_runs), label)) in groups.iter().zip(&runs).zip(labels).enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let (mut return_values, mut loss_values, mut q_values, mut eval_values) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut margin_values = Vec::new();
        // Per hazard kind, per run: the shares arrived and collided.
        let mut arrived_values: Vec<Vec<Vec<Option<f64>>>> = vec![Vec::new(); kinds.len()];
        let mut collided_values: Vec<Vec<Vec<Option<f64>>>> = vec![Vec::new(); kinds.len()];
        let mut window_note = None;
        for run in group_runs {
            let window = effective_window(opts.smoothing, run.episodes.len());
            if window < opts.smoothing && !run.episodes.is_empty() {
                window_note = Some(window);
            }
            let episode_points: Vec<(f64, f64)> = run.episodes.iter().map(|e| (x.of(e.time_secs, e.env_steps), e.episode_return)).collect();
            let return_curve = smooth(&episode_points, window, &grid);
            return_values.push(resample(&return_curve, &grid));
            let train_values = |f: fn(&TrainRecord) -> Option<f64>| {
                let points: Vec<(f64, f64)> = run.train.iter().filter_map(|t| Some((x.of(t.time_secs, t.env_steps), f(t)?))).collect();
                resample(&smooth(&points, 1, &grid), &grid)
            };
            loss_values.push(train_values(|t| t.loss));
            q_values.push(train_values(|t| t.mean_q));
            if run.train.iter().any(|t| t.margin_loss.is_some()) {
                margin_values.push(train_values(|t| t.margin_loss));
            }
            let eval_points: Vec<(f64, f64)> =
                run.eval.iter().map(|e| (x.of(e.time_secs, e.env_steps), f64::from(e.route_types_mastered))).collect();
            eval_values.push(resample(&smooth(&eval_points, 1, &grid), &grid));
            for (k, kind) in kinds.iter().enumerate() {
                let of_kind: Vec<_> = run.episodes.iter().filter(|e| e.hazard.as_ref() == Some(kind)).collect();
                let kind_window = effective_window(opts.smoothing, of_kind.len());
                let share = |f: fn(&EpisodeRecord) -> bool| {
                    let points: Vec<(f64, f64)> =
                        of_kind.iter().map(|e| (x.of(e.time_secs, e.env_steps), if f(e) { 1.0 } else { 0.0 })).collect();
                    resample(&trailing_mean(&points, kind_window), &grid)
                };
                arrived_values[k].push(share(|e| e.arrived));
                collided_values[k].push(share(|e| e.collision.is_some()));
            }
            summary.runs.push(RunSummary {
                name: run.name.clone(),
                group: label.clone(),
                episodes: run.episodes.len(),
                train_points: run.train.len(),
                final_smoothed_return: return_curve.last().and_then(|c| c.last()).map(|p| p.1),
                eval_points: run.eval.len(),
                minutes_to_competence: run
                    .eval
                    .iter()
                    .find(|e| e.route_types_mastered >= COMPETENT_ROUTE_TYPES)
                    .map(|e| e.time_secs / 60.0),
            });
        }

        let run_summaries = &summary.runs[summary.runs.len() - group_runs.len()..];
        summary.groups.push(group_summary(&label, run_summaries));
        let several = group_runs.len() > 1;
        let (return_label, label) = match group.label() {
            Some(_) => {
                let seeds = if group_runs.len() == 1 { "1 seed".to_string() } else { format!("{} seeds", group_runs.len()) };
                let label = format!("{label} ({seeds})");
                (label.clone(), label)
            }
            None => {
                let episodes = group_runs[0].episodes.len();
                let return_label = match window_note {
                    Some(w) => format!("{label} ({episodes} episodes, window {w})"),
                    None => format!("{label} ({episodes} episodes)"),
                };
                (return_label, label)
            }
        };
        let series = |label: String, values: &[Vec<Option<f64>>]| Series {
            label,
            colour,
            pieces: band(values, &grid),
            band: several,
            markers: Vec::new(),
            dashed: false,
        };
        returns.push(series(return_label, &return_values));
        loss.push(series(label.clone(), &loss_values));
        if !margin_values.is_empty() {
            loss.push(Series { dashed: true, ..series(format!("{label} margin loss (demonstrations)"), &margin_values) });
        }
        mean_q.push(series(label.clone(), &q_values));
        for (panel, (arrived, collided)) in hazards.iter_mut().zip(arrived_values.iter().zip(&collided_values)) {
            panel.series.push(series(format!("{label} arrived"), arrived));
            panel.series.push(Series { dashed: true, ..series(format!("{label} collided"), collided) });
        }
        let mut eval_series = series(label, &eval_values);
        if !several {
            eval_series.markers =
                group_runs[0].eval.iter().map(|e| (x.of(e.time_secs, e.env_steps), f64::from(e.route_types_mastered))).collect();
        }
        evals.push(eval_series);
    }

    let with_eval = runs.iter().flatten().any(|r| !r.eval.is_empty());
    let curves = Curves { x_axis: x, x: grid.range(), returns, loss, mean_q, evals, with_eval, hazards };
    draw(out, (opts.width, opts.height), opts.smoothing, &curves)
        .map_err(|message| PlotError::Draw { path: out.to_path_buf(), message })?;
    Ok(summary)
}

/// A group's summary from its runs'.
fn group_summary(label: &str, runs: &[RunSummary]) -> GroupSummary {
    let mean = |values: Vec<f64>| (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64);
    let competent: Vec<f64> = runs.iter().filter_map(|r| r.minutes_to_competence).collect();
    GroupSummary {
        label: label.to_string(),
        runs: runs.len(),
        mean_final_smoothed_return: mean(runs.iter().filter_map(|r| r.final_smoothed_return).collect()),
        competent_runs: competent.len(),
        mean_minutes_to_competence: mean(competent),
    }
}
