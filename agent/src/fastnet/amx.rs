//! Intel AMX: detection, and a bf16 matrix multiply with f32 accumulation on the tile registers
//! (`tdpbf16ps`), behind a bounds-checked safe interface. With `gemm.rs`, the only `unsafe` code of
//! the workspace: stable Rust has no AMX intrinsics, so the kernel is `asm!` with the tiles named
//! literally (tmm0–3 accumulate a 32 × 32 block of the output, tmm4–5 hold two 16-row strips of
//! the left matrix, tmm6–7 two 16-column strips of the right one).
//!
//! Layouts (`bf16` values are `u16` bit patterns, see `fastnet::bf16`):
//! - the left matrix is read in place through an [`AView`]: rows at a stride, each row's K values
//!   in `segments` runs of `seg_len` (a multiple of 32) consecutive values, `seg_stride` apart. A
//!   convolution reads its padded image this way (a run per kernel row), with no packing;
//! - the right matrix is a [`PackedB`]: K padded to a multiple of 32 with zeros and rows taken in
//!   pairs (`[k / 2][n][k % 2]`), the layout `tdpbf16ps` multiplies by.

#![allow(unsafe_code)]

use std::sync::OnceLock;

use super::gemm::View;

/// Values of K one tile step consumes (64 bytes of bf16).
pub const K_STEP: usize = 32;
/// Rows (and columns) of one accumulator tile.
const TILE: usize = 16;
/// K steps of one pass over the output (192 values: one kernel row of a 64-channel convolution).
const K_BLOCK: usize = 6;

/// Whether this process may run the AMX kernel: `Ok` on a CPU with AMX-TILE and AMX-BF16 whose
/// OS enables and grants the tile state, else the reason it may not (for the log line that says
/// which path runs). Checked once per process.
pub fn available() -> Result<(), &'static str> {
    static STATE: OnceLock<Result<(), &'static str>> = OnceLock::new();
    *STATE.get_or_init(detect)
}

#[cfg(target_arch = "x86_64")]
fn detect() -> Result<(), &'static str> {
    use std::arch::asm;
    use std::arch::x86_64::__cpuid_count;
    #[allow(unused_unsafe)]
    // SAFETY: CPUID exists on every x86_64 CPU.
    let (leaf1, leaf7) = unsafe { (__cpuid_count(1, 0), __cpuid_count(7, 0)) };
    if leaf7.edx & (1 << 24) == 0 {
        return Err("the CPU has no AMX-TILE (CPUID leaf 7 EDX bit 24)");
    }
    if leaf7.edx & (1 << 22) == 0 {
        return Err("the CPU has no AMX-BF16 (CPUID leaf 7 EDX bit 22)");
    }
    if leaf1.ecx & (1 << 27) == 0 {
        return Err("the OS has not enabled XSAVE (CPUID leaf 1 ECX bit 27)");
    }
    let (lo, _hi): (u32, u32);
    // SAFETY: XGETBV is available once OSXSAVE is set (checked above); it reads XCR0 only.
    unsafe { asm!("xgetbv", in("ecx") 0u32, out("eax") lo, out("edx") _hi, options(nomem, nostack, preserves_flags)) };
    if lo & (0b11 << 17) != 0b11 << 17 {
        return Err("the OS does not enable the tile state (XCR0 bits 17-18)");
    }
    // Linux hands out the 8 KiB tile state only on request: arch_prctl(ARCH_REQ_XCOMP_PERM,
    // XFEATURE_XTILEDATA), once per process; without it the first tile instruction is a SIGILL.
    const SYS_ARCH_PRCTL: i64 = 158;
    const ARCH_REQ_XCOMP_PERM: i64 = 0x1023;
    const XFEATURE_XTILEDATA: i64 = 18;
    let ret: i64;
    // SAFETY: a plain Linux system call that changes no memory of ours; rcx and r11 are clobbered
    // by `syscall` and declared so.
    unsafe {
        asm!(
            "syscall",
            inlateout("rax") SYS_ARCH_PRCTL => ret,
            in("rdi") ARCH_REQ_XCOMP_PERM,
            in("rsi") XFEATURE_XTILEDATA,
            lateout("rcx") _,
            lateout("r11") _,
            options(nostack)
        );
    }
    if ret != 0 {
        return Err("the kernel refused the tile state (arch_prctl ARCH_REQ_XCOMP_PERM)");
    }
    Ok(())
}

#[cfg(not(target_arch = "x86_64"))]
fn detect() -> Result<(), &'static str> {
    Err("AMX exists only on x86_64")
}

/// The left matrix of [`matmul`] inside a `u16` slice: element (i, k) at
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

    /// One past the largest index the view reads, `None` if that overflows.
    fn end(&self) -> Option<usize> {
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
    pub(super) data: Vec<u16>,
    pub(super) k_pad: usize,
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
        self.k_pad = k.div_ceil(K_STEP) * K_STEP;
        self.n = n;
        self.n_pad = n.div_ceil(TILE) * TILE;
        self.data.clear();
        self.data.resize(self.k_pad * self.n_pad, 0);
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
                    for ((o, &e), &d) in out.chunks_exact_mut(2).zip(even).zip(odd) {
                        o[0] = super::bf16::from_f32_finite(e);
                        o[1] = super::bf16::from_f32_finite(d);
                    }
                } else {
                    for (o, &e) in out.chunks_exact_mut(2).zip(even) {
                        o[0] = super::bf16::from_f32_finite(e);
                    }
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

/// `dst = a · b`, or `dst += a · b` when `accumulate`, in bf16 with f32 accumulation, on the calling
/// thread. `d` must be row-major (`col_stride` 1) with `a.rows` rows and `b`'s N columns, and
/// `a`'s K must be `b`'s padded K.
///
/// # Panics
/// If the shapes disagree, a view leaves its slice or the destination
/// view is not row-major (checked first, on any machine), or AMX is not [`available`]:
/// programming errors of the caller, never data-dependent.
pub fn matmul(dst: &mut [f32], d: View, accumulate: bool, a: &[u16], av: AView, b: &PackedB) {
    assert!(d.col_stride == 1 && d.row_stride >= d.cols, "amx::matmul: destination {d:?} is not row-major");
    assert!(d.rows == av.rows && d.cols == b.n && av.k() == b.k_pad, "amx::matmul shapes: {d:?} = {av:?} · {}×{}", b.k_pad, b.n);
    assert!(av.seg_len.is_multiple_of(K_STEP), "amx::matmul: segment of {} values is not a multiple of {K_STEP}", av.seg_len);
    assert!(av.end().is_some_and(|end| end <= a.len()), "amx::matmul: left view {av:?} leaves a slice of {}", a.len());
    let d_end = if d.rows == 0 || d.cols == 0 {
        Some(d.offset)
    } else {
        (d.rows - 1).checked_mul(d.row_stride).and_then(|r| r.checked_add(d.offset + d.cols))
    };
    assert!(d_end.is_some_and(|end| end <= dst.len()), "amx::matmul: destination view {d:?} leaves a slice of {}", dst.len());
    assert!(b.data.len() == b.k_pad * b.n_pad, "amx::matmul: a PackedB of {} values for {}×{}", b.data.len(), b.k_pad, b.n_pad);
    if let Err(why) = available() {
        panic!("amx::matmul without AMX: {why}");
    }
    if d.rows == 0 || d.cols == 0 {
        return;
    }
    if b.k_pad == 0 {
        if !accumulate {
            for i in 0..d.rows {
                dst[d.offset + i * d.row_stride..][..d.cols].fill(0.0);
            }
        }
        return;
    }
    let seg_chunks = av.seg_len / K_STEP;
    let mut config = TileConfig::default();
    let mut loaded = None;
    let mut first = true;
    // K in blocks of at most K_BLOCK steps, each swept over the whole output: a block's B panel
    // (K_BLOCK·32 × N bf16: 24 KiB for N = 64) and one row strip pair of A (12 KiB) stay in L1
    // while the output's tiles are loaded and stored around them.
    for seg in 0..av.segments {
        for c0 in (0..seg_chunks).step_by(K_BLOCK) {
            let chunks = (seg_chunks - c0).min(K_BLOCK);
            let a_k = av.offset + seg * av.seg_stride + c0 * K_STEP;
            let b_k = (seg * av.seg_len + c0 * K_STEP) / 2 * 2 * b.n_pad;
            let acc = accumulate || !first;
            first = false;
            for i0 in (0..d.rows).step_by(2 * TILE) {
                let mr0 = (d.rows - i0).min(TILE);
                let mr1 = (d.rows - i0 - mr0).min(TILE);
                for j0 in (0..d.cols).step_by(2 * TILE) {
                    let nr0 = (d.cols - j0).min(TILE);
                    let nr1 = (d.cols - j0 - nr0).min(TILE);
                    let shape = (mr0, mr1, nr0, nr1);
                    if loaded != Some(shape) {
                        config.set(shape);
                        // SAFETY: AMX is available (checked above); the configuration is
                        // well-formed (palette 1, at most 16 rows and 64 bytes per tile).
                        unsafe { load_config(&config) };
                        loaded = Some(shape);
                    }
                    let block = Block {
                        // The second strips repeat the first where the block has only one:
                        // their results are then computed and dropped, and nothing outside the
                        // views is read.
                        a0: a_k + i0 * av.row_stride,
                        a1: a_k + (i0 + if mr1 > 0 { TILE } else { 0 }) * av.row_stride,
                        b0: b_k + j0 * 2,
                        b1: b_k + (j0 + if nr1 > 0 { TILE } else { 0 }) * 2,
                        c: d.offset + i0 * d.row_stride + j0,
                        c_second_rows: d.offset + (i0 + TILE) * d.row_stride + j0,
                        tiles: (mr1 > 0, nr1 > 0),
                    };
                    // SAFETY: every tile row the kernel reads lies inside the views checked
                    // above: A rows i0..i0 + mr (< av.rows), this block's K steps of one
                    // segment; B's rows of those K steps, columns j0..j0 + nr (< n_pad); C rows
                    // and columns inside `d`. Tiles are configured to those sizes.
                    unsafe { block.run(dst, d.row_stride, acc, a, av.row_stride, chunks, b) };
                }
            }
        }
    }
    // SAFETY: AMX is available; releasing the tiles only drops their state.
    unsafe { release() };
}

/// A tile configuration (palette 1): per tile, rows and bytes per row.
#[repr(C, align(64))]
#[derive(Debug, Clone, Copy)]
struct TileConfig([u8; 64]);

impl Default for TileConfig {
    fn default() -> Self {
        let mut c = [0u8; 64];
        c[0] = 1;
        Self(c)
    }
}

impl TileConfig {
    /// Tiles for a block of `mr0 + mr1` rows and `nr0 + nr1` columns (a zero repeats the first).
    fn set(&mut self, (mr0, mr1, nr0, nr1): (usize, usize, usize, usize)) {
        let (mr1, nr1) = (if mr1 == 0 { mr0 } else { mr1 }, if nr1 == 0 { nr0 } else { nr1 });
        // tmm0..3: C (rows × 4·cols bytes); tmm4..5: A strips (rows × 64 bytes); tmm6..7: B strips
        // (16 pair-rows × 4·cols bytes).
        let tiles = [(mr0, 4 * nr0), (mr0, 4 * nr1), (mr1, 4 * nr0), (mr1, 4 * nr1), (mr0, 64), (mr1, 64), (16, 4 * nr0), (16, 4 * nr1)];
        for (t, (rows, bytes)) in tiles.into_iter().enumerate() {
            let bytes = u16::try_from(bytes).expect("tile row of at most 64 bytes");
            self.0[16 + 2 * t..18 + 2 * t].copy_from_slice(&bytes.to_le_bytes());
            self.0[48 + t] = u8::try_from(rows).expect("tile of at most 16 rows");
        }
    }
}

/// One 32 × 32 (or smaller) block of the output: element offsets of its strips.
struct Block {
    a0: usize,
    a1: usize,
    b0: usize,
    b1: usize,
    c: usize,
    c_second_rows: usize,
    /// Whether the block has second row and column strips.
    tiles: (bool, bool),
}

#[cfg(target_arch = "x86_64")]
unsafe fn load_config(config: &TileConfig) {
    // SAFETY: the caller checked AMX; `config` is 64 aligned bytes.
    unsafe { std::arch::asm!("ldtilecfg [{}]", in(reg) config.0.as_ptr(), options(nostack, readonly)) };
}

#[cfg(target_arch = "x86_64")]
unsafe fn release() {
    // SAFETY: the caller checked AMX.
    unsafe { std::arch::asm!("tilerelease", options(nostack, nomem)) };
}

impl Block {
    /// Runs the block's K loop. The tiles persist between the three `asm!` blocks (no code the
    /// compiler emits touches them).
    #[cfg(target_arch = "x86_64")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn run(&self, dst: &mut [f32], ldc: usize, accumulate: bool, a: &[u16], a_row_stride: usize, chunks: usize, b: &PackedB) {
        use std::arch::asm;
        let ldc_bytes = ldc * 4;
        let c0 = dst.as_mut_ptr().wrapping_add(self.c);
        let c1 = dst.as_mut_ptr().wrapping_add(self.c_second_rows);
        let (rows2, cols2) = self.tiles;
        // SAFETY (all blocks): the caller checked every address against the views and configured
        // the tiles to the block's size.
        unsafe {
            if accumulate {
                asm!("tileloadd tmm0, [{c} + {ldc}*1]", c = in(reg) c0, ldc = in(reg) ldc_bytes, options(nostack, readonly));
                if cols2 {
                    asm!("tileloadd tmm1, [{c} + {ldc}*1 + 64]", c = in(reg) c0, ldc = in(reg) ldc_bytes, options(nostack, readonly));
                } else {
                    asm!("tilezero tmm1", options(nostack, nomem));
                }
                if rows2 {
                    asm!("tileloadd tmm2, [{c} + {ldc}*1]", c = in(reg) c1, ldc = in(reg) ldc_bytes, options(nostack, readonly));
                } else {
                    asm!("tilezero tmm2", options(nostack, nomem));
                }
                if rows2 && cols2 {
                    asm!("tileloadd tmm3, [{c} + {ldc}*1 + 64]", c = in(reg) c1, ldc = in(reg) ldc_bytes, options(nostack, readonly));
                } else {
                    asm!("tilezero tmm3", options(nostack, nomem));
                }
            } else {
                asm!("tilezero tmm0", "tilezero tmm1", "tilezero tmm2", "tilezero tmm3", options(nostack, nomem));
            }
            let lda = a_row_stride * 2;
            let ldb = b.n_pad * 4;
            asm!(
                "2:",
                "tileloadd tmm4, [{a0} + {lda}*1]",
                "tileloadd tmm6, [{b0} + {ldb}*1]",
                "tileloadd tmm7, [{b1} + {ldb}*1]",
                "tdpbf16ps tmm0, tmm4, tmm6",
                "tdpbf16ps tmm1, tmm4, tmm7",
                "tileloadd tmm5, [{a1} + {lda}*1]",
                "tdpbf16ps tmm2, tmm5, tmm6",
                "tdpbf16ps tmm3, tmm5, tmm7",
                "add {a0}, 64",
                "add {a1}, 64",
                "add {b0}, {bstep}",
                "add {b1}, {bstep}",
                "dec {kk}",
                "jnz 2b",
                a0 = inout(reg) a.as_ptr().wrapping_add(self.a0) => _,
                a1 = inout(reg) a.as_ptr().wrapping_add(self.a1) => _,
                b0 = inout(reg) b.data.as_ptr().wrapping_add(self.b0) => _,
                b1 = inout(reg) b.data.as_ptr().wrapping_add(self.b1) => _,
                lda = in(reg) lda,
                ldb = in(reg) ldb,
                bstep = in(reg) 16 * ldb,
                kk = inout(reg) chunks => _,
                options(nostack, readonly)
            );
            asm!("tilestored [{c} + {ldc}*1], tmm0", c = in(reg) c0, ldc = in(reg) ldc_bytes, options(nostack));
            if cols2 {
                asm!("tilestored [{c} + {ldc}*1 + 64], tmm1", c = in(reg) c0, ldc = in(reg) ldc_bytes, options(nostack));
            }
            if rows2 {
                asm!("tilestored [{c} + {ldc}*1], tmm2", c = in(reg) c1, ldc = in(reg) ldc_bytes, options(nostack));
            }
            if rows2 && cols2 {
                asm!("tilestored [{c} + {ldc}*1 + 64], tmm3", c = in(reg) c1, ldc = in(reg) ldc_bytes, options(nostack));
            }
        }
    }

    #[cfg(not(target_arch = "x86_64"))]
    #[allow(clippy::too_many_arguments)]
    unsafe fn run(&self, _: &mut [f32], _: usize, _: bool, _: &[u16], _: usize, _: usize, _: &PackedB) {
        unreachable!("AMX is never available off x86_64")
    }
}

#[cfg(not(target_arch = "x86_64"))]
unsafe fn load_config(_: &TileConfig) {}

#[cfg(not(target_arch = "x86_64"))]
unsafe fn release() {}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::bf16;
    use super::*;

    /// Whether to run an AMX test here; says so when not (a skip is never silent).
    pub(crate) fn amx_or_skip(test: &str) -> bool {
        match available() {
            Ok(()) => true,
            Err(why) => {
                eprintln!("SKIPPED {test}: no AMX here ({why}); the f32 path is tested instead");
                false
            }
        }
    }

    fn values(n: usize, seed: f32) -> Vec<f32> {
        (0..n).map(|i| ((i as f32 + seed) * 0.618).sin() * 2.0).collect()
    }

    /// The product in f64 of the bf16-rounded inputs: what the kernel must give up to f32
    /// accumulation error.
    fn reference(a: &[u16], av: AView, b: &[f32], bv: View) -> Vec<f64> {
        let mut out = vec![0f64; av.rows * bv.cols];
        for i in 0..av.rows {
            for j in 0..bv.cols {
                let mut s = 0f64;
                for k in 0..bv.rows {
                    let ak = av.offset + i * av.row_stride + (k / av.seg_len) * av.seg_stride + k % av.seg_len;
                    let bk = bf16::to_f32(bf16::from_f32(b[bv.offset + k * bv.row_stride + j * bv.col_stride]));
                    s += f64::from(bf16::to_f32(a[ak])) * f64::from(bk);
                }
                out[i * bv.cols + j] = s;
            }
        }
        out
    }

    #[test]
    fn every_block_shape_multiplies_like_the_definition() {
        if !amx_or_skip("every_block_shape_multiplies_like_the_definition") {
            return;
        }
        // Rows and columns that exercise full 32 × 32 blocks, single strips and partial tiles;
        // segmented, overlapping rows of A as a convolution reads them.
        for (m, n, segments, seg_len, row_stride, seg_stride) in
            [(1, 1, 1, 32, 32, 0), (16, 16, 1, 64, 64, 0), (45, 70, 3, 64, 7, 100), (100, 64, 3, 192, 64, 64 * 44), (33, 17, 2, 32, 40, 33)]
        {
            let k = segments * seg_len;
            let av = AView { offset: 5, rows: m, row_stride, segments, seg_len, seg_stride };
            let a_f32 = values(av.end().unwrap(), 0.5);
            let mut a = vec![0u16; a_f32.len()];
            bf16::convert(&a_f32, &mut a);
            let b = values(k * n * 2, 1.5);
            let bv = View { offset: 3, rows: k, cols: n, row_stride: 1, col_stride: k + 1 };
            let mut packed = PackedB::default();
            packed.pack(&b, bv);
            let expected = reference(&a, av, &b, bv);
            let ld = n + 3;
            let mut out = vec![f32::NAN; m * ld];
            matmul(&mut out, View::rows(0, m, n, ld), false, &a, av, &packed);
            for acc in [false, true] {
                if acc {
                    matmul(&mut out, View::rows(0, m, n, ld), true, &a, av, &packed);
                }
                let scale = if acc { 2.0 } else { 1.0 };
                for i in 0..m {
                    for j in 0..n {
                        let (x, e) = (f64::from(out[i * ld + j]), scale * expected[i * n + j]);
                        assert!((x - e).abs() <= 1e-5 * (k as f64) * 4.0, "{m}×{n}×{k} ({i}, {j}): {x} vs {e}");
                    }
                    // Nothing outside the destination view is written.
                    for j in n..ld {
                        assert!(out[i * ld + j].is_nan(), "{m}×{n}: column {j} of row {i} written");
                    }
                }
            }
        }
    }

    #[test]
    #[should_panic(expected = "leaves a slice")]
    fn a_left_view_past_the_end_is_refused() {
        let a = vec![0u16; 100];
        let mut packed = PackedB::default();
        packed.pack(&[0.0; 64], View::rows(0, 32, 2, 2));
        let mut out = vec![0f32; 8];
        matmul(&mut out, View::rows(0, 4, 2, 2), false, &a, AView::rows(0, 4, 32, 30), &packed);
    }
}
