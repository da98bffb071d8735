//! Learning curves of training runs, drawn to a PNG from the metrics the learner writes to its run
//! directory (`episodes.jsonl` and `train.jsonl`, JSON Lines).
//!
//! [`plot_runs`] draws three panels stacked vertically: the normalised smoothed episode return
//! against the episode index (the paper's Figure 5), the training loss and the mean Q-value
//! against the learner step. Text is drawn with a subset of DejaVu Sans embedded in the binary
//! (`assets/DejaVuSans-Plot.ttf`, made by `assets/make_plot_font.py`, license in
//! `assets/DejaVuSans-LICENSE.txt`), so plotting needs no system font or library.

use std::fs;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, DefaultFormatting, KeyPointHint, ValueFormatter};
use plotters::prelude::*;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// The file of finished episodes in a run directory.
pub const EPISODES_FILE: &str = "episodes.jsonl";
/// The file of periodic training reports in a run directory.
pub const TRAIN_FILE: &str = "train.jsonl";

/// One finished training episode: a line of `episodes.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeRecord {
    /// Seconds since the run started.
    pub time_secs: f64,
    /// Global count of finished episodes in the run, 1-based and increasing.
    pub episode_index: u64,
    pub actor_id: String,
    /// The actor's environment the episode ran in.
    pub env: u32,
    /// The undiscounted sum of rewards.
    #[serde(rename = "return")]
    pub episode_return: f64,
    pub steps: u32,
    pub arrived: bool,
    /// What the ego vehicle hit, if the episode ended in a collision.
    pub collision: Option<String>,
    pub scenario: String,
    /// The learner's update count when the episode was received.
    pub learner_step: u64,
    /// Environment steps received by the learner so far.
    pub env_steps: u64,
}

/// One reporting interval of the learner: a line of `train.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainRecord {
    pub time_secs: f64,
    pub learner_step: u64,
    pub env_steps: u64,
    pub transitions_stored: u64,
    /// Mean training loss over the interval; `None` before training starts.
    pub loss: Option<f64>,
    /// Mean Q-value over the interval; `None` before training starts.
    pub mean_q: Option<f64>,
    pub updates_per_sec: f64,
    pub env_steps_per_sec: f64,
    pub epsilon: f64,
    pub replay_size: u64,
    pub weights_version: u64,
    /// Episodes finished so far.
    pub episodes: u64,
}

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
}

/// Why a plot could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("no run directories to plot")]
    NoRuns,
    #[error("invalid plot options: {0}")]
    Options(String),
    #[error("run directory {} has no {EPISODES_FILE}", dir.display())]
    MissingEpisodes { dir: PathBuf },
    #[error("reading {}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{}: line {line}: {source}", path.display())]
    Parse { path: PathBuf, line: usize, source: serde_json::Error },
    #[error("the embedded font could not be loaded")]
    Font,
    #[error("drawing {}: {message}", path.display())]
    Draw { path: PathBuf, message: String },
}

/// Reads `episodes.jsonl`. See [`read_jsonl`] for how bad lines are handled.
pub fn read_episodes(path: &Path) -> Result<Vec<EpisodeRecord>, PlotError> {
    read_jsonl(path)
}

/// Reads `train.jsonl`. See [`read_jsonl`] for how bad lines are handled.
pub fn read_train(path: &Path) -> Result<Vec<TrainRecord>, PlotError> {
    read_jsonl(path)
}

/// Reads a JSON Lines file of records. Blank lines are skipped; so is a last line that does not
/// parse (a run killed mid-write truncates it), with a warning. Any other line that does not parse
/// is an error naming the file and the 1-based line number. Unknown fields are ignored.
pub fn read_jsonl<T: DeserializeOwned>(path: &Path) -> Result<Vec<T>, PlotError> {
    let bytes = fs::read(path).map_err(|source| PlotError::Io { path: path.to_path_buf(), source })?;
    let lines: Vec<&[u8]> = bytes.split(|&b| b == b'\n').collect();
    let last = lines.iter().rposition(|line| !line.trim_ascii().is_empty());
    let mut records = Vec::with_capacity(lines.len());
    for (i, line) in lines.iter().enumerate() {
        let line = line.trim_ascii();
        if line.is_empty() {
            continue;
        }
        match serde_json::from_slice(line) {
            Ok(record) => records.push(record),
            Err(e) if Some(i) == last => {
                tracing::warn!("{}: skipping unparsable last line {} (truncated?): {e}", path.display(), i + 1);
            }
            Err(source) => return Err(PlotError::Parse { path: path.to_path_buf(), line: i + 1, source }),
        }
    }
    Ok(records)
}

/// Line colours of the runs, in order (cycled past ten runs).
const COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans-Plot.ttf");
const FONT_FAMILY: &str = "sans-serif";

/// Registers the embedded font as plotters' `sans-serif` (every style falls back to it).
fn register_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok { Ok(()) } else { Err(PlotError::Font) }
}

/// One run's data, read.
struct Run {
    name: String,
    episodes: Vec<EpisodeRecord>,
    train: Vec<TrainRecord>,
}

fn read_run(dir: &Path) -> Result<Run, PlotError> {
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
    Ok(Run { name: run_name(dir), episodes, train })
}

/// The run directory's final path component (of its canonical path for `.` and the like).
fn run_name(dir: &Path) -> String {
    let name = dir.file_name().map(|n| n.to_os_string()).or_else(|| dir.canonicalize().ok()?.file_name().map(|n| n.to_os_string()));
    match name {
        Some(n) => n.to_string_lossy().into_owned(),
        None => dir.display().to_string(),
    }
}

/// The effective moving-average window of a run of `n` episodes: `smoothing`, shrunk to half the
/// run (rounded up) for short runs so that they still draw a curve.
fn effective_window(smoothing: usize, n: usize) -> usize {
    smoothing.min(n.div_ceil(2)).max(1)
}

/// Trailing moving average over full windows of `window` values: the point at `i` (for
/// `i >= window - 1`) is the mean of `values[i + 1 - window..=i]`.
fn moving_average(values: &[f64], window: usize) -> Vec<f64> {
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
fn normalise(v: f64, min: f64, max: f64) -> f64 {
    if max > min { (v - min) / (max - min) } else { 0.5 }
}

struct Series {
    label: String,
    colour: RGBColor,
    points: Vec<(f64, f64)>,
}

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

    draw(out, opts, return_bounds, &reward, &loss, &mean_q).map_err(|message| PlotError::Draw { path: out.to_path_buf(), message })?;
    Ok(PlotSummary { runs: summaries })
}

/// Appends " #2", " #3", … to names that an earlier run already has.
fn disambiguate_names(runs: &mut [Run]) {
    let names: Vec<String> = runs.iter().map(|r| r.name.clone()).collect();
    for (i, run) in runs.iter_mut().enumerate() {
        let earlier = names[..i].iter().filter(|n| **n == names[i]).count();
        if earlier > 0 {
            run.name = format!("{} #{}", names[i], earlier + 1);
        }
    }
}

/// The smallest and largest finite values, if any.
fn bounds(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.filter(|v| v.is_finite()).fold(None, |acc, v| match acc {
        None => Some((v, v)),
        Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
    })
}

/// Sizes of the text in a panel of `height` pixels.
struct TextSizes {
    caption: u32,
    axis_desc: u32,
    labels: u32,
}

impl TextSizes {
    fn for_panel(height: u32) -> Self {
        Self { caption: (height / 13).clamp(12, 30), axis_desc: (height / 18).clamp(10, 22), labels: (height / 22).clamp(9, 18) }
    }
}

/// Draws the three panels and writes the PNG; errors as text.
fn draw(
    out: &Path,
    opts: &PlotOptions,
    return_bounds: Option<(f64, f64)>,
    reward: &[Series],
    loss: &[Series],
    mean_q: &[Series],
) -> Result<(), String> {
    let root = BitMapBackend::new(out, (opts.width, opts.height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let panels = root.split_evenly((3, 1));
    let sizes = TextSizes::for_panel(opts.height / 3);

    let x_episodes = x_range(reward);
    let episode_desc = match return_bounds {
        Some((min, max)) if max > min => format!("episode   (normalised: 0 = return {}, 1 = return {})", fmt_value(min), fmt_value(max)),
        Some((v, _)) => format!("episode   (all smoothed returns are {})", fmt_value(v)),
        None => "episode".into(),
    };
    let reward_title = format!("Normalised reward vs episode (moving average of {} episodes)", opts.smoothing);
    let reward_panel = Panel { title: &reward_title, x_desc: &episode_desc, y_desc: "normalised return", sizes: &sizes };
    reward_panel.draw(&panels[0], x_episodes, -0.02..1.02, reward, &|v| fmt_value(*v)).map_err(|e| e.to_string())?;

    let loss_bounds = bounds(loss.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    let x_loss = x_range(loss);
    match loss_bounds {
        Some((lo, hi)) if lo > 0.0 => {
            // Log scale: plot log10(loss) on a linear axis with ticks at 1, 2, 5 × 10^k.
            let range = padded(Some((lo.log10(), hi.log10())));
            let (ticks, minor) = log_ticks(&range);
            let log_loss: Vec<Series> = loss
                .iter()
                .map(|s| Series {
                    label: s.label.clone(),
                    colour: s.colour,
                    points: s.points.iter().map(|&(x, y)| (x, y.log10())).collect(),
                })
                .collect();
            let panel = Panel { title: "Loss", x_desc: "learner step", y_desc: "loss (log scale)", sizes: &sizes };
            panel.draw(&panels[1], x_loss, TickedAxis { range, ticks, minor }, &log_loss, &|v| fmt_value(10f64.powf(*v)))
        }
        b => {
            let panel = Panel { title: "Loss", x_desc: "learner step", y_desc: "loss", sizes: &sizes };
            panel.draw(&panels[1], x_loss, padded(b), loss, &|v| fmt_value(*v))
        }
    }
    .map_err(|e| e.to_string())?;

    let q_bounds = bounds(mean_q.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    let panel = Panel { title: "Mean Q", x_desc: "learner step", y_desc: "mean Q", sizes: &sizes };
    panel.draw(&panels[2], x_range(mean_q), padded(q_bounds), mean_q, &|v| fmt_value(*v)).map_err(|e| e.to_string())?;

    root.present().map_err(|e| e.to_string())
}

/// The x range covering every series' points (0..1 with none).
fn x_range(series: &[Series]) -> Range<f64> {
    match bounds(series.iter().flat_map(|s| s.points.iter().map(|p| p.0))) {
        Some((lo, hi)) if hi > lo => lo..hi,
        Some((lo, _)) => lo - 1.0..lo + 1.0,
        None => 0.0..1.0,
    }
}

/// A linear y range around `bounds`, with 5% margins (0..1 with no data).
fn padded(bounds: Option<(f64, f64)>) -> Range<f64> {
    match bounds {
        Some((lo, hi)) if hi > lo => {
            let pad = (hi - lo) * 0.05;
            lo - pad..hi + pad
        }
        Some((v, _)) => {
            let pad = if v == 0.0 { 1.0 } else { v.abs() * 0.1 };
            v - pad..v + pad
        }
        None => 0.0..1.0,
    }
}

/// Ticks for an axis of log10 values spanning `range`: the powers of ten, or 1, 2, 5 × 10^k, or
/// 1…9 × 10^k, whichever first gives at least three (powers of ten thinned to at most eight);
/// and minor ticks at 1…9 × 10^k (none if there would be too many).
fn log_ticks(range: &Range<f64>) -> (Vec<f64>, Vec<f64>) {
    let (lo, hi) = (range.start, range.end);
    let decades = (lo.floor() as i32)..=(hi.ceil() as i32);
    let ticks = |mults: &[f64]| -> Vec<f64> {
        decades.clone().flat_map(|d| mults.iter().map(move |m| (m * 10f64.powi(d)).log10())).filter(|v| (lo..=hi).contains(v)).collect()
    };
    let all = ticks(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    let minor = if all.len() <= 60 { all } else { Vec::new() };
    let powers = ticks(&[1.0]);
    if powers.len() > 8 {
        return (powers.iter().copied().step_by(powers.len().div_ceil(8)).collect(), minor);
    }
    let mut best = powers;
    for mults in [&[1.0, 2.0, 5.0][..], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]] {
        if best.len() >= 3 {
            break;
        }
        best = ticks(mults);
    }
    if best.len() < 2 {
        best = (0..5).map(|i| lo + (hi - lo) * (0.1 + 0.2 * i as f64)).collect();
    }
    (best, minor)
}

/// A linear axis of `f64` with given labelled ticks and minor grid lines.
struct TickedAxis {
    range: Range<f64>,
    ticks: Vec<f64>,
    minor: Vec<f64>,
}

impl Ranged for TickedAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let t = (value - self.range.start) / (self.range.end - self.range.start);
        limit.0 + (t * f64::from(limit.1 - limit.0)).round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() { self.minor.clone() } else { self.ticks.clone() }
    }

    fn range(&self) -> Range<f64> {
        self.range.clone()
    }
}

/// The corner of the plot for the legend: the one with the fewest data points near it (the lower
/// right on a tie).
fn legend_corner(series: &[Series], x: Range<f64>, y: Range<f64>) -> SeriesLabelPosition {
    let frac = |v: f64, r: &Range<f64>| if r.end > r.start { (v - r.start) / (r.end - r.start) } else { 0.5 };
    let corners = [
        (SeriesLabelPosition::LowerRight, true, false),
        (SeriesLabelPosition::UpperRight, true, true),
        (SeriesLabelPosition::UpperLeft, false, true),
        (SeriesLabelPosition::LowerLeft, false, false),
    ];
    let near = |right: bool, upper: bool| {
        let points = series.iter().flat_map(|s| s.points.iter());
        points
            .filter(|&&(px, py)| {
                let (fx, fy) = (frac(px, &x), frac(py, &y));
                (if right { fx > 0.5 } else { fx < 0.5 }) && (if upper { fy > 0.6 } else { fy < 0.4 })
            })
            .count()
    };
    let counts: Vec<usize> = corners.iter().map(|&(_, right, upper)| near(right, upper)).collect();
    let best = (0..corners.len()).min_by_key(|&i| counts[i]).unwrap_or(0);
    corners.into_iter().nth(best).map(|c| c.0).unwrap_or(SeriesLabelPosition::LowerRight)
}

struct Panel<'a> {
    title: &'a str,
    x_desc: &'a str,
    y_desc: &'a str,
    sizes: &'a TextSizes,
}

impl Panel<'_> {
    fn draw<DB, Y>(
        &self,
        area: &DrawingArea<DB, Shift>,
        x: Range<f64>,
        y: Y,
        series: &[Series],
        y_fmt: &dyn Fn(&f64) -> String,
    ) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>>
    where
        DB: DrawingBackend,
        Y: AsRangedCoord<Value = f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let s = self.sizes;
        let mut chart = ChartBuilder::on(area)
            .caption(self.title, (FONT_FAMILY, s.caption))
            .margin(8)
            .margin_right(20)
            .x_label_area_size(s.labels * 2 + s.axis_desc + 6)
            .y_label_area_size(s.labels * 4 + s.axis_desc + 10)
            .build_cartesian_2d(x, y)?;
        chart
            .configure_mesh()
            .x_desc(self.x_desc)
            .y_desc(self.y_desc)
            .axis_desc_style((FONT_FAMILY, s.axis_desc))
            .label_style((FONT_FAMILY, s.labels))
            .x_label_formatter(&|v| fmt_count(*v))
            .y_label_formatter(y_fmt)
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(200, 200, 200))
            .draw()?;
        let mut any = false;
        for s in series {
            let colour = s.colour;
            if s.points.len() == 1 {
                chart.draw_series(s.points.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
            } else {
                chart.draw_series(LineSeries::new(s.points.iter().copied(), colour.stroke_width(2)))?;
            }
            chart
                .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
                .label(s.label.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3)));
            any |= !s.points.is_empty();
        }
        let legend = legend_corner(series, chart.x_range(), chart.y_range());
        chart
            .configure_series_labels()
            .position(legend)
            .label_font((FONT_FAMILY, self.sizes.labels))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .draw()?;
        if !any {
            let (w, h) = chart.plotting_area().dim_in_pixel();
            let style = TextStyle::from((FONT_FAMILY, self.sizes.axis_desc).into_font()).color(&RGBColor(120, 120, 120));
            chart.plotting_area().strip_coord_spec().draw(&Text::new("no data yet", (w as i32 / 2 - 40, h as i32 / 2), style))?;
        }
        Ok(())
    }
}

/// An axis label for counts (episodes, steps): "950", "12k", "1.5M"; none for fractions.
fn fmt_count(v: f64) -> String {
    let a = v.abs();
    if a >= 1e6 {
        format!("{}M", trim_decimals(format!("{:.2}", v / 1e6)))
    } else if a >= 1e4 {
        format!("{}k", trim_decimals(format!("{:.1}", v / 1e3)))
    } else if (v - v.round()).abs() < 1e-9 {
        format!("{}", v.round() as i64)
    } else {
        // Counts are whole: no label between them.
        String::new()
    }
}

/// An axis label for values: three significant digits, scientific when very large or small.
fn fmt_value(v: f64) -> String {
    let a = v.abs();
    if a < 1e-12 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        let s = format!("{v:.1e}");
        s.replace(".0e", "e")
    } else {
        let decimals = (2 - a.log10().floor() as i32).clamp(0, 5) as usize;
        trim_decimals(format!("{v:.decimals$}"))
    }
}

/// "1.50" → "1.5", "2.00" → "2", "-0" → "0".
fn trim_decimals(s: String) -> String {
    let t = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { &s };
    if t == "-0" { "0".into() } else { t.to_string() }
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
    fn labels_are_short() {
        assert_eq!(fmt_count(0.0), "0");
        assert_eq!(fmt_count(500.0), "500");
        assert_eq!(fmt_count(4.5), "");
        assert_eq!(fmt_count(25_000.0), "25k");
        assert_eq!(fmt_count(1_500_000.0), "1.5M");
        assert_eq!(fmt_value(0.25), "0.25");
        assert_eq!(fmt_value(1.0), "1");
        assert_eq!(fmt_value(-12.345), "-12.3");
        assert_eq!(fmt_value(0.0001), "1e-4");
        assert_eq!(fmt_value(250_000.0), "2.5e5");
    }

    #[test]
    fn log_ticks_are_round_numbers() {
        let labels =
            |lo: f64, hi: f64| log_ticks(&(lo.log10()..hi.log10())).0.iter().map(|v| fmt_value(10f64.powf(*v))).collect::<Vec<_>>();
        assert_eq!(labels(0.05, 3.0), ["0.05", "0.1", "0.2", "0.5", "1", "2"]);
        assert_eq!(labels(1e-6, 10.0), ["1e-6", "1e-5", "1e-4", "0.001", "0.01", "0.1", "1", "10"]);
        assert_eq!(labels(1e-12, 1.0).len(), 7);
        assert_eq!(labels(0.3, 0.9), ["0.3", "0.4", "0.5", "0.6", "0.7", "0.8", "0.9"]);
        assert_eq!(labels(0.51, 0.52).len(), 5);
    }

    #[test]
    fn duplicate_names_are_numbered() {
        let run = |name: &str| Run { name: name.into(), episodes: Vec::new(), train: Vec::new() };
        let mut runs = vec![run("a"), run("b"), run("a"), run("a")];
        disambiguate_names(&mut runs);
        let names: Vec<_> = runs.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(names, ["a", "b", "a #2", "a #3"]);
    }

    #[test]
    fn records_round_trip_with_the_documented_field_names() {
        let e = EpisodeRecord {
            time_secs: 1.5,
            episode_index: 3,
            actor_id: "actor-0".into(),
            env: 1,
            episode_return: -2.5,
            steps: 40,
            arrived: false,
            collision: None,
            scenario: "right_turn".into(),
            learner_step: 10,
            env_steps: 400,
        };
        let json = serde_json::to_value(&e).unwrap();
        assert_eq!(json["return"], -2.5);
        assert!(json["collision"].is_null());
        assert_eq!(serde_json::from_value::<EpisodeRecord>(json).unwrap(), e);
    }
}
