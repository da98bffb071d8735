//! The one vector type of the simulator and deterministic scalar functions.
//!
//! `Vec2` is parry2d's (glam, f32): geometry and collision share it with no conversions. Trigonometry
//! goes through `libm` (pure Rust) rather than the platform's C library so that trajectories are
//! bit-identical on every machine.

pub use parry2d::math::Vec2;

/// Sine, bit-identical on every platform.
#[inline]
pub fn sin(x: f32) -> f32 {
    libm::sinf(x)
}

/// Cosine, bit-identical on every platform.
#[inline]
pub fn cos(x: f32) -> f32 {
    libm::cosf(x)
}

/// `atan2(y, x)`, bit-identical on every platform.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    libm::atan2f(y, x)
}

/// Tangent, bit-identical on every platform.
#[inline]
pub fn tan(x: f32) -> f32 {
    libm::tanf(x)
}

/// Arc tangent, bit-identical on every platform.
#[inline]
pub fn atan(x: f32) -> f32 {
    libm::atanf(x)
}

/// Unit vector pointing along `heading` (radians, counter-clockwise from +x).
#[inline]
pub fn dir(heading: f32) -> Vec2 {
    Vec2::new(cos(heading), sin(heading))
}

/// The vector rotated by +90° (to the left of `v`).
#[inline]
pub fn left_normal(v: Vec2) -> Vec2 {
    Vec2::new(-v.y, v.x)
}

/// Heading of a direction vector, radians in (-π, π].
#[inline]
pub fn heading_of(v: Vec2) -> f32 {
    atan2(v.y, v.x)
}

/// An angle wrapped into (-π, π].
#[inline]
pub fn wrap_angle(a: f32) -> f32 {
    use std::f32::consts::{PI, TAU};
    let mut a = a % TAU;
    if a > PI {
        a -= TAU;
    } else if a <= -PI {
        a += TAU;
    }
    a
}

/// 2-D cross product (z of the 3-D cross product).
#[inline]
pub fn cross(a: Vec2, b: Vec2) -> f32 {
    a.x * b.y - a.y * b.x
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    #[test]
    fn wrap_angle_stays_in_range() {
        for k in -20..20 {
            let a = wrap_angle(k as f32 * 0.7);
            assert!(a > -PI - 1e-6 && a <= PI + 1e-6, "{a}");
        }
        assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-5);
    }

    #[test]
    fn left_normal_is_counter_clockwise() {
        assert_eq!(left_normal(Vec2::new(1.0, 0.0)), Vec2::new(0.0, 1.0));
    }
}
