//! The 3×3 convolution of `conv` on a bf16 kernel (`bf16_matmul`), for layers whose K = 3·C is a
//! whole number of tile steps (C a multiple of 32: the paper's second and third layers):
//! the same GEMMs over the same padded layouts, with the image read in place as bf16 (one
//! segment per kernel row) and f32 accumulation.
//!
//! The kernel gradient reduces over output rows, so it reads the padded input transposed
//! ([`transpose_padded`]: channel-major planes) and the output gradient in pairs of rows
//! ([`PackedB`]); the input gradient is the forward convolution of the bf16 output gradient
//! with the flipped kernel, as in `conv`.

use super::aligned::Aligned;
use super::bf16_matmul::{self, AView, K_STEP, PackedB};
use super::conv::{self, ConvGeom};
use super::gemm::View;

/// What one convolution multiplies: an f32 padded image and k-major kernel (`conv`), or the same
/// image in bf16 and the kernel packed for the tiles.
#[derive(Debug, Clone, Copy)]
pub enum Operands<'a> {
    F32 { input: &'a [f32], kernel: &'a [f32] },
    Bf16 { input: &'a [u16], kernel: &'a PackedB },
}

impl Operands<'_> {
    /// Output rows `first..first + out.len() / cout` of the convolution (`conv::forward_rows`).
    pub fn forward_rows(&self, g: &ConvGeom, first: usize, out: &mut [f32], patches: &mut [f32]) {
        match *self {
            Self::F32 { input, kernel } => conv::forward_rows(input, kernel, g, first, out, patches, 1),
            Self::Bf16 { input, kernel } => forward_rows(input, kernel, g, first, out),
        }
    }
}

/// Whether a layer of this geometry runs on the bf16 kernel.
#[must_use]
pub fn fits(g: &ConvGeom) -> bool {
    !g.gathers() && (3 * g.cin).is_multiple_of(K_STEP)
}

/// Output rows `first..first + out.len() / cout` of one bf16 padded image convolved with `kernel`
/// (the k-major kernel packed, `9·cin × cout`), bias excluded.
///
/// # Panics
/// If the layer does not [`fits`] or the slices do not match the geometry.
pub fn forward_rows(input: &[u16], kernel: &PackedB, g: &ConvGeom, first: usize, out: &mut [f32]) {
    assert!(fits(g), "conv_bf16: a layer of {} input channels", g.cin);
    let n = out.len() / g.cout;
    let av = AView { offset: first * g.cin, rows: n, row_stride: g.cin, segments: 3, seg_len: 3 * g.cin, seg_stride: g.pw() * g.cin };
    bf16_matmul::matmul(out, View::rows(0, n, g.cout, g.cout), false, input, av, kernel);
}

/// Values of one channel's plane in [`transpose_padded`]'s layout: the padded image's pixels and
/// a tail of zeros for the kernel gradient's last tile step to read, rounded up to whole tile
/// rows so that every plane starts a cache line (`aligned`), as the first does.
#[must_use]
pub fn plane(g: &ConvGeom) -> usize {
    ((g.h + 2) * g.pw() + K_STEP).next_multiple_of(K_STEP)
}

/// The padded image `input` (bf16, pixel-major: the forward pass's copy) as channel planes of
/// [`plane`] values. A transpose of 16-bit values only: the forward pass already rounded them,
/// so this pass does no arithmetic (converting from f32 again here was a visible share of a bf16
/// update: experiments/performance/CHANGELOG.md).
pub fn transpose_padded(input: &[u16], g: &ConvGeom, out: &mut Aligned<u16>) {
    // Blocks of pixels whose channels fit in L1, so that each plane is written a run at a time.
    const PIXELS: usize = 16;
    let (c, p) = (g.cin, plane(g));
    let pixels = g.padded_in() / c;
    if out.len() == c * p {
        // Only the pixels are written below: zero the tails, not the whole buffer again.
        for tail in out.chunks_exact_mut(p) {
            tail[pixels..].fill(0);
        }
    } else {
        out.clear();
        out.resize(c * p, 0);
    }
    assert!(c.is_multiple_of(4), "transpose_padded: {c} channels");
    for (block, values) in input[..g.padded_in()].chunks(PIXELS * c).enumerate() {
        let n = values.len() / c;
        let first = block * PIXELS;
        for (group, planes) in out.chunks_exact_mut(4 * p).enumerate() {
            let ch = 4 * group;
            let (p0, rest) = planes.split_at_mut(p);
            let (p1, rest) = rest.split_at_mut(p);
            let (p2, p3) = rest.split_at_mut(p);
            // 4 pixels × 4 channels at a time, as four 64-bit words transposed in registers:
            // a quarter of the loads and stores of one value at a time.
            let whole = n - n % 4;
            for px in (0..whole).step_by(4) {
                let rows = [0, 1, 2, 3].map(|i| load4(&values[(px + i) * c + ch..]));
                let cols = transpose4(rows);
                for (plane, col) in [&mut *p0, &mut *p1, &mut *p2, &mut *p3].into_iter().zip(cols) {
                    store4(&mut plane[first + px..], col);
                }
            }
            for px in whole..n {
                for (i, plane) in [&mut *p0, &mut *p1, &mut *p2, &mut *p3].into_iter().enumerate() {
                    plane[first + px] = values[px * c + ch + i];
                }
            }
        }
    }
}

/// Four consecutive 16-bit values as one word, the first in the low bits.
#[inline]
fn load4(s: &[u16]) -> u64 {
    let v: [u16; 4] = s[..4].try_into().expect("four values");
    v.iter().rev().fold(0, |w, &x| (w << 16) | u64::from(x))
}

/// The word's four 16-bit values, low bits first, into `d[..4]`.
#[inline]
fn store4(d: &mut [u16], w: u64) {
    d[..4].copy_from_slice(&[0, 16, 32, 48].map(|shift| (w >> shift) as u16));
}

/// The 4 × 4 matrix of 16-bit values whose rows are `rows` (column j in bits 16j..16j + 16),
/// transposed: two rounds of swapping blocks, 16-bit then 32-bit.
#[inline]
fn transpose4(rows: [u64; 4]) -> [u64; 4] {
    const EVEN16: u64 = 0x0000_FFFF_0000_FFFF;
    const LOW32: u64 = 0x0000_0000_FFFF_FFFF;
    let [r0, r1, r2, r3] = rows;
    // t0 = (r0c0, r1c0, r0c2, r1c2), t1 = (r0c1, r1c1, r0c3, r1c3), and t2, t3 of rows 2 and 3.
    let t0 = (r0 & EVEN16) | ((r1 & EVEN16) << 16);
    let t1 = ((r0 >> 16) & EVEN16) | (r1 & !EVEN16);
    let t2 = (r2 & EVEN16) | ((r3 & EVEN16) << 16);
    let t3 = ((r2 >> 16) & EVEN16) | (r3 & !EVEN16);
    [(t0 & LOW32) | (t2 << 32), (t1 & LOW32) | (t3 << 32), (t0 >> 32) | (t2 & !LOW32), (t1 >> 32) | (t3 & !LOW32)]
}

/// The padded output gradient (f32, `padded_out` values) as the right matrix of the kernel
/// gradient: output row q's gradient (padded row q + pw + 1) in pairs of rows.
pub fn pack_output_grad(grad_padded: &[f32], g: &ConvGeom, out: &mut PackedB) {
    out.pack(grad_padded, View::rows((g.pw() + 1) * g.cout, g.rows(), g.cout, g.cout));
}

/// Adds one image's k-major kernel gradient to `dk` (`9·cin × cout`), from its transposed input
/// ([`transpose_padded`]) and packed output gradient ([`pack_output_grad`]).
///
/// # Panics
/// If the slices do not match the geometry.
pub fn kernel_grad(input_t: &[u16], grad: &PackedB, g: &ConvGeom, dk: &mut [f32]) {
    let (c, pw, p) = (g.cin, g.pw(), plane(g));
    let (k_pad, _) = grad.dims();
    for ky in 0..3 {
        for kx in 0..3 {
            let k = ky * 3 + kx;
            // Row c of this kernel tap: channel c's plane from pixel q + ky·pw + kx, q over the
            // output rows (the padded tail of the gradient is zero).
            let av = AView::rows(ky * pw + kx, c, k_pad, p);
            bf16_matmul::matmul(dk, View::rows(k * c * g.cout, c, g.cout, g.cout), true, input_t, av, grad);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::bf16;
    use super::super::bf16_matmul::tests::bf16_or_skip;
    use super::*;

    fn values(n: usize, seed: f32) -> Vec<f32> {
        (0..n).map(|i| ((i as f32 + seed) * 0.618).sin()).collect()
    }

    fn rounded(v: &[f32]) -> Vec<f32> {
        v.iter().map(|&x| bf16::to_f32(bf16::from_f32(x))).collect()
    }

    /// A padded image with zero borders (as the network keeps them).
    fn padded(g: &ConvGeom, c: usize, seed: f32) -> Vec<f32> {
        let mut img = vec![0f32; (g.h + 2) * g.pw() * c];
        let v = values(img.len(), seed);
        for y in 0..g.h {
            for x in 0..g.w {
                let p = ((y + 1) * g.pw() + x + 1) * c;
                img[p..p + c].copy_from_slice(&v[p..p + c]);
            }
        }
        img
    }

    /// The bf16 convolution and its gradients against `conv`'s f32 ones on bf16-rounded inputs:
    /// equal up to f32 accumulation error.
    #[test]
    fn four_by_four_transposes_in_words() {
        let m: Vec<u16> = (0..16).map(|i| 100 + i).collect();
        let rows = [0, 1, 2, 3].map(|r| load4(&m[4 * r..]));
        let mut t = [0u16; 16];
        for (j, col) in transpose4(rows).into_iter().enumerate() {
            store4(&mut t[4 * j..], col);
        }
        for i in 0..4 {
            for j in 0..4 {
                assert_eq!(t[4 * j + i], m[4 * i + j], "({i}, {j})");
            }
        }
    }

    #[test]
    fn forward_and_gradients_match_the_f32_convolution_of_rounded_inputs() {
        if !bf16_or_skip("forward_and_gradients_match_the_f32_convolution_of_rounded_inputs") {
            return;
        }
        let g = ConvGeom { h: 7, w: 9, cin: 32, cout: 20 };
        assert!(fits(&g));
        let input = rounded(&padded(&g, g.cin, 0.3));
        let kernel = rounded(&values(9 * g.cin * g.cout, 1.7));
        let mut packed = PackedB::default();
        packed.pack(&kernel, View::rows(0, 9 * g.cin, g.cout, g.cout));
        let mut input_b = vec![0u16; input.len()];
        bf16::convert(&input, &mut input_b);
        let close = |x: &[f32], e: &[f32], what: &str| {
            for (i, (a, b)) in x.iter().zip(e).enumerate() {
                assert!((a - b).abs() <= 1e-4 * (1.0 + b.abs()), "{what}[{i}]: {a} vs {b}");
            }
        };
        let (mut out, mut expected) = (vec![0f32; g.rows() * g.cout], vec![0f32; g.rows() * g.cout]);
        forward_rows(&input_b, &packed, &g, 0, &mut out);
        conv::forward(&input, &kernel, &g, &mut expected, &mut [], 1);
        close(&out, &expected, "forward");
        // A band of rows starting inside the image.
        let mut band = vec![0f32; 10 * g.cout];
        forward_rows(&input_b, &packed, &g, 13, &mut band);
        close(&band, &expected[13 * g.cout..23 * g.cout], "band");

        let grad = rounded(&padded(&g, g.cout, 2.9));
        let (mut dk, mut dk_expected) = (vec![0.5f32; 9 * g.cin * g.cout], vec![0.5f32; 9 * g.cin * g.cout]);
        let (mut input_t, mut grad_packed) = (Aligned::default(), PackedB::default());
        transpose_padded(&input_b, &g, &mut input_t);
        for (ch, plane) in input_t.chunks_exact(plane(&g)).enumerate() {
            let pixels: Vec<u16> = input_b[..g.padded_in()].chunks_exact(g.cin).map(|px| px[ch]).collect();
            assert_eq!(plane[..pixels.len()], pixels[..], "channel {ch}'s plane");
            assert!(plane[pixels.len()..].iter().all(|&v| v == 0), "channel {ch}'s tail");
        }
        pack_output_grad(&grad, &g, &mut grad_packed);
        kernel_grad(&input_t, &grad_packed, &g, &mut dk);
        conv::kernel_grad(&input, &grad, &g, &mut dk_expected, &mut [], 1);
        close(&dk, &dk_expected, "kernel gradient");
    }
}
