//! The common x axis of a plot (minutes or environment steps) and the curves on it: each run's
//! points smoothed by a trailing moving average within stretches of data without a gap, resampled
//! onto one grid of x values that every run shares, and a group's mean and min–max band over its
//! runs at each grid point.
//!
//! Resampling is what makes lines clean: a run with tens of thousands of episodes draws
//! [`GRID_POINTS`] points, not one per episode; a line is continuous wherever its run has data and
//! breaks where it has none; and the runs of one agent can be averaged point by point.

use std::fmt;
use std::ops::Range;
use std::str::FromStr;

use super::error::PlotError;

/// Points of the common grid, from the smallest x of any record to the largest.
pub(super) const GRID_POINTS: usize = 200;

/// Consecutive points further apart than this many grid cells (or [`GAP_SPACINGS`] times the run's
/// median spacing, if wider) are a gap: the line breaks there.
const GAP_CELLS: f64 = 3.0;
/// See [`GAP_CELLS`]: sparse but regular records (`train.jsonl` every 10 s in a five-minute run
/// are several cells apart) still make one line.
const GAP_SPACINGS: f64 = 5.0;

/// The x axis of every panel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum XAxis {
    /// Minutes of training: `time_secs / 60` of every record (summed over resumes).
    #[default]
    Minutes,
    /// Environment steps received by the learner: `env_steps` of every record.
    EnvSteps,
}

impl XAxis {
    /// `minutes` or `env-steps`.
    pub fn parse(s: &str) -> Result<Self, PlotError> {
        match s {
            "minutes" => Ok(Self::Minutes),
            "env-steps" => Ok(Self::EnvSteps),
            other => Err(PlotError::XAxis { value: other.into() }),
        }
    }

    /// The x of a record with these fields.
    pub(super) fn of(self, time_secs: f64, env_steps: u64) -> f64 {
        match self {
            Self::Minutes => time_secs / 60.0,
            Self::EnvSteps => env_steps as f64,
        }
    }

    /// The axis description under each panel.
    pub(super) fn description(self) -> &'static str {
        match self {
            Self::Minutes => "minutes of training",
            Self::EnvSteps => "environment steps",
        }
    }
}

impl FromStr for XAxis {
    type Err = PlotError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::parse(s)
    }
}

impl fmt::Display for XAxis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Minutes => "minutes",
            Self::EnvSteps => "env steps",
        })
    }
}

/// Evenly spaced x values shared by every run of a plot.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Grid {
    lo: f64,
    step: f64,
    n: usize,
}

impl Grid {
    /// `n` points (at least 2) from the smallest to the largest finite value of `xs`; one unit
    /// either side of a single value, and 0..1 without any.
    pub(super) fn spanning(xs: impl Iterator<Item = f64>, n: usize) -> Self {
        let n = n.max(2);
        let bounds = xs.filter(|x| x.is_finite()).fold(None, |acc: Option<(f64, f64)>, x| match acc {
            None => Some((x, x)),
            Some((lo, hi)) => Some((lo.min(x), hi.max(x))),
        });
        let (lo, hi) = match bounds {
            Some((lo, hi)) if hi > lo => (lo, hi),
            Some((x, _)) => (x - 1.0, x + 1.0),
            None => (0.0, 1.0),
        };
        Self { lo, step: (hi - lo) / (n - 1) as f64, n }
    }

    pub(super) fn len(&self) -> usize {
        self.n
    }

    /// The `k`-th x value.
    pub(super) fn x(&self, k: usize) -> f64 {
        self.lo + self.step * k as f64
    }

    /// From the first x value to the last.
    pub(super) fn range(&self) -> Range<f64> {
        self.lo..self.x(self.n - 1)
    }

    /// The distance between neighbouring x values.
    pub(super) fn cell(&self) -> f64 {
        self.step
    }

    /// The indices of the grid points in `[a, b]` (with a little tolerance for rounding).
    fn indices_within(&self, a: f64, b: f64) -> Range<usize> {
        const EPS: f64 = 1e-9;
        let last = ((b - self.lo) / self.step + EPS).floor();
        if last < 0.0 {
            return 0..0;
        }
        let end = (last as usize).saturating_add(1).min(self.n);
        let first = ((a - self.lo) / self.step - EPS).ceil().max(0.0) as usize;
        first.min(end)..end
    }
}

/// A run's smoothed curve, in stretches without a gap: within each, from the `window`-th point on,
/// the trailing mean of the last `window` points, or of every point in the last grid cell when
/// those are more (so that no point between two grid values is skipped: dense data does not
/// alias). The window never reaches across a gap (consecutive points further apart than
/// [`gap_width`]), so it fills again after one; a stretch shorter than the window has no curve.
/// Points with a non-finite x or y are skipped; the rest are taken in order of x.
pub(super) fn smooth(points: &[(f64, f64)], window: usize, grid: &Grid) -> Vec<Vec<(f64, f64)>> {
    assert!(window >= 1);
    let mut points: Vec<(f64, f64)> = points.iter().copied().filter(|p| p.0.is_finite() && p.1.is_finite()).collect();
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    let gap = gap_width(&points, grid.cell());
    let mut curves = Vec::new();
    let mut start = 0;
    for end in 1..=points.len() {
        if end < points.len() && points[end].0 - points[end - 1].0 <= gap {
            continue;
        }
        let stretch = &points[start..end];
        start = end;
        // Prefix sums: the mean of any trailing window in O(1).
        let mut prefix = Vec::with_capacity(stretch.len() + 1);
        let mut sum = 0.0;
        prefix.push(sum);
        for p in stretch {
            sum += p.1;
            prefix.push(sum);
        }
        // The cell is (x - cell, x]; a point one cell back (up to rounding) is not in it.
        let cell = grid.cell() * (1.0 - 1e-6);
        let mut cell_start = 0;
        let mut curve = Vec::new();
        for (i, p) in stretch.iter().enumerate() {
            while stretch[cell_start].0 <= p.0 - cell {
                cell_start += 1;
            }
            if i + 1 < window {
                continue;
            }
            let n = window.max(i + 1 - cell_start);
            curve.push((p.0, (prefix[i + 1] - prefix[i + 1 - n]) / n as f64));
        }
        if !curve.is_empty() {
            curves.push(curve);
        }
    }
    curves
}

/// The trailing mean of the last `window` points (in their order), from the `window`-th point on,
/// as one stretch: for sparse, irregular series (one hazard kind's episodes) whose spacing says
/// nothing of a pause, where [`smooth`]'s gaps would cut the curve and make its window refill.
pub(super) fn trailing_mean(points: &[(f64, f64)], window: usize) -> Vec<Vec<(f64, f64)>> {
    assert!(window >= 1);
    if points.len() < window {
        return Vec::new();
    }
    let mut sum: f64 = points[..window - 1].iter().map(|p| p.1).sum();
    let mut out = Vec::with_capacity(points.len() + 1 - window);
    for i in window - 1..points.len() {
        sum += points[i].1;
        out.push((points[i].0, sum / window as f64));
        sum -= points[i + 1 - window].1;
    }
    vec![out]
}

/// The widest spacing of consecutive x values (`sorted` by x) that is not a gap: [`GAP_CELLS`]
/// grid cells, or [`GAP_SPACINGS`] times the median spacing if that is wider.
fn gap_width(sorted: &[(f64, f64)], cell: f64) -> f64 {
    let mut spacings: Vec<f64> = sorted.windows(2).map(|w| w[1].0 - w[0].0).collect();
    let median = if spacings.is_empty() {
        0.0
    } else {
        let mid = spacings.len() / 2;
        *spacings.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    (GAP_CELLS * cell).max(GAP_SPACINGS * median)
}

/// A smoothed curve's value at each grid point: interpolated linearly between its points, `None`
/// outside them (before the first full window, after the last point, between stretches). A lone
/// grid value (no neighbour with a value) is dropped too: data narrower than a grid cell would draw
/// a single pixel.
pub(super) fn resample(curves: &[Vec<(f64, f64)>], grid: &Grid) -> Vec<Option<f64>> {
    let mut values = vec![None; grid.len()];
    for curve in curves {
        let (Some(first), Some(last)) = (curve.first(), curve.last()) else { continue };
        for k in grid.indices_within(first.0, last.0) {
            values[k] = Some(interpolate(curve, grid.x(k)));
        }
    }
    let has = |k: Option<usize>| k.and_then(|k| values.get(k)).is_some_and(Option::is_some);
    let lone: Vec<bool> = (0..values.len()).map(|k| !has(k.checked_sub(1)) && !has(Some(k + 1))).collect();
    for (v, lone) in values.iter_mut().zip(lone) {
        if lone {
            *v = None;
        }
    }
    values
}

/// `curve` (sorted by x, not empty) at `x`: linear between the points around it, the end value
/// beyond an end.
fn interpolate(curve: &[(f64, f64)], x: f64) -> f64 {
    let i = curve.partition_point(|p| p.0 <= x);
    if i == 0 {
        return curve[0].1;
    }
    if i == curve.len() {
        return curve[i - 1].1;
    }
    let (a, b) = (curve[i - 1], curve[i]);
    a.1 + (b.1 - a.1) * (x - a.0) / (b.0 - a.0)
}

/// A point of a group's line: the mean over the group's runs that have a value at `x`, and the
/// smallest and largest of those values (the band).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct BandPoint {
    pub(super) x: f64,
    pub(super) mean: f64,
    pub(super) min: f64,
    pub(super) max: f64,
}

/// A group's line in pieces: a [`BandPoint`] at each grid point where at least one of `runs`
/// (each resampled onto `grid`) has a value; a piece ends where none has. For a single run the
/// mean, min and max are its value.
pub(super) fn band(runs: &[Vec<Option<f64>>], grid: &Grid) -> Vec<Vec<BandPoint>> {
    let mut pieces = Vec::new();
    let mut piece = Vec::new();
    for k in 0..grid.len() {
        let values: Vec<f64> = runs.iter().filter_map(|r| r.get(k).copied().flatten()).collect();
        if values.is_empty() {
            if !piece.is_empty() {
                pieces.push(std::mem::take(&mut piece));
            }
            continue;
        }
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        piece.push(BandPoint { x: grid.x(k), mean, min, max });
    }
    if !piece.is_empty() {
        pieces.push(piece);
    }
    pieces
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid with x = 0, 1, …, n - 1.
    fn unit_grid(n: usize) -> Grid {
        Grid::spanning([0.0, (n - 1) as f64].into_iter(), n)
    }

    #[test]
    fn x_axes_parse_and_read_records() {
        assert_eq!(XAxis::parse("minutes").unwrap(), XAxis::Minutes);
        assert_eq!("env-steps".parse::<XAxis>().unwrap(), XAxis::EnvSteps);
        assert_eq!(XAxis::default(), XAxis::Minutes);
        let err = XAxis::parse("episodes").unwrap_err();
        assert!(err.to_string().contains("`episodes`") && err.to_string().contains("env-steps"), "{err}");
        assert_eq!(XAxis::Minutes.of(90.0, 7), 1.5);
        assert_eq!(XAxis::EnvSteps.of(90.0, 7), 7.0);
    }

    #[test]
    fn the_grid_spans_the_data() {
        let g = Grid::spanning([3.0, f64::NAN, 1.0, 2.0].into_iter(), 5);
        assert_eq!((g.len(), g.x(0), g.x(4), g.cell()), (5, 1.0, 3.0, 0.5));
        assert_eq!(g.range(), 1.0..3.0);
        assert_eq!(Grid::spanning([2.0].into_iter(), 3).range(), 1.0..3.0);
        assert_eq!(Grid::spanning(std::iter::empty(), 3).range(), 0.0..1.0);
        assert_eq!(g.indices_within(1.2, 2.5), 1..4);
        assert_eq!(g.indices_within(-5.0, 0.5), 0..0);
        assert_eq!(g.indices_within(2.9, 9.0), 4..5);
    }

    #[test]
    fn a_trailing_mean_is_one_stretch_whatever_the_spacing() {
        let points = [(0.0, 1.0), (1.0, 0.0), (50.0, 1.0), (51.0, 1.0)];
        assert_eq!(trailing_mean(&points, 2), vec![vec![(1.0, 0.5), (50.0, 0.5), (51.0, 1.0)]]);
        assert_eq!(trailing_mean(&points, 1).concat().len(), 4);
        assert!(trailing_mean(&points, 5).is_empty());
    }

    #[test]
    fn smoothing_uses_full_trailing_windows() {
        let grid = unit_grid(10);
        let pts = |ys: &[f64]| ys.iter().enumerate().map(|(i, &y)| (i as f64, y)).collect::<Vec<_>>();
        assert_eq!(smooth(&pts(&[1.0, 2.0, 3.0, 4.0]), 2, &grid), vec![vec![(1.0, 1.5), (2.0, 2.5), (3.0, 3.5)]]);
        assert_eq!(smooth(&pts(&[1.0, 2.0, 3.0]), 3, &grid), vec![vec![(2.0, 2.0)]]);
        assert_eq!(smooth(&pts(&[1.0, 2.0]), 3, &grid), Vec::<Vec<_>>::new());
        assert_eq!(smooth(&pts(&[5.0, 7.0]), 1, &grid), vec![vec![(0.0, 5.0), (1.0, 7.0)]]);
        // Non-finite values are skipped; points are taken in order of x.
        let messy = [(2.0, 3.0), (0.0, 1.0), (1.0, f64::NAN), (f64::INFINITY, 9.0), (1.0, 2.0)];
        assert_eq!(smooth(&messy, 2, &grid), vec![vec![(1.0, 1.5), (2.0, 2.5)]]);
    }

    #[test]
    fn dense_points_are_averaged_over_a_whole_grid_cell() {
        // Ten points per cell of width 1: a window of 2 points widens to the cell's points.
        let grid = unit_grid(5);
        let points: Vec<(f64, f64)> = (0..40).map(|i| (i as f64 / 10.0, if i % 2 == 0 { 0.0 } else { 10.0 })).collect();
        let curves = smooth(&points, 2, &grid);
        assert_eq!(curves.len(), 1);
        let late: Vec<f64> = curves[0].iter().filter(|p| p.0 >= 1.0).map(|p| p.1).collect();
        assert!(late.iter().all(|&v| (v - 5.0).abs() < 1e-9), "{late:?}");
    }

    #[test]
    fn a_gap_breaks_the_line_without_isolated_points() {
        // Points every 0.1 on [0, 4] and [6, 10], a lone point at 5, on a grid with cells of 0.1.
        let grid = Grid::spanning([0.0, 10.0].into_iter(), 101);
        let mut points: Vec<(f64, f64)> = (0..=40).chain(60..=100).map(|i| (i as f64 / 10.0, i as f64)).collect();
        points.push((5.0, 50.0));
        let curves = smooth(&points, 1, &grid);
        assert_eq!(curves.len(), 3, "two stretches and the lone point");
        let values = resample(&curves, &grid);
        let defined: Vec<usize> = (0..values.len()).filter(|&k| values[k].is_some()).collect();
        assert_eq!(defined, (0..=40).chain(60..=100).collect::<Vec<_>>(), "the gap breaks the line and the lone point is dropped");
        for k in defined {
            assert!((values[k].unwrap() - k as f64).abs() < 1e-9, "interpolated at {k}: {:?}", values[k]);
        }
        // No isolated values, and a line of each stretch.
        let pieces = band(&[resample(&curves, &grid)], &grid);
        assert_eq!(pieces.iter().map(Vec::len).collect::<Vec<_>>(), [41, 41]);

        // The window fills again after the gap: with 5 points, the second stretch starts at its
        // fifth point (6.4), not with a mean reaching back before the gap.
        let values = resample(&smooth(&points, 5, &grid), &grid);
        assert!(values[63].is_none() && values[64].is_some());
        assert!((values[64].unwrap() - 62.0).abs() < 1e-9, "{:?}", values[64]);
    }

    #[test]
    fn sparse_regular_points_are_one_line() {
        // A point every 7 cells: far apart, but regular, so no gap.
        let grid = unit_grid(100);
        let points: Vec<(f64, f64)> = (0..15).map(|i| (i as f64 * 7.0, 1.0)).collect();
        let values = resample(&smooth(&points, 1, &grid), &grid);
        assert!(values[..=98].iter().all(Option::is_some) && values[99].is_none(), "{values:?}");
    }

    #[test]
    fn the_band_is_the_mean_min_and_max_over_runs_with_data() {
        let grid = unit_grid(4);
        let runs = vec![
            vec![Some(1.0), Some(2.0), None, Some(0.0)],
            vec![Some(3.0), Some(4.0), None, None],
            vec![Some(5.0), Some(9.0), None, None],
        ];
        let pieces = band(&runs, &grid);
        let p = |x: f64, mean: f64, min: f64, max: f64| BandPoint { x, mean, min, max };
        assert_eq!(pieces, vec![vec![p(0.0, 3.0, 1.0, 5.0), p(1.0, 5.0, 2.0, 9.0)], vec![p(3.0, 0.0, 0.0, 0.0)]]);
        assert_eq!(band(&[vec![None; 4]], &grid), Vec::<Vec<BandPoint>>::new());
    }
}
