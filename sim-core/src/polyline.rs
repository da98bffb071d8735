//! Polylines parametrised by arc length: lanes, connectors and routes are all made of these.

use crate::math::{Vec2, cross, heading_of};

/// A sequence of points with cumulative arc length. Always has at least two points and positive
/// length (constructors enforce it).
#[derive(Debug, Clone)]
pub struct Polyline {
    points: Vec<Vec2>,
    /// `cum[i]` = arc length from `points[0]` to `points[i]`.
    cum: Vec<f32>,
    /// Per run of [`BLOCK`] segments, a disc holding them (see [`Reach`]).
    blocks: Vec<Reach>,
    /// Per segment, its heading (radians): every car's pose asks for it every step.
    headings: Vec<f32>,
}

/// Segments per [`Reach`]: projections test a run's disc before its segments.
const BLOCK: usize = 8;

/// Relative slack of a [`Reach`]'s test. An f32 rounding is at most 6e-8 of the magnitudes
/// involved and the exact scan rounds a handful of times, so a run the test rejects is farther
/// than the best distance by far more than any rounding of that scan: skipping it changes no bit.
const SLACK: f32 = 1e-5;

/// A disc containing every point of a run of segments, its radius widened by [`SLACK`] of the
/// coordinates so that a lower bound on the distance to the run's segments is safe under
/// rounding.
#[derive(Debug, Clone, Copy)]
struct Reach {
    centre: Vec2,
    radius: f32,
}

impl Reach {
    fn around(points: &[Vec2]) -> Self {
        let (lo, hi) = points.iter().fold((points[0], points[0]), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        let centre = (lo + hi) * 0.5;
        let r = points.iter().map(|&p| p.distance(centre)).fold(0.0f32, f32::max);
        Self { centre, radius: r * (1.0 + SLACK) + SLACK * (centre.x.abs() + centre.y.abs() + 1.0) }
    }

    /// A lower bound on the distance from `p` to the run's segments, less the slack of `p`'s
    /// coordinates (`p_slack`).
    #[inline]
    fn below(&self, p: Vec2, p_slack: f32) -> f32 {
        p.distance(self.centre) - self.radius - p_slack
    }
}

/// The closest point of a polyline to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// Arc length of the closest point.
    pub s: f32,
    /// Signed lateral offset of the query point: positive to the left of the direction of travel.
    pub lateral: f32,
    /// Euclidean distance from the query point to the closest point.
    pub distance: f32,
    /// Index of the segment holding the closest point.
    pub segment: usize,
}

impl Polyline {
    /// Builds a polyline, dropping consecutive duplicate points. Returns `None` when fewer than two
    /// distinct points remain.
    #[must_use]
    pub fn new(points: impl IntoIterator<Item = Vec2>) -> Option<Self> {
        let mut pts: Vec<Vec2> = Vec::new();
        for p in points {
            if pts.last().is_none_or(|q| q.distance(p) > 1e-4) {
                pts.push(p);
            }
        }
        if pts.len() < 2 {
            return None;
        }
        let mut cum = Vec::with_capacity(pts.len());
        let mut acc = 0.0;
        cum.push(0.0);
        for w in pts.windows(2) {
            acc += w[0].distance(w[1]);
            cum.push(acc);
        }
        let blocks = (0..pts.len() - 1).step_by(BLOCK).map(|i| Reach::around(&pts[i..(i + BLOCK + 1).min(pts.len())])).collect();
        let headings = pts.windows(2).map(|w| heading_of(w[1] - w[0])).collect();
        Some(Self { points: pts, cum, blocks, headings })
    }

    /// The vertices.
    #[must_use]
    pub fn points(&self) -> &[Vec2] {
        &self.points
    }

    /// Total arc length in metres.
    #[must_use]
    pub fn length(&self) -> f32 {
        *self.cum.last().expect("polyline has points")
    }

    /// First point.
    #[must_use]
    pub fn start(&self) -> Vec2 {
        self.points[0]
    }

    /// Last point.
    #[must_use]
    pub fn end(&self) -> Vec2 {
        *self.points.last().expect("polyline has points")
    }

    /// Index of the segment containing arc length `s` (clamped to the polyline).
    #[must_use]
    pub fn segment_at(&self, s: f32) -> usize {
        let n = self.points.len() - 1;
        // partition_point gives the first vertex with cum > s; the segment starts one before it.
        let i = self.cum.partition_point(|&c| c <= s);
        i.saturating_sub(1).min(n - 1)
    }

    /// Point at arc length `s` (clamped to the ends).
    #[must_use]
    pub fn point_at(&self, s: f32) -> Vec2 {
        self.point_at_from(s, self.segment_at(s))
    }

    /// Point at arc length `s`, given the segment that holds it.
    fn point_at_from(&self, s: f32, seg: usize) -> Vec2 {
        let (a, b) = (self.points[seg], self.points[seg + 1]);
        let len = self.cum[seg + 1] - self.cum[seg];
        let t = ((s - self.cum[seg]) / len).clamp(0.0, 1.0);
        a + (b - a) * t
    }

    /// Unit tangent at arc length `s`.
    #[must_use]
    pub fn tangent_at(&self, s: f32) -> Vec2 {
        let seg = self.segment_at(s);
        (self.points[seg + 1] - self.points[seg]).normalize()
    }

    /// Heading (radians) at arc length `s`.
    #[must_use]
    pub fn heading_at(&self, s: f32) -> f32 {
        heading_of(self.tangent_at(s))
    }

    /// Point and heading at arc length `s`, searching for the segment from `hint` (a segment index
    /// close to the answer, usually the previous step's). Returns the segment found, to be passed
    /// back as the next hint: this makes following a polyline O(1) per step.
    #[must_use]
    pub fn pose_at_hinted(&self, s: f32, hint: usize) -> (Vec2, f32, usize) {
        let n = self.points.len() - 1;
        let mut seg = hint.min(n - 1);
        let s = s.clamp(0.0, self.length());
        while seg + 1 < n && self.cum[seg + 1] < s {
            seg += 1;
        }
        while seg > 0 && self.cum[seg] > s {
            seg -= 1;
        }
        let p = self.point_at_from(s, seg);
        (p, self.headings[seg], seg)
    }

    /// The closest point to `p` over the whole polyline.
    #[must_use]
    pub fn project(&self, p: Vec2) -> Projection {
        self.project_range(p, 0, self.points.len() - 1)
    }

    /// The closest point to `p` among segments `first..last` (clamped to the polyline): the
    /// first of the segments at the least distance.
    ///
    /// As a scan of every segment in order, but a run of segments whose disc lies farther than
    /// a distance already found is skipped: the run nearest by its disc is scanned first, for
    /// a good bound, then the runs before it and after it in order.
    #[must_use]
    pub fn project_range(&self, p: Vec2, first: usize, last: usize) -> Projection {
        let last = last.min(self.points.len() - 1);
        let first = first.min(last.saturating_sub(1));
        let none = Best { proj: Projection { s: 0.0, lateral: 0.0, distance: f32::INFINITY, segment: first }, d2: f32::INFINITY };
        if first >= last {
            return none.proj;
        }
        let p_slack = SLACK * (p.x.abs() + p.y.abs());
        let (k0, k1) = (first / BLOCK, (last - 1) / BLOCK + 1);
        let run = |k: usize| (k * BLOCK).max(first)..((k + 1) * BLOCK).min(last);
        let below = |k: usize| self.blocks[k].below(p, p_slack);
        let far = |k: usize, best: &Best| below(k) > best.proj.distance * (1.0 + SLACK);
        let start = (k0 + 1..k1).fold(k0, |m, k| if below(k) < below(m) { k } else { m });
        let mut here = none;
        self.scan(p, run(start), &mut here);
        // The runs before `start`, in order; any tie with `here` goes to them (lower indices).
        let mut before = none;
        for k in k0..start {
            if !far(k, &here) {
                self.scan(p, run(k), &mut before);
            }
        }
        let mut best = if before.proj.distance <= here.proj.distance { before } else { here };
        for k in start + 1..k1 {
            if !far(k, &best) {
                self.scan(p, run(k), &mut best);
            }
        }
        best.proj
    }

    /// Scans `segments` in order for one closer to `p` than `best` (strictly: the first of equals
    /// stays).
    #[inline]
    fn scan(&self, p: Vec2, segments: std::ops::Range<usize>, best: &mut Best) {
        let points = &self.points[segments.start..=segments.end];
        let cum = &self.cum[segments.start..=segments.end];
        for (j, (w, c)) in points.windows(2).zip(cum.windows(2)).enumerate() {
            let (a, b) = (w[0], w[1]);
            let ab = b - a;
            let len2 = ab.length_squared();
            let t = ((p - a).dot(ab) / len2).clamp(0.0, 1.0);
            let q = a + ab * t;
            let d2 = (q - p).length_squared();
            // sqrt is monotone: a segment no nearer in d² cannot be strictly nearer.
            if d2 < best.d2 {
                let dist = d2.sqrt();
                if dist < best.proj.distance {
                    let lateral = cross(ab, p - a) / len2.sqrt();
                    best.proj = Projection { s: c[0] + t * (c[1] - c[0]), lateral, distance: dist, segment: segments.start + j };
                    best.d2 = d2;
                }
            }
        }
    }

    /// Points resampled every `spacing` metres from the start, the end always included.
    #[must_use]
    pub fn resample(&self, spacing: f32) -> Vec<Vec2> {
        let len = self.length();
        let n = (len / spacing).ceil().max(1.0) as usize;
        let mut out: Vec<Vec2> = (0..n).map(|i| self.point_at(i as f32 * spacing)).collect();
        out.push(self.end());
        out
    }
}

/// A projection found so far and its squared distance.
#[derive(Debug, Clone, Copy)]
struct Best {
    proj: Projection,
    d2: f32,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn l_shape() -> Polyline {
        Polyline::new([Vec2::new(0.0, 0.0), Vec2::new(10.0, 0.0), Vec2::new(10.0, 10.0)]).unwrap()
    }

    #[test]
    fn length_and_point_at() {
        let pl = l_shape();
        assert_eq!(pl.length(), 20.0);
        assert_eq!(pl.point_at(5.0), Vec2::new(5.0, 0.0));
        assert_eq!(pl.point_at(15.0), Vec2::new(10.0, 5.0));
        assert_eq!(pl.point_at(99.0), Vec2::new(10.0, 10.0));
        assert_eq!(pl.point_at(-1.0), Vec2::new(0.0, 0.0));
    }

    #[test]
    fn projection_reports_side_and_distance() {
        let pl = l_shape();
        let left = pl.project(Vec2::new(4.0, 2.0));
        assert_eq!((left.s, left.lateral, left.distance), (4.0, 2.0, 2.0));
        let right = pl.project(Vec2::new(4.0, -3.0));
        assert_eq!(right.lateral, -3.0);
        let up = pl.project(Vec2::new(12.0, 6.0));
        assert_eq!((up.s, up.lateral), (16.0, -2.0));
    }

    #[test]
    fn hinted_pose_matches_unhinted_point() {
        let pl = l_shape();
        let mut hint = 0;
        for k in 0..=40 {
            let s = k as f32 * 0.5;
            let (p, _, seg) = pl.pose_at_hinted(s, hint);
            hint = seg;
            assert_eq!(p, pl.point_at(s), "s = {s}");
        }
    }

    /// The scan of every segment that `project_range` must match bit for bit.
    fn scan_all(pl: &Polyline, p: Vec2, first: usize, last: usize) -> Projection {
        let (pts, cum) = (pl.points(), &pl.cum);
        let last = last.min(pts.len() - 1);
        let first = first.min(last.saturating_sub(1));
        let mut best = Projection { s: 0.0, lateral: 0.0, distance: f32::INFINITY, segment: first };
        for i in first..last {
            let (a, b) = (pts[i], pts[i + 1]);
            let ab = b - a;
            let len2 = ab.length_squared();
            let t = ((p - a).dot(ab) / len2).clamp(0.0, 1.0);
            let dist = (a + ab * t).distance(p);
            if dist < best.distance {
                let lateral = cross(ab, p - a) / len2.sqrt();
                best = Projection { s: cum[i] + t * (cum[i + 1] - cum[i]), lateral, distance: dist, segment: i };
            }
        }
        best
    }

    #[test]
    fn skipping_runs_changes_no_projection() {
        // A winding line far from the origin, with a stretch that doubles back over itself (ties)
        // and points spaced as lanes' are; queries near it, on it and far away, over windows
        // cutting runs anywhere.
        let mut pts: Vec<Vec2> = (0..300).map(|i| Vec2::new(1500.0 + i as f32 * 0.9, -800.0 + 30.0 * (i as f32 * 0.05).sin())).collect();
        pts.extend((0..40).map(|i| Vec2::new(1500.0 + 299.0 * 0.9 - i as f32, -800.0 + 30.0 * (299.0f32 * 0.05).sin())));
        let pl = Polyline::new(pts).unwrap();
        let n = pl.points().len() - 1;
        let mut seed = 12345u32;
        let mut rand = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        for _ in 0..4000 {
            let v = pl.points()[(rand() * n as f32) as usize];
            let p = v + Vec2::new(rand() - 0.5, rand() - 0.5) * [0.0, 2.0, 40.0, 600.0][(rand() * 4.0) as usize];
            let first = (rand() * n as f32) as usize;
            let last = first + (rand() * 120.0) as usize;
            let (got, want) = (pl.project_range(p, first, last), scan_all(&pl, p, first, last));
            assert_eq!(
                (got.s.to_bits(), got.lateral.to_bits(), got.distance.to_bits(), got.segment),
                (want.s.to_bits(), want.lateral.to_bits(), want.distance.to_bits(), want.segment),
                "{p:?} over {first}..{last}"
            );
        }
        let p = Vec2::new(1700.0, -780.0);
        assert_eq!(pl.project(p), scan_all(&pl, p, 0, n));
    }

    #[test]
    fn degenerate_polylines_are_refused() {
        assert!(Polyline::new([Vec2::ZERO, Vec2::ZERO]).is_none());
        assert!(Polyline::new([Vec2::ZERO]).is_none());
    }

    #[test]
    fn resample_includes_end() {
        let pts = l_shape().resample(8.0);
        assert_eq!(pts.len(), 4);
        assert_eq!(*pts.last().unwrap(), Vec2::new(10.0, 10.0));
    }
}
