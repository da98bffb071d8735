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
    #[cfg(target_arch = "x86_64")]
    if wide() {
        // SAFETY: the CPU has AVX-512F and BW (`wide`).
        #[allow(unsafe_code)]
        unsafe {
            convert_avx512(src, dst);
        }
        return;
    }
    convert_plain(src, dst);
}

/// `out[2j] = bf16(even[j])`, `out[2j + 1] = bf16(odd[j])`: two rows of a matrix as one pair row
/// of `bf16_layout::PackedB`.
///
/// # Panics
/// If `even` and `odd` differ in length or `out` is not twice as long.
pub fn convert_pairs(even: &[f32], odd: &[f32], out: &mut [u16]) {
    assert!(
        even.len() == odd.len() && out.len() == 2 * even.len(),
        "bf16::convert_pairs: {} + {} values into {}",
        even.len(),
        odd.len(),
        out.len()
    );
    #[cfg(target_arch = "x86_64")]
    if wide() {
        // SAFETY: the CPU has AVX-512F and BW (`wide`).
        #[allow(unsafe_code)]
        unsafe {
            convert_pairs_avx512(even, odd, out);
        }
        return;
    }
    convert_pairs_plain(even, odd, out);
}

/// Whether the bulk conversions run on 512-bit registers. The crate is built for baseline
/// x86-64, where these loops vectorise to 128 bits only; the same loops compiled for AVX-512
/// give the same bits (integer arithmetic) four times as wide.
#[cfg(target_arch = "x86_64")]
fn wide() -> bool {
    std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("avx512bw")
}

fn convert_plain(src: &[f32], dst: &mut [u16]) {
    for (d, &x) in dst.iter_mut().zip(src) {
        *d = from_f32_finite(x);
    }
}

fn convert_pairs_plain(even: &[f32], odd: &[f32], out: &mut [u16]) {
    for ((o, &e), &d) in out.chunks_exact_mut(2).zip(even).zip(odd) {
        o[0] = from_f32_finite(e);
        o[1] = from_f32_finite(d);
    }
}

/// [`convert_plain`] compiled for AVX-512.
///
/// # Safety
/// The CPU has AVX-512F and AVX-512BW.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw")]
#[allow(unsafe_code)]
unsafe fn convert_avx512(src: &[f32], dst: &mut [u16]) {
    convert_plain(src, dst);
}

/// [`convert_pairs_plain`] compiled for AVX-512.
///
/// # Safety
/// The CPU has AVX-512F and AVX-512BW.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw")]
#[allow(unsafe_code)]
unsafe fn convert_pairs_avx512(even: &[f32], odd: &[f32], out: &mut [u16]) {
    convert_pairs_plain(even, odd, out);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The wide and the plain loops give the same bits, on every value class and length.
    #[test]
    fn bulk_conversions_agree_with_one_value_at_a_time() {
        let mut values: Vec<f32> = (0..1037).map(|i| ((i as f32) * 0.377).sin() * 3e4).collect();
        values.extend([0.0, -0.0, f32::MIN_POSITIVE, 1e-40, -1e-40, f32::MAX, f32::INFINITY, f32::NEG_INFINITY, 1.0 + 1.0 / 256.0]);
        for len in [0, 1, 15, 16, 17, 63, values.len()] {
            let src = &values[..len];
            let mut out = vec![0; len];
            convert(src, &mut out);
            assert!(out.iter().zip(src).all(|(&b, &x)| b == from_f32_finite(x)), "convert, {len} values");
            let half = len / 2;
            let mut pairs = vec![0; 2 * half];
            convert_pairs(&src[..half], &src[half..2 * half], &mut pairs);
            for j in 0..half {
                assert_eq!(
                    [pairs[2 * j], pairs[2 * j + 1]],
                    [from_f32_finite(src[j]), from_f32_finite(src[half + j])],
                    "pair {j} of {half}"
                );
            }
        }
    }

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
