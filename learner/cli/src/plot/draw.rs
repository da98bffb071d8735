//! Drawing the curves with plotters: the panels (smoothed return, loss on a log axis, mean Q,
//! greedy evaluations, per-hazard-kind shares) on one x axis, lines in pieces over shaded bands, round-number ticks, a
//! legend placed away from the data, and the embedded font.

use std::ops::Range;
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, DefaultFormatting, KeyPointHint, ValueFormatter};
use plotters::prelude::*;

use super::error::PlotError;
use super::grid::XAxis;
use super::series::{Curves, Series, bounds};

/// Line colours of the groups of runs, in order (cycled past ten).
pub(super) const COLOURS: [RGBColor; 10] = [
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

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans-Plot.ttf");

const FONT_FAMILY: &str = "sans-serif";

/// Registers the embedded font as plotters' `sans-serif` (every style falls back to it).
pub(super) fn register_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok { Ok(()) } else { Err(PlotError::Font) }
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

/// Draws the panels and writes the PNG; errors as text.
pub(super) fn draw(out: &Path, (width, height): (u32, u32), smoothing: usize, curves: &Curves) -> Result<(), String> {
    let Curves { x_axis, x, returns, loss, mean_q, evals, with_eval, hazards } = curves;
    // A fourth panel when any run has periodic greedy evaluations; then one per hazard kind.
    let eval_rows = usize::from(*with_eval);
    let rows = 3 + eval_rows + hazards.len();
    // `height` is that of four panels: hazard panels make the image taller, not every panel flatter.
    let height = if rows > 4 { (height as usize * rows / 4) as u32 } else { height };
    let root = BitMapBackend::new(out, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let panels = root.split_evenly((rows, 1));
    let sizes = TextSizes::for_panel(height / rows as u32);
    let x_fmt: &dyn Fn(&f64) -> String = match x_axis {
        // Minutes may be fractional (a short run); steps are counted.
        XAxis::Minutes => &|v: &f64| fmt_value(*v),
        XAxis::EnvSteps => &|v: &f64| fmt_count(*v),
    };
    let panel = |title: &str, y_desc: &'static str, series: &[Series]| Panel {
        // Say what the band is wherever one is drawn.
        title: if series.iter().any(|s| s.band) { format!("{title}; over seeds: mean, shaded min–max") } else { title.to_string() },
        x_desc: x_axis.description(),
        y_desc,
        x_fmt,
        sizes: &sizes,
    };
    let y_bounds = |series: &[Series]| bounds(series.iter().flat_map(|s| s.points().map(|p| p.1)));

    let title = format!("Smoothed episode return vs {x_axis} (mean of the last {smoothing} episodes)");
    panel(&title, "episode return", returns)
        .draw(&panels[0], x.clone(), padded(y_bounds(returns)), returns, &|v| fmt_value(*v))
        .map_err(|e| e.to_string())?;

    match y_bounds(loss) {
        Some((lo, hi)) if lo > 0.0 => {
            // Log scale: plot log10(loss) on a linear axis with ticks at 1, 2, 5 × 10^k.
            let range = padded(Some((lo.log10(), hi.log10())));
            let (ticks, minor) = log_ticks(&range);
            let log_loss: Vec<Series> = loss.iter().map(|s| s.map_y(f64::log10)).collect();
            panel("Loss", "loss (log scale)", loss)
                .draw(&panels[1], x.clone(), TickedAxis { range, ticks, minor }, &log_loss, &|v| fmt_value(10f64.powf(*v)))
        }
        b => panel("Loss", "loss", loss).draw(&panels[1], x.clone(), padded(b), loss, &|v| fmt_value(*v)),
    }
    .map_err(|e| e.to_string())?;

    panel("Mean Q", "mean Q", mean_q)
        .draw(&panels[2], x.clone(), padded(y_bounds(mean_q)), mean_q, &|v| fmt_value(*v))
        .map_err(|e| e.to_string())?;

    if *with_eval {
        panel("Greedy evaluation: route types completed in at least half their runs", "route types (of 7)", evals)
            .draw(&panels[3], x.clone(), -0.2..7.2, evals, &|v| fmt_value(*v))
            .map_err(|e| e.to_string())?;
    }

    for (k, h) in hazards.iter().enumerate() {
        let title = format!("Hazard {}: share arrived (solid), collided (dashed); last {smoothing} of its episodes", h.kind);
        panel(&title, "share of episodes", &h.series)
            .draw(&panels[3 + eval_rows + k], x.clone(), -0.05..1.05, &h.series, &|v| fmt_value(*v))
            .map_err(|e| e.to_string())?;
    }

    root.present().map_err(|e| e.to_string())
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
        let points = series.iter().flat_map(Series::points);
        points
            .filter(|&(px, py)| {
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
    title: String,
    x_desc: &'a str,
    y_desc: &'a str,
    x_fmt: &'a dyn Fn(&f64) -> String,
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
            .caption(&self.title, (FONT_FAMILY, s.caption))
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
            .x_label_formatter(self.x_fmt)
            .y_label_formatter(y_fmt)
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(200, 200, 200))
            .draw()?;
        // Bands first, so that every line is drawn over them.
        for s in series.iter().filter(|s| s.band) {
            let fill = s.colour.mix(0.2).filled();
            chart.draw_series(s.pieces.iter().filter(|p| p.len() > 1).map(|p| {
                let upper = p.iter().map(|b| (b.x, b.max));
                let lower = p.iter().rev().map(|b| (b.x, b.min));
                Polygon::new(upper.chain(lower).collect::<Vec<_>>(), fill)
            }))?;
        }
        for s in series {
            let colour = s.colour;
            for piece in &s.pieces {
                if let [only] = piece.as_slice() {
                    chart.draw_series(std::iter::once(Circle::new((only.x, only.mean), 3, colour.filled())))?;
                } else if s.dashed {
                    chart.draw_series(DashedLineSeries::new(piece.iter().map(|b| (b.x, b.mean)), 8, 5, colour.stroke_width(2)))?;
                } else {
                    chart.draw_series(LineSeries::new(piece.iter().map(|b| (b.x, b.mean)), colour.stroke_width(2)))?;
                }
            }
            chart.draw_series(s.markers.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
            let entry = chart.draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?.label(s.label.as_str());
            if s.band {
                let fill = colour.mix(0.2).filled();
                entry.legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + Rectangle::new([(0, -6), (20, 6)], fill)
                        + PathElement::new(vec![(0, 0), (20, 0)], colour.stroke_width(3))
                });
            } else if s.dashed {
                entry.legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new(vec![(0, 0), (7, 0)], colour.stroke_width(3))
                        + PathElement::new(vec![(13, 0), (20, 0)], colour.stroke_width(3))
                });
            } else {
                entry.legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3)));
            }
        }
        let any = series.iter().any(|s| !s.pieces.is_empty() || !s.markers.is_empty());
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
}
