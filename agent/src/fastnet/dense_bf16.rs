//! The first dense layer (fc1: the flattened convolution output, 2,306 inputs at 48×48, into
//! 256 units) on a bf16 kernel (`bf16_matmul`) for a training batch: its forward pass, weight
//! gradient and input gradient as three bf16 products with f32 accumulation, split across
//! threads by rows of each product's output. The bias, the ReLU and everything after stay f32.
//!
//! - forward: `outᵀ = W · inputᵀ`, `W` (candle's `n × k`) rounded once per call into rows of K
//!   padded to a tile step, the input packed transposed (K = k, N = the batch);
//! - weight gradient: `dW = upstreamᵀ · input` (K = the batch, padded);
//! - input gradient: `dinput = upstream · W` (K = n).

use super::aligned::Aligned;
use super::bf16;
use super::bf16_matmul::{self, AView, K_STEP, PackedB};
use super::gemm::View;

/// Images from which the layer runs on the bf16 kernel: one tile's rows. The forward pass's
/// N is the batch, padded to 16 columns, so an actor's batch of 1–8 would multiply mostly zeros
/// (it stays f32).
pub const MIN_BATCH: usize = 16;

/// The layer's bf16 operands, kept across calls.
#[derive(Debug, Default)]
pub struct DenseBf16 {
    /// `W` in bf16, `n` rows of K padded to a tile step.
    w_rows: Aligned<u16>,
    /// The forward pass's `inputᵀ`, packed.
    input_t: PackedB,
    /// The weight gradient's `input`, packed.
    input: PackedB,
    /// The upstream gradient in bf16 (transposed for the weight gradient), K padded.
    upstream: Aligned<u16>,
    /// `W` packed as the input gradient's right matrix.
    w_packed: PackedB,
    /// `outᵀ` of the forward pass.
    out_t: Vec<f32>,
}

/// Splits `rows` rows into `threads` bands of whole 16-row tiles where there are enough, and runs
/// `work(first, rows_in_band, dst_band)` on each, the last on the calling thread.
fn tile_bands<F>(dst: &mut [f32], rows: usize, row_len: usize, threads: usize, work: F)
where
    F: Fn(usize, usize, &mut [f32]) + Sync,
{
    let tiles = rows.div_ceil(16);
    let bands = threads.min(tiles).max(1);
    let work = &work;
    rayon::scope(|scope| {
        let mut rest = &mut dst[..rows * row_len];
        for band in 0..bands {
            let first = (band * tiles / bands * 16).min(rows);
            let end = ((band + 1) * tiles / bands * 16).min(rows);
            let (mine, tail) = std::mem::take(&mut rest).split_at_mut((end - first) * row_len);
            rest = tail;
            if band + 1 == bands {
                work(first, end - first, mine);
            } else {
                scope.spawn(move |_| work(first, end - first, mine));
            }
        }
    });
}

impl DenseBf16 {
    /// `out = input · Wᵀ` (`b × n`, no bias) for `input` (`b × k`) and candle's `W` (`n × k`).
    ///
    /// # Panics
    /// If the slices do not fit `b`, `k` and `n`, or no bf16 kernel runs here.
    #[allow(clippy::too_many_arguments)]
    pub fn forward(&mut self, out: &mut [f32], input: &[f32], w: &[f32], b: usize, k: usize, n: usize, threads: usize) {
        assert!(out.len() == b * n && input.len() == b * k && w.len() == n * k, "dense_bf16::forward: {b} × {k} · ({n} × {k})ᵀ");
        let k_pad = k.next_multiple_of(K_STEP);
        rows_to_bf16(w, n, k, k_pad, &mut self.w_rows);
        self.input_t.pack(input, View::rows(0, b, k, k).t());
        self.out_t.resize(n * b, 0.0);
        let (w_rows, packed) = (&self.w_rows[..], &self.input_t);
        tile_bands(&mut self.out_t, n, b, threads, |first, rows, dst| {
            bf16_matmul::matmul(dst, View::rows(0, rows, b, b), false, w_rows, AView::rows(first * k_pad, rows, k_pad, k_pad), packed);
        });
        for (j, units) in self.out_t.chunks_exact(b).enumerate() {
            for (i, &v) in units.iter().enumerate() {
                out[i * n + j] = v;
            }
        }
    }

    /// The weight gradient `dw = upstreamᵀ · input` (`n × k`) for `upstream` (`b × n`) and
    /// `input` (`b × k`).
    ///
    /// # Panics
    /// As [`Self::forward`].
    #[allow(clippy::too_many_arguments)]
    pub fn weight_grad(&mut self, dw: &mut [f32], upstream: &[f32], input: &[f32], b: usize, n: usize, k: usize, threads: usize) {
        assert!(dw.len() == n * k && upstream.len() == b * n && input.len() == b * k, "dense_bf16::weight_grad: ({b} × {n})ᵀ · {b} × {k}");
        let b_pad = b.next_multiple_of(K_STEP);
        self.upstream.clear();
        self.upstream.resize(n * b_pad, 0);
        for (i, row) in upstream.chunks_exact(n).enumerate() {
            for (j, &u) in row.iter().enumerate() {
                self.upstream[j * b_pad + i] = bf16::from_f32_finite(u);
            }
        }
        self.input.pack(input, View::rows(0, b, k, k));
        let (a, packed) = (&self.upstream[..], &self.input);
        tile_bands(dw, n, k, threads, |first, rows, dst| {
            bf16_matmul::matmul(dst, View::rows(0, rows, k, k), false, a, AView::rows(first * b_pad, rows, b_pad, b_pad), packed);
        });
    }

    /// The input gradient `dinput = upstream · W` (`b × k`).
    ///
    /// # Panics
    /// As [`Self::forward`].
    #[allow(clippy::too_many_arguments)]
    pub fn input_grad(&mut self, dinput: &mut [f32], upstream: &[f32], w: &[f32], b: usize, n: usize, k: usize, threads: usize) {
        assert!(dinput.len() == b * k && upstream.len() == b * n && w.len() == n * k, "dense_bf16::input_grad: {b} × {n} · {n} × {k}");
        let n_pad = n.next_multiple_of(K_STEP);
        rows_to_bf16(upstream, b, n, n_pad, &mut self.upstream);
        self.w_packed.pack(w, View::rows(0, n, k, k));
        let (a, packed) = (&self.upstream[..], &self.w_packed);
        tile_bands(dinput, b, k, threads, |first, rows, dst| {
            bf16_matmul::matmul(dst, View::rows(0, rows, k, k), false, a, AView::rows(first * n_pad, rows, n_pad, n_pad), packed);
        });
    }
}

/// `src` (`rows × cols`) in bf16, each row zero-padded to `stride` values.
fn rows_to_bf16(src: &[f32], rows: usize, cols: usize, stride: usize, dst: &mut Aligned<u16>) {
    dst.resize(rows * stride, 0);
    for (d, s) in dst.chunks_exact_mut(stride).zip(src.chunks_exact(cols)) {
        let (values, pad) = d.split_at_mut(cols);
        bf16::convert(s, values);
        pad.fill(0);
    }
}

#[cfg(test)]
mod tests {
    use super::super::bf16_matmul::tests::bf16_or_skip;
    use super::*;

    fn values(n: usize, seed: f32) -> Vec<f32> {
        (0..n).map(|i| ((i as f32 + seed) * 0.618).sin()).collect()
    }

    fn round(v: &[f32]) -> Vec<f64> {
        v.iter().map(|&x| f64::from(bf16::to_f32(bf16::from_f32(x)))).collect()
    }

    /// `c[i][j] = Σ_p a[i][p] · b[p][j]` in f64 over strided views (`(row, col) → index`).
    fn product(rows: usize, cols: usize, inner: usize, a: impl Fn(usize, usize) -> f64, b: impl Fn(usize, usize) -> f64) -> Vec<f64> {
        let mut c = vec![0.0; rows * cols];
        for i in 0..rows {
            for j in 0..cols {
                c[i * cols + j] = (0..inner).map(|p| a(i, p) * b(p, j)).sum();
            }
        }
        c
    }

    fn close(got: &[f32], want: &[f64], inner: usize, what: &str) {
        assert_eq!(got.len(), want.len(), "{what}");
        for (i, (&g, &w)) in got.iter().zip(want).enumerate() {
            // f32 accumulation of `inner` products of values below 1.
            assert!((f64::from(g) - w).abs() <= 4e-6 * inner as f64, "{what} [{i}]: {g} vs {w}");
        }
    }

    /// Each of the three products against its f64 definition on the bf16-rounded inputs, at the
    /// learner's shape and at ones with partial tiles and K that is no multiple of a tile step,
    /// on one and two threads.
    #[test]
    fn the_three_products_match_their_definition_on_bf16_inputs() {
        if !bf16_or_skip("the_three_products_match_their_definition_on_bf16_inputs") {
            return;
        }
        for (b, k, n) in [(32, 2306, 256), (17, 45, 40), (20, 64, 33)] {
            let (x, w, up) = (values(b * k, 0.3), values(n * k, 1.7), values(b * n, 2.9));
            let (xr, wr, upr) = (round(&x), round(&w), round(&up));
            let fwd = product(b, n, k, |i, p| xr[i * k + p], |p, j| wr[j * k + p]);
            let dw = product(n, k, b, |i, p| upr[p * n + i], |p, j| xr[p * k + j]);
            let dx = product(b, k, n, |i, p| upr[i * n + p], |p, j| wr[p * k + j]);
            for threads in [1, 2] {
                let mut layer = DenseBf16::default();
                let what = format!("b {b}, k {k}, n {n}, {threads} threads");
                let mut out = vec![f32::NAN; b * n];
                layer.forward(&mut out, &x, &w, b, k, n, threads);
                close(&out, &fwd, k, &format!("forward, {what}"));
                let mut g = vec![f32::NAN; n * k];
                layer.weight_grad(&mut g, &up, &x, b, n, k, threads);
                close(&g, &dw, b, &format!("weight gradient, {what}"));
                let mut d = vec![f32::NAN; b * k];
                layer.input_grad(&mut d, &up, &w, b, n, k, threads);
                close(&d, &dx, n, &format!("input gradient, {what}"));
            }
        }
    }
}
