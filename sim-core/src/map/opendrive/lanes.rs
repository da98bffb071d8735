//! A lane section sampled across: stations along the reference line (denser in tight curves, at
//! every geometry boundary) and, at each, every lane's inner and outer border as a lateral offset
//! `t` (positive to the left), from the lane offset and the lanes' cubic widths.

use super::geometry::{Geometry, Pose, cubic_at, reference_pose};
use super::parse::{Road, Section};
use crate::math::Vec2;

/// Stations are at most this far apart, metres.
const MAX_STEP: f64 = 1.0;
/// ... and at most this much heading change apart in curves, radians.
const MAX_TURN: f64 = 0.06;
/// ... but never closer than this, metres.
const MIN_STEP: f64 = 0.1;

/// One lane across a sampled section.
#[derive(Debug, Clone)]
pub struct SampledLane {
    /// Lateral offset of the border nearer the reference line, per station.
    pub inner: Vec<f64>,
    /// Lateral offset of the border farther from it, per station.
    pub outer: Vec<f64>,
}

impl SampledLane {
    /// Lateral offset of the lane's centre at station `i`.
    #[must_use]
    pub fn centre(&self, i: usize) -> f64 {
        0.5 * (self.inner[i] + self.outer[i])
    }

    /// Width at station `i`.
    #[must_use]
    pub fn width(&self, i: usize) -> f64 {
        (self.outer[i] - self.inner[i]).abs()
    }
}

/// A lane section sampled along and across.
#[derive(Debug, Clone)]
pub struct SampledSection {
    pub stations: Vec<f64>,
    pub poses: Vec<Pose>,
    /// The lane offset (the centre lane's position) per station.
    pub offset: Vec<f64>,
    /// In the section's lane order (left lanes by id, then right lanes by |id|).
    pub lanes: Vec<SampledLane>,
    /// Stations where a width polynomial went negative (clamped to 0).
    pub negative_widths: usize,
}

impl SampledSection {
    /// The map point at station `i`, `t` metres to the left of the reference line.
    #[must_use]
    pub fn point(&self, i: usize, t: f64) -> Vec2 {
        let p = self.poses[i];
        Vec2::new((p.x - libm::sin(p.hdg) * t) as f32, (p.y + libm::cos(p.hdg) * t) as f32)
    }
}

/// Where section `k` of `road` ends along the road.
#[must_use]
pub fn section_end(road: &Road, k: usize) -> f64 {
    road.sections.get(k + 1).map_or(road.length, |s| s.s).min(road.length)
}

/// The stations of `[s0, s1]`: every geometry boundary inside, and steps no longer than
/// `MAX_STEP` nor turning more than `MAX_TURN`.
fn stations(pieces: &[Geometry], s0: f64, s1: f64) -> Vec<f64> {
    let mut out = vec![s0];
    let mut s = s0;
    while s < s1 - 1e-9 {
        let i = pieces.partition_point(|g| g.s <= s).saturating_sub(1);
        let piece_end = pieces.get(i + 1).map_or(s1, |g| g.s).min(s1);
        let k = pieces[i].max_curvature();
        let step = if k > 0.0 { (MAX_TURN / k).clamp(MIN_STEP, MAX_STEP) } else { MAX_STEP };
        let end = if piece_end > s + 1e-9 { piece_end } else { s1 };
        let n = ((end - s) / step).ceil().max(1.0) as usize;
        for j in 1..=n {
            out.push(s + (end - s) * j as f64 / n as f64);
        }
        s = end;
    }
    out
}

/// Samples section `k` of `road`.
#[must_use]
pub fn sample(road: &Road, k: usize) -> SampledSection {
    let section: &Section = &road.sections[k];
    let (s0, s1) = (section.s.min(road.length), section_end(road, k));
    let stations = stations(&road.geometry, s0, s1.max(s0));
    let poses: Vec<Pose> = stations.iter().map(|&s| reference_pose(&road.geometry, s)).collect();
    let offset: Vec<f64> = stations.iter().map(|&s| cubic_at(&road.lane_offset, s)).collect();
    let mut negative_widths = 0;
    let mut lanes: Vec<SampledLane> = section.lanes.iter().map(|_| SampledLane { inner: offset.clone(), outer: offset.clone() }).collect();
    // Left lanes come first, by increasing id; right lanes after, by increasing |id|: each lane's
    // inner border is the previous lane's outer border on its side.
    for side_left in [true, false] {
        let mut border = offset.clone();
        for (lane, sampled) in section.lanes.iter().zip(lanes.iter_mut()) {
            if (lane.id > 0) != side_left {
                continue;
            }
            let sign = if side_left { 1.0 } else { -1.0 };
            sampled.inner.clone_from(&border);
            for (i, &s) in stations.iter().enumerate() {
                let mut w = cubic_at(&lane.widths, s - section.s);
                if w < 0.0 {
                    negative_widths += 1;
                    w = 0.0;
                }
                border[i] += sign * w;
            }
            sampled.outer.clone_from(&border);
        }
    }
    SampledSection { stations, poses, offset, lanes, negative_widths }
}
