//! bfloat16 values as `u16` bit patterns (the top half of an f32): rounding to nearest even, and
//! the bulk conversions the bf16 path does while it reads data it already reads.

/// `x` rounded to the nearest bf16 (ties to even); NaN stays a (quiet) NaN.
#[must_use]
#[inline]
pub fn from_f32(x: f32) -> u16 {
    let bits = x.to_bits();
    if x.is_nan() {
        return ((bits >> 16) as u16) | 0x0040;
    }
    let round = 0x7FFF + ((bits >> 16) & 1);
    (bits.wrapping_add(round) >> 16) as u16
}

/// The f32 a bf16 stands for (exact).
#[must_use]
#[inline]
pub fn to_f32(b: u16) -> f32 {
    f32::from_bits(u32::from(b) << 16)
}

/// [`from_f32`] for every value but NaN, branch-free, so that loops of it vectorise: a NaN's
/// rounding may carry into the exponent, which keeps it a NaN or makes it infinite; the network
/// never holds NaNs (gradients are checked).
#[must_use]
#[inline]
pub fn from_f32_finite(x: f32) -> u16 {
    let bits = x.to_bits();
    (bits.wrapping_add(0x7FFF + ((bits >> 16) & 1)) >> 16) as u16
}

/// `dst[i] = bf16(src[i])` ([`from_f32_finite`]).
///
/// # Panics
/// If the lengths differ.
pub fn convert(src: &[f32], dst: &mut [u16]) {
    assert_eq!(src.len(), dst.len(), "bf16::convert: {} values into {}", src.len(), dst.len());
    for (d, &x) in dst.iter_mut().zip(src) {
        *d = from_f32_finite(x);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounds_to_nearest_even() {
        // 1 + 2^-8 is halfway between bf16 1.0 and 1 + 2^-7: ties to even (1.0).
        assert_eq!(from_f32(1.0 + 1.0 / 256.0), 0x3F80);
        // Just above the halfway point rounds up.
        assert_eq!(from_f32(1.0 + 1.0 / 256.0 + 1.0 / 65536.0), 0x3F81);
        // 1 + 3·2^-8 is halfway between 1 + 2^-7 (odd) and 1 + 2^-6: ties to even (up).
        assert_eq!(from_f32(1.0 + 3.0 / 256.0), 0x3F82);
        assert_eq!(to_f32(from_f32(-2.5)), -2.5);
        assert!(to_f32(from_f32(f32::NAN)).is_nan());
        assert_eq!(to_f32(from_f32(f32::INFINITY)), f32::INFINITY);
        let values: Vec<f32> = (0..1000).map(|i| ((i as f32) * 0.731).sin() * 1e3).collect();
        let mut out = vec![0; values.len()];
        convert(&values, &mut out);
        for (&x, &b) in values.iter().zip(&out) {
            assert_eq!(b, from_f32(x));
            assert!((to_f32(b) - x).abs() <= x.abs() / 256.0, "{x} -> {}", to_f32(b));
        }
    }
}
