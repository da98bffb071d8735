//! The layouts of the bf16 product's operands (`bf16_matmul`), which both of its kernels multiply
//! (`bf16` values are `u16` bit patterns, see `fastnet::bf16`):
//! - the left matrix is read in place through an [`AView`]: rows at a stride, each row's K values
//!   in `segments` runs of `seg_len` (a multiple of 32) consecutive values, `seg_stride` apart. A
//!   convolution reads its padded image this way (a run per kernel row), with no packing;
//! - the right matrix is a [`PackedB`]: K padded to a multiple of 32 with zeros, N to a multiple
//!   of 16, and rows taken in pairs (`[k / 2][n][k % 2]`), the layout both instructions multiply by.

use super::aligned::Aligned;
use super::gemm::View;

/// Values of K one step of either kernel consumes (64 bytes of bf16: one AMX tile row).
pub const K_STEP: usize = 32;
/// Columns of the right matrix one step covers (one AMX tile, one zmm register of f32).
pub(super) const N_STEP: usize = 16;
/// K steps of one pass of a kernel over the output (192 values: one kernel row of a 64-channel
/// convolution): one pass's panel of B (24 KiB for N = 64) and a row block of A stay in L1 while
/// the output streams past them.
pub(super) const K_BLOCK: usize = 6;

/// One pass of a kernel over the output: at most [`K_BLOCK`] consecutive K steps inside one
/// segment of A.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct KBlock {
    /// Index in A of row 0's first value of the block.
    pub a_k: usize,
    /// Index in the packed B's data of the block's first pair row.
    pub b_k: usize,
    /// K steps in the block.
    pub chunks: usize,
    /// Whether it is the first block (the output is written, not added to, unless the caller
    /// accumulates).
    pub first: bool,
}

/// The left matrix of a bf16 product (`bf16_matmul::matmul`) inside a `u16` slice: element (i, k) at
/// `offset + i·row_stride + (k / seg_len)·seg_stride + k % seg_len`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AView {
    pub offset: usize,
    pub rows: usize,
    pub row_stride: usize,
    pub segments: usize,
    pub seg_len: usize,
    pub seg_stride: usize,
}

impl AView {
    /// A dense row-major `rows × k` matrix (`k` a multiple of [`K_STEP`]) with rows `row_stride` apart.
    #[must_use]
    pub fn rows(offset: usize, rows: usize, k: usize, row_stride: usize) -> Self {
        Self { offset, rows, row_stride, segments: 1, seg_len: k, seg_stride: 0 }
    }

    /// K, the values of one row.
    #[must_use]
    pub fn k(&self) -> usize {
        self.segments * self.seg_len
    }

    /// Its K steps in passes of at most [`K_BLOCK`], in K's order, against a packed B of `n_pad`
    /// columns.
    pub(super) fn k_blocks(&self, n_pad: usize) -> impl Iterator<Item = KBlock> {
        let seg_chunks = self.seg_len / K_STEP;
        let (offset, seg_len, seg_stride) = (self.offset, self.seg_len, self.seg_stride);
        (0..self.segments).flat_map(move |seg| {
            (0..seg_chunks).step_by(K_BLOCK).map(move |c0| KBlock {
                a_k: offset + seg * seg_stride + c0 * K_STEP,
                b_k: (seg * seg_len + c0 * K_STEP) / 2 * 2 * n_pad,
                chunks: (seg_chunks - c0).min(K_BLOCK),
                first: seg == 0 && c0 == 0,
            })
        })
    }

    /// One past the largest index the view reads, `None` if that overflows.
    pub(super) fn end(&self) -> Option<usize> {
        if self.rows == 0 || self.k() == 0 {
            return Some(self.offset);
        }
        let last_row = (self.rows - 1).checked_mul(self.row_stride)?;
        let last_seg = (self.segments - 1).checked_mul(self.seg_stride)?;
        self.offset.checked_add(last_row)?.checked_add(last_seg)?.checked_add(self.seg_len)
    }
}

/// A right matrix (`k × n`) in the pair-interleaved layout of `tdpbf16ps`, K padded with zeros to a
/// multiple of [`K_STEP`] and N to a multiple of 16.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PackedB {
    /// Aligned to a cache line, as every tile row of it then is (rows are 64 bytes).
    pub(super) data: Aligned<u16>,
    pub(super) k_pad: usize,
    /// K before padding: with N, what the zeroed padding is laid out for.
    k: usize,
    pub(super) n: usize,
    pub(super) n_pad: usize,
}

impl PackedB {
    /// Packs the `k × n` f32 matrix `src` (read through `v`, any strides) rounded to bf16 (a NaN
    /// in a contiguous source may come out infinite: `bf16::from_f32_finite`).
    ///
    /// # Panics
    /// If the view leaves `src`.
    pub fn pack(&mut self, src: &[f32], v: View) {
        let (k, n) = (v.rows, v.cols);
        if (k, n) != (self.k, self.n) {
            // A new shape: zero it all. The same shape again writes every value of the matrix
            // and leaves the padding as it was, zero (a matrix packed per image or per call
            // spent a tenth of its time clearing what it then overwrote).
            self.k = k;
            self.k_pad = k.div_ceil(K_STEP) * K_STEP;
            self.n = n;
            self.n_pad = n.div_ceil(N_STEP) * N_STEP;
            self.data.clear();
            self.data.resize(self.k_pad * self.n_pad, 0);
        }
        if k > 0 && n > 0 {
            assert!(
                (v.offset + (k - 1) * v.row_stride + (n - 1) * v.col_stride) < src.len(),
                "PackedB::pack: {v:?} leaves a slice of {}",
                src.len()
            );
        }
        if v.col_stride == 1 {
            // Rows of the source are contiguous: interleave each pair in one pass.
            for (pair, out) in self.data.chunks_exact_mut(2 * self.n_pad).take(k.div_ceil(2)).enumerate() {
                let even = &src[v.offset + 2 * pair * v.row_stride..][..n];
                if 2 * pair + 1 < k {
                    let odd = &src[v.offset + (2 * pair + 1) * v.row_stride..][..n];
                    super::bf16::convert_pairs(even, odd, &mut out[..2 * n]);
                } else {
                    for (o, &e) in out.chunks_exact_mut(2).zip(even) {
                        o[0] = super::bf16::from_f32_finite(e);
                    }
                }
            }
            return;
        }
        if v.row_stride == 1 && k.is_multiple_of(2) {
            // The source is transposed (its columns contiguous: a batch of inputs as the right
            // matrix): each column's pair of rows is two neighbouring values.
            for j in 0..n {
                let col = &src[v.offset + j * v.col_stride..][..k];
                for (pair, kv) in col.chunks_exact(2).enumerate() {
                    let o = pair * 2 * self.n_pad + 2 * j;
                    self.data[o] = super::bf16::from_f32_finite(kv[0]);
                    self.data[o + 1] = super::bf16::from_f32_finite(kv[1]);
                }
            }
            return;
        }
        for kk in 0..k {
            let row = &mut self.data[(kk / 2) * 2 * self.n_pad..(kk / 2 + 1) * 2 * self.n_pad];
            for j in 0..n {
                row[2 * j + kk % 2] = super::bf16::from_f32(src[v.offset + kk * v.row_stride + j * v.col_stride]);
            }
        }
    }

    /// K (padded) and N of the matrix.
    #[must_use]
    pub fn dims(&self) -> (usize, usize) {
        (self.k_pad, self.n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn k_blocks_cover_k_in_order_without_crossing_a_segment() {
        // 3 segments of 7 steps, 1000 values apart; B rows of 64 columns.
        let av = AView { offset: 5, rows: 2, row_stride: 64, segments: 3, seg_len: 7 * K_STEP, seg_stride: 1000 };
        let blocks: Vec<KBlock> = av.k_blocks(64).collect();
        assert_eq!(blocks.iter().map(|b| b.chunks).collect::<Vec<_>>(), [6, 1, 6, 1, 6, 1]);
        assert_eq!(blocks.iter().map(|b| b.first).collect::<Vec<_>>(), [true, false, false, false, false, false]);
        // Segment 1's second block: 6 steps into segment 1 of A; K value 7·32 + 6·32 of B, whose
        // pair rows hold 2 × 64 values.
        assert_eq!(blocks[3].a_k, 5 + 1000 + 6 * K_STEP);
        assert_eq!(blocks[3].b_k, (7 * K_STEP + 6 * K_STEP) / 2 * 2 * 64);
        assert_eq!(AView::rows(0, 4, 0, 32).k_blocks(16).count(), 0);
    }

    /// Packing again into the same buffer, in the same shape or after another, gives what a
    /// fresh buffer does (the padding stays zero where only the values are rewritten).
    #[test]
    fn a_buffer_packed_again_equals_a_fresh_one() {
        let values = |n: usize, seed: f32| -> Vec<f32> { (0..n).map(|i| (i as f32 * 0.71 + seed).cos()).collect() };
        let mut reused = PackedB::default();
        for (k, n, seed) in [(45, 20, 1.0), (45, 20, 2.0), (7, 33, 3.0), (45, 20, 4.0), (64, 16, 5.0)] {
            let src = values(k * n, seed);
            reused.pack(&src, View::rows(0, k, n, n));
            let mut fresh = PackedB::default();
            fresh.pack(&src, View::rows(0, k, n, n));
            assert_eq!(reused, fresh, "k {k}, n {n}");
        }
    }

    /// Every source layout packs to the same pairs: contiguous rows, contiguous columns (a
    /// transposed source) and any strides, with K and N that are no multiple of a step.
    #[test]
    fn every_source_layout_packs_the_same_pairs() {
        for (k, n) in [(64, 32), (46, 21), (7, 3), (2, 17)] {
            let rows: Vec<f32> = (0..k * n).map(|i| (i as f32 * 0.37).sin()).collect();
            let mut cols = vec![0.0; k * n];
            let mut strided = vec![0.0; 3 * k * n + 5];
            for kk in 0..k {
                for j in 0..n {
                    cols[j * k + kk] = rows[kk * n + j];
                    strided[5 + kk * 3 * n + 2 * j] = rows[kk * n + j];
                }
            }
            let mut expected = PackedB::default();
            expected.pack(&rows, View::rows(0, k, n, n));
            for (src, v) in
                [(&cols, View::rows(0, n, k, k).t()), (&strided, View { offset: 5, rows: k, cols: n, row_stride: 3 * n, col_stride: 2 })]
            {
                let mut got = PackedB::default();
                got.pack(src, v);
                assert_eq!(got, expected, "k {k}, n {n}, {v:?}");
            }
        }
    }
}
