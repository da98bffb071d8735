//! OpenDRIVE's plan-view geometry, evaluated in f64: the reference line's pieces (`line`, `arc`,
//! `spiral`, `poly3`, `paramPoly3`) and the cubic records of lane offsets and lane widths.
//!
//! Trigonometry goes through `libm` (as `crate::math` does) so that a map is the same on every
//! machine, bit for bit.

/// Gauss–Legendre nodes and weights on [-1, 1], five points (exact for polynomials of degree 9).
const GAUSS5: [(f64, f64); 5] = [
    (0.0, 0.568_888_888_888_888_9),
    (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
    (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
    (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
    (0.906_179_845_938_664, 0.236_926_885_056_189_1),
];
/// A spiral is integrated over sub-intervals at most this long, metres, ...
const SPIRAL_STEP: f64 = 0.5;
/// ... over which its heading turns at most this much, radians (5-point Gauss–Legendre is then
/// within 1e-10 m per sub-interval).
const SPIRAL_TURN: f64 = 0.2;

/// A position and heading in the map's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub x: f64,
    pub y: f64,
    /// Radians, counter-clockwise from +x.
    pub hdg: f64,
}

/// The shape of one `<geometry>` record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    Line,
    /// Constant curvature, 1/m (positive turns left).
    Arc {
        curvature: f64,
    },
    /// A clothoid: curvature linear in s from `start` to `end`.
    Spiral {
        start: f64,
        end: f64,
    },
    /// `v = a + b u + c u² + d u³` in the local frame; u is taken as the distance along the piece
    /// (OpenDRIVE's deprecated form, approximated as its author almost always meant it).
    Poly3 {
        a: f64,
        b: f64,
        c: f64,
        d: f64,
    },
    /// `u(p)`, `v(p)` cubics; p runs over `[0, length]` (`pRange="arcLength"`) or `[0, 1]`
    /// (`pRange="normalized"`).
    ParamPoly3 {
        u: [f64; 4],
        v: [f64; 4],
        normalized: bool,
    },
}

/// One `<geometry>` record of a road's `planView`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geometry {
    /// Where the piece starts along the road, metres.
    pub s: f64,
    pub start: Pose,
    pub length: f64,
    pub shape: Shape,
}

fn poly(c: &[f64; 4], p: f64) -> f64 {
    c[0] + p * (c[1] + p * (c[2] + p * c[3]))
}

fn poly_slope(c: &[f64; 4], p: f64) -> f64 {
    c[1] + p * (2.0 * c[2] + p * 3.0 * c[3])
}

/// A clothoid's local position and heading change after `ds` metres, starting at the origin
/// heading +x with curvature `k0` and curvature rate `rate` (1/m²): the integrals of
/// `cos θ`, `sin θ` with `θ(s) = k0 s + rate s² / 2`, by Gauss–Legendre quadrature.
#[must_use]
pub fn spiral_local(k0: f64, rate: f64, ds: f64) -> (f64, f64, f64) {
    let theta = |s: f64| k0 * s + 0.5 * rate * s * s;
    let k_max = k0.abs().max((k0 + rate * ds).abs());
    let step = if k_max > 0.0 { SPIRAL_STEP.min(SPIRAL_TURN / k_max) } else { SPIRAL_STEP };
    let n = (ds / step).ceil().clamp(1.0, 1.0e7) as usize;
    let h = ds / n as f64;
    let (mut x, mut y) = (0.0, 0.0);
    for i in 0..n {
        let mid = (i as f64 + 0.5) * h;
        for (node, w) in GAUSS5 {
            let t = theta(mid + 0.5 * h * node);
            x += 0.5 * h * w * libm::cos(t);
            y += 0.5 * h * w * libm::sin(t);
        }
    }
    (x, y, theta(ds))
}

impl Geometry {
    /// The pose `ds` metres into the piece (clamped to the piece).
    #[must_use]
    pub fn pose_at(&self, ds: f64) -> Pose {
        let ds = ds.clamp(0.0, self.length);
        let Pose { x, y, hdg } = self.start;
        let (local_x, local_y, dh) = match self.shape {
            Shape::Line => (ds, 0.0, 0.0),
            Shape::Arc { curvature: k } if k.abs() < 1e-12 => (ds, 0.0, 0.0),
            Shape::Arc { curvature: k } => (libm::sin(k * ds) / k, (1.0 - libm::cos(k * ds)) / k, k * ds),
            Shape::Spiral { start, end } => spiral_local(start, (end - start) / self.length, ds),
            Shape::Poly3 { a, b, c, d } => {
                let c4 = [a, b, c, d];
                (ds, poly(&c4, ds), libm::atan(poly_slope(&c4, ds)))
            }
            Shape::ParamPoly3 { u, v, normalized } => {
                let p = if normalized { ds / self.length } else { ds };
                (poly(&u, p), poly(&v, p), libm::atan2(poly_slope(&v, p), poly_slope(&u, p)))
            }
        };
        let (sin, cos) = (libm::sin(hdg), libm::cos(hdg));
        Pose { x: x + cos * local_x - sin * local_y, y: y + sin * local_x + cos * local_y, hdg: hdg + dh }
    }

    /// The largest absolute curvature the piece reaches (an estimate for polynomials), 1/m:
    /// sampling density follows it.
    #[must_use]
    pub fn max_curvature(&self) -> f64 {
        match self.shape {
            Shape::Line => 0.0,
            Shape::Arc { curvature } => curvature.abs(),
            Shape::Spiral { start, end } => start.abs().max(end.abs()),
            Shape::Poly3 { .. } | Shape::ParamPoly3 { .. } => {
                let n = 16;
                let mut k_max: f64 = 0.0;
                let step = self.length / n as f64;
                for i in 0..n {
                    let (a, b) = (self.pose_at(i as f64 * step), self.pose_at((i + 1) as f64 * step));
                    if step > 0.0 {
                        k_max = k_max.max(wrap(b.hdg - a.hdg).abs() / step);
                    }
                }
                k_max
            }
        }
    }
}

/// An angle wrapped to [-π, π).
#[must_use]
pub fn wrap(a: f64) -> f64 {
    let two_pi = 2.0 * std::f64::consts::PI;
    a - two_pi * libm::floor((a + std::f64::consts::PI) / two_pi)
}

/// The reference line's pose at `s`: the last piece starting at or before `s`.
#[must_use]
pub fn reference_pose(pieces: &[Geometry], s: f64) -> Pose {
    let i = pieces.partition_point(|g| g.s <= s).saturating_sub(1);
    let g = &pieces[i];
    g.pose_at(s - g.s)
}

/// One cubic record (`laneOffset`, lane `width`): `a + b ds + c ds² + d ds³` from `s` on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cubic {
    pub s: f64,
    pub coefficients: [f64; 4],
}

/// The value at `s` of a list of cubic records sorted by `s` (the last record starting at or
/// before `s`; the first one before it starts; 0 for an empty list).
#[must_use]
pub fn cubic_at(records: &[Cubic], s: f64) -> f64 {
    if records.is_empty() {
        return 0.0;
    }
    let i = records.partition_point(|r| r.s <= s).saturating_sub(1);
    let r = &records[i];
    poly(&r.coefficients, (s - r.s).max(0.0))
}
