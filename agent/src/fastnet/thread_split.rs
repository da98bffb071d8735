//! One image's layers split across threads, for the actors' small batches: with fewer images than
//! threads, `gemm`'s own threading does little for one image (the per-call hand-off costs more
//! than the work it shares), so each thread instead takes a band of the output — a band of image
//! lines (their convolution, then bias, ReLU and pooling of those lines) or a band of a dense
//! layer's units (for any batch on more than one thread: `gemm`'s own two threads were slower at
//! the learner's 32 rows too). Bands share only read-only inputs and write disjoint slices, on the `rayon` pool
//! `gemm` already runs on. A convolution output is the same dot product as on one thread; a dense
//! unit's sum may be ordered differently (Q values within 1e-5 relative, tested).

use super::conv::ConvGeom;
use super::conv_bf16::Operands;
use super::conv_direct;
use super::gemm::{View, matmul};
use super::pool::{self, Strided};

/// Lines `start..end` of band `band` of `bands` over an image of `h` lines: even boundaries, so
/// that each band pools whole pairs of lines (the last band takes an odd last line, which pooling
/// drops).
fn line_band(h: usize, bands: usize, band: usize) -> (usize, usize) {
    let pairs = h / 2;
    let start = 2 * (band * pairs / bands);
    let end = if band + 1 == bands { h } else { 2 * ((band + 1) * pairs / bands) };
    (start, end)
}

/// Floats of one output row's patch (0 when the layer does not gather patches).
fn patch_row(g: &ConvGeom) -> usize {
    if g.gathers() { 9 * g.cin } else { 0 }
}

/// Convolution of one padded image (`conv::forward`'s arguments) into `pre`, then
/// `relu(pre + bias)` pooled into `dst` through `to`, which must keep pooled lines apart (the next
/// layer's padded input, [`Strided::padded`]), band by band on up to `threads` threads.
/// (Pooling block by block of a few lines while they are in cache was measured: no gain.)
///
/// # Panics
/// If `to` interleaves channels of different lines (a channel-major destination).
#[allow(clippy::too_many_arguments)]
pub fn conv_pool(
    ops: Operands<'_>,
    g: &ConvGeom,
    bias: &[f32],
    pre: &mut [f32],
    patches: &mut [f32],
    dst: &mut [f32],
    to: Strided,
    threads: usize,
) {
    assert!(to.chan == 1 && to.row >= to.col * (g.w / 2), "conv_pool: a destination whose lines overlap: {to:?}");
    let (pw, cout, pr) = (g.pw(), g.cout, patch_row(g));
    let line_to = Strided { base: 0, ..to };
    let (pre, patches, dst) = (&mut pre[..g.out_len()], &mut patches[..g.rows() * pr], &mut dst[to.base..]);
    let bands = threads.min(g.h / 2).max(1);
    if bands == 1 {
        conv_pool_lines(ops, g, bias, (0, g.h), pre, patches, dst, line_to);
        return;
    }
    rayon::scope(|scope| {
        let (mut pre_rest, mut patches_rest, mut dst_rest) = (pre, patches, dst);
        for band in 0..bands {
            let (y0, y1) = line_band(g.h, bands, band);
            let (first, end) = (y0 * pw, (y1 * pw).min(g.rows()));
            let (pre_band, rest) = std::mem::take(&mut pre_rest).split_at_mut((y1 - y0) * pw * cout);
            pre_rest = rest;
            let (patch_band, rest) = std::mem::take(&mut patches_rest).split_at_mut((end - first) * pr);
            patches_rest = rest;
            let (dst_band, rest) = std::mem::take(&mut dst_rest).split_at_mut((y1 / 2 - y0 / 2) * to.row);
            dst_rest = rest;
            let mut work = move || conv_pool_lines(ops, g, bias, (y0, y1), pre_band, patch_band, dst_band, line_to);
            if band + 1 == bands { work() } else { scope.spawn(move |_| work()) }
        }
    });
}

/// [`conv_pool`] of lines `y0..y1` (even `y0`) on the calling thread: `pre` holds those lines'
/// output, `patches` their rows' patches and `dst` their pooled lines.
#[allow(clippy::too_many_arguments)]
fn conv_pool_lines(
    ops: Operands<'_>,
    g: &ConvGeom,
    bias: &[f32],
    (y0, y1): (usize, usize),
    pre: &mut [f32],
    patches: &mut [f32],
    dst: &mut [f32],
    to: Strided,
) {
    let (first, end) = (y0 * g.pw(), (y1 * g.pw()).min(g.rows()));
    ops.forward_rows(g, first, &mut pre[..(end - first) * g.cout], patches);
    pool::forward(pre, bias, y1 - y0, g.w, dst, to);
}

/// The first layer of one padded image computed directly and pooled into `dst` through `to`
/// (`conv_direct::forward_pool`; the next layer's padded input), band by band of lines on up to
/// `threads` threads. Each output is computed as on one thread, so the bits do not depend on
/// the bands.
#[allow(clippy::too_many_arguments)]
pub fn direct_pool(input: &[f32], kernel: &[f32], bias: &[f32], g: &ConvGeom, dst: &mut [f32], to: Strided, threads: usize) {
    assert!(to.chan == 1 && to.row >= to.col * (g.w / 2), "direct_pool: a destination whose lines overlap: {to:?}");
    let line_to = Strided { base: 0, ..to };
    let dst = &mut dst[to.base..];
    let bands = threads.min(g.h / 2).max(1);
    if bands == 1 {
        conv_direct::forward_pool(input, kernel, bias, g, (0, g.h), dst, line_to);
        return;
    }
    rayon::scope(|scope| {
        let mut dst_rest = dst;
        for band in 0..bands {
            let (y0, y1) = line_band(g.h, bands, band);
            let (dst_band, rest) = std::mem::take(&mut dst_rest).split_at_mut((y1 / 2 - y0 / 2) * to.row);
            dst_rest = rest;
            let mut work = move || conv_direct::forward_pool(input, kernel, bias, g, (y0, y1), dst_band, line_to);
            if band + 1 == bands { work() } else { scope.spawn(move |_| work()) }
        }
    });
}

/// The convolution of one padded image (`conv::forward`) with its output rows split across up to
/// `threads` threads.
pub fn conv(ops: Operands<'_>, g: &ConvGeom, out: &mut [f32], patches: &mut [f32], threads: usize) {
    let (rows, cout, pr) = (g.rows(), g.cout, patch_row(g));
    let bands = threads.min(g.h).max(1);
    if bands == 1 {
        ops.forward_rows(g, 0, &mut out[..rows * cout], &mut patches[..rows * pr]);
        return;
    }
    rayon::scope(|scope| {
        let (mut out_rest, mut patches_rest) = (&mut out[..rows * cout], &mut patches[..rows * pr]);
        for band in 0..bands {
            let (first, end) = (band * rows / bands, (band + 1) * rows / bands);
            let (o, rest) = std::mem::take(&mut out_rest).split_at_mut((end - first) * cout);
            out_rest = rest;
            let (p, rest) = std::mem::take(&mut patches_rest).split_at_mut((end - first) * pr);
            patches_rest = rest;
            let mut work = move || ops.forward_rows(g, first, o, p);
            if band + 1 == bands { work() } else { scope.spawn(move |_| work()) }
        }
    });
}

/// `out = input · Wᵀ` (`b × n`, no bias) for a candle `Linear` weight `W` (`n × k`), its units
/// split across up to `threads` threads: each thread multiplies its band of `W`'s rows (contiguous,
/// so each weight is read once, by one thread) into its rows of `outᵀ`, held in `scratch`.
#[allow(clippy::too_many_arguments)]
pub fn dense(out: &mut [f32], input: &[f32], w: &[f32], b: usize, k: usize, n: usize, scratch: &mut Vec<f32>, threads: usize) {
    let bands = threads.min(n).max(1);
    scratch.resize(n * b, 0.0);
    rayon::scope(|scope| {
        let mut rest_t = &mut scratch[..];
        for band in 0..bands {
            let (first, end) = (band * n / bands, (band + 1) * n / bands);
            let (t, rest) = std::mem::take(&mut rest_t).split_at_mut((end - first) * b);
            rest_t = rest;
            // Rows first..end of outᵀ = W[first..end] · inputᵀ; with one image, a matrix-vector
            // product over contiguous rows of W.
            let mut work = move || {
                let dst = View::rows(0, end - first, b, b);
                matmul(t, dst, false, w, View::rows(first * k, end - first, k, k), input, View::rows(0, b, k, k).t(), 1);
            };
            if band + 1 == bands { work() } else { scope.spawn(move |_| work()) }
        }
    });
    for (j, units) in scratch.chunks_exact(b).enumerate() {
        for (i, &v) in units.iter().enumerate() {
            out[i * n + j] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_bands_cover_the_image_in_even_steps() {
        for h in [1, 2, 5, 21, 42, 84] {
            for bands in 1..=4 {
                let bands = bands.min(h / 2).max(1);
                let mut next = 0;
                for band in 0..bands {
                    let (start, end) = line_band(h, bands, band);
                    assert_eq!(start, next, "h {h}, {bands} bands");
                    assert!(start % 2 == 0 && (end % 2 == 0 || end == h) && end > start, "h {h}: {start}..{end}");
                    next = end;
                }
                assert_eq!(next, h);
            }
        }
    }
}
