//! AVX512-BF16: detection, and the `vdpbf16ps` kernel of `bf16_matmul` for CPUs without AMX
//! (Intel Xeons before Sapphire Rapids that have it, AMD Zen 4 and later). One `vdpbf16ps`
//! multiplies 16 pairs of bf16 values into 16 f32 sums, twice the products of an f32 FMA on the
//! same register. On Intel's cores it issues on one port where FMA has two, so there it loses to
//! f32; on AMD Zen 4 it beats f32 (docs/PERFORMANCE.md#bf16). It runs only where `precision =
//! "bf16"` asks for it: `auto` is AMX only.
//!
//! A block of up to 6 output rows × 64 columns (24 zmm accumulators) is kept in registers over
//! one K block: per pair of K values, the block's 4 vectors of the packed right matrix are loaded
//! and each row's pair of left values is broadcast to all 16 lanes.

#![allow(unsafe_code)]

use super::bf16_layout::{AView, K_STEP, PackedB};
use super::gemm::View;

/// Rows of one register block.
const MR: usize = 6;
/// 16-column vectors of one register block (64 columns).
const NV: usize = 4;

/// Whether this process may run the kernel: `Ok` where the CPU has AVX-512F and AVX512-BF16 and the
/// OS saves the zmm state, else the reason it may not.
pub fn available() -> Result<(), &'static str> {
    #[cfg(target_arch = "x86_64")]
    {
        if !std::arch::is_x86_feature_detected!("avx512f") {
            return Err("the CPU has no AVX-512F");
        }
        if !std::arch::is_x86_feature_detected!("avx512bf16") {
            return Err("the CPU has no AVX512-BF16");
        }
        Ok(())
    }
    #[cfg(not(target_arch = "x86_64"))]
    Err("AVX512-BF16 exists only on x86_64")
}

/// `dst = a · b` (or `+=`) with `vdpbf16ps`, on the calling thread.
///
/// # Safety
/// The kernel is [`available`], and `bf16_matmul::matmul` has checked the views against their
/// slices and the shapes against each other, with at least one row, one column and one K step.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bf16")]
pub(super) unsafe fn matmul_unchecked(dst: &mut [f32], d: View, accumulate: bool, a: &[u16], av: AView, b: &PackedB) {
    let pair_row = 2 * b.n_pad;
    // K in passes of at most K_BLOCK steps, as AMX's: a pass's right panel (192 × 64 bf16,
    // 24 KiB) stays in L1 while every row block streams past it.
    for kb in av.k_blocks(b.n_pad) {
        let (a_k, b_k) = (kb.a_k, kb.b_k);
        let pairs = kb.chunks * K_STEP / 2;
        let acc = accumulate || !kb.first;
        for i0 in (0..d.rows).step_by(MR) {
            let rows = (d.rows - i0).min(MR);
            for j0 in (0..d.cols).step_by(16 * NV) {
                let cols = (d.cols - j0).min(16 * NV);
                let block = Block {
                    c: dst.as_mut_ptr().wrapping_add(d.offset + i0 * d.row_stride + j0),
                    ldc: d.row_stride,
                    last_mask: match cols % 16 {
                        0 => u16::MAX,
                        r => (1u16 << r) - 1,
                    },
                    accumulate: acc,
                    a: a.as_ptr().wrapping_add(a_k + i0 * av.row_stride),
                    lda: av.row_stride,
                    b: b.data.as_ptr().wrapping_add(b_k + 2 * j0),
                    pair_row,
                    pairs,
                };
                // SAFETY: rows i0..i0 + rows of A and C and columns j0..j0 + cols of C lie
                // inside the checked views; B's rows of this K block and columns up to the next
                // multiple of 16 (≤ n_pad) lie inside the packed matrix.
                unsafe { block.run_rows(rows, cols.div_ceil(16)) };
            }
        }
    }
}

/// Placeholder off x86_64: [`available`] is never `Ok` there.
///
/// # Safety
/// Never callable: the kernel is not available off x86_64.
#[cfg(not(target_arch = "x86_64"))]
pub(super) unsafe fn matmul_unchecked(_: &mut [f32], _: View, _: bool, _: &[u16], _: AView, _: &PackedB) {
    unreachable!("AVX512-BF16 is never available off x86_64")
}

/// One register block of the output and the K block it sums.
#[cfg(target_arch = "x86_64")]
struct Block {
    /// The block's first output element; rows `ldc` apart.
    c: *mut f32,
    ldc: usize,
    /// Columns of the block's last 16-column vector that belong to the output.
    last_mask: u16,
    accumulate: bool,
    /// The block's first row's first K value of this K block; rows `lda` apart.
    a: *const u16,
    lda: usize,
    /// The packed right matrix at this K block's first pair row and the block's first column.
    b: *const u16,
    /// `u16` values per pair row of the packed right matrix.
    pair_row: usize,
    pairs: usize,
}

#[cfg(target_arch = "x86_64")]
impl Block {
    /// [`Block::run`] for `rows` (1..=6) rows and `vectors` (1..=4) column vectors.
    #[target_feature(enable = "avx512f,avx512bf16")]
    unsafe fn run_rows(&self, rows: usize, vectors: usize) {
        // SAFETY (all arms): the caller's, for a block of this many rows and vectors.
        unsafe {
            match rows {
                1 => self.run_vectors::<1>(vectors),
                2 => self.run_vectors::<2>(vectors),
                3 => self.run_vectors::<3>(vectors),
                4 => self.run_vectors::<4>(vectors),
                5 => self.run_vectors::<5>(vectors),
                _ => self.run_vectors::<MR>(vectors),
            }
        }
    }

    #[target_feature(enable = "avx512f,avx512bf16")]
    unsafe fn run_vectors<const R: usize>(&self, vectors: usize) {
        // SAFETY (all arms): the caller's.
        unsafe {
            match vectors {
                1 => self.run::<R, 1>(),
                2 => self.run::<R, 2>(),
                3 => self.run::<R, 3>(),
                _ => self.run::<R, NV>(),
            }
        }
    }

    /// The block's sums over its K block: `R` rows, `V` vectors of 16 columns (the last masked).
    #[target_feature(enable = "avx512f,avx512bf16")]
    #[inline]
    unsafe fn run<const R: usize, const V: usize>(&self) {
        use std::arch::x86_64::{
            __m512, __m512bh, _mm512_dpbf16_ps, _mm512_loadu_si512, _mm512_mask_storeu_ps, _mm512_maskz_loadu_ps, _mm512_set1_epi32,
            _mm512_setzero_ps,
        };
        let mask = |v: usize| if v + 1 == V { self.last_mask } else { u16::MAX };
        let mut acc: [[__m512; V]; R] = [[_mm512_setzero_ps(); V]; R];
        // SAFETY: every address below is inside the block's views (the caller's contract); loads
        // and stores of the last vector are masked to the output's columns.
        unsafe {
            if self.accumulate {
                for (r, row) in acc.iter_mut().enumerate() {
                    for (v, x) in row.iter_mut().enumerate() {
                        *x = _mm512_maskz_loadu_ps(mask(v), self.c.add(r * self.ldc + 16 * v));
                    }
                }
            }
            for p in 0..self.pairs {
                let bp = self.b.add(p * self.pair_row);
                let bv: [__m512bh; V] = std::array::from_fn(|v| std::mem::transmute(_mm512_loadu_si512(bp.add(32 * v).cast())));
                for (r, row) in acc.iter_mut().enumerate() {
                    let pair = self.a.add(r * self.lda + 2 * p).cast::<i32>().read_unaligned();
                    let x: __m512bh = std::mem::transmute(_mm512_set1_epi32(pair));
                    for (y, &bw) in row.iter_mut().zip(&bv) {
                        *y = _mm512_dpbf16_ps(*y, x, bw);
                    }
                }
            }
            for (r, row) in acc.iter().enumerate() {
                for (v, &x) in row.iter().enumerate() {
                    _mm512_mask_storeu_ps(self.c.add(r * self.ldc + 16 * v), mask(v), x);
                }
            }
        }
    }
}
