//! Polylines parametrised by arc length: lanes, connectors and routes are all made of these.

use crate::math::{Vec2, cross, heading_of};

/// A sequence of points with cumulative arc length. Always has at least two points and positive
/// length (constructors enforce it).
#[derive(Debug, Clone)]
pub struct Polyline {
    points: Vec<Vec2>,
    /// `cum[i]` = arc length from `points[0]` to `points[i]`.
    cum: Vec<f32>,
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
        Some(Self { points: pts, cum })
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
        let h = heading_of(self.points[seg + 1] - self.points[seg]);
        (p, h, seg)
    }

    /// The closest point to `p` over the whole polyline.
    #[must_use]
    pub fn project(&self, p: Vec2) -> Projection {
        self.project_range(p, 0, self.points.len() - 1)
    }

    /// The closest point to `p` among segments `first..last` (clamped to the polyline).
    #[must_use]
    pub fn project_range(&self, p: Vec2, first: usize, last: usize) -> Projection {
        let last = last.min(self.points.len() - 1);
        let first = first.min(last.saturating_sub(1));
        let mut best = Projection { s: 0.0, lateral: 0.0, distance: f32::INFINITY, segment: first };
        for i in first..last {
            let (a, b) = (self.points[i], self.points[i + 1]);
            let ab = b - a;
            let len2 = ab.length_squared();
            let t = ((p - a).dot(ab) / len2).clamp(0.0, 1.0);
            let q = a + ab * t;
            let dist = q.distance(p);
            if dist < best.distance {
                let lateral = cross(ab, p - a) / len2.sqrt();
                best = Projection { s: self.cum[i] + t * (self.cum[i + 1] - self.cum[i]), lateral, distance: dist, segment: i };
            }
        }
        best
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
