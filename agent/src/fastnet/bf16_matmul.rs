//! A bf16 matrix multiply with f32 accumulation, behind a bounds-checked safe interface: the
//! layouts the bf16 path keeps its operands in, and the choice between the machine's two kernels
//! for it, Intel's AMX tiles (`amx`, `tdpbf16ps`) and AVX512-BF16's `vdpbf16ps` (`avx512_bf16`,
//! AMD Zen 4 and later Xeons). Both multiply the same layouts in the same K blocks; where a CPU has
//! both, AMX runs (16× the products per instruction).
//!
//! Layouts (`bf16` values are `u16` bit patterns, see `fastnet::bf16`):
//! - the left matrix is read in place through an [`AView`]: rows at a stride, each row's K values
//!   in `segments` runs of `seg_len` (a multiple of 32) consecutive values, `seg_stride` apart. A
//!   convolution reads its padded image this way (a run per kernel row), with no packing;
//! - the right matrix is a [`PackedB`]: K padded to a multiple of 32 with zeros, N to a multiple
//!   of 16, and rows taken in pairs (`[k / 2][n][k % 2]`), the layout both instructions multiply by.

use std::sync::OnceLock;

use super::gemm::View;
use super::{amx, avx512_bf16};

/// Values of K one step of either kernel consumes (64 bytes of bf16: one AMX tile row).
pub const K_STEP: usize = 32;
/// Columns of the right matrix one step covers (one AMX tile, one zmm register of f32).
const N_STEP: usize = 16;

/// The instruction set a bf16 product runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kernel {
    /// Intel AMX tiles (`tdpbf16ps`).
    Amx,
    /// AVX512-BF16 (`vdpbf16ps` on zmm registers).
    Avx512Bf16,
}

impl Kernel {
    /// How logs and JSON name it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Amx => "AMX-BF16",
            Self::Avx512Bf16 => "AVX512-BF16",
        }
    }

    /// Its spelling in [`KERNEL_ENV`].
    #[must_use]
    pub fn env_name(self) -> &'static str {
        match self {
            Self::Amx => "amx",
            Self::Avx512Bf16 => "avx512-bf16",
        }
    }
}

/// The environment variable that narrows the choice to one kernel (`amx` or `avx512-bf16`), for
/// measuring and testing the other kernel on a machine that has both, as oneDNN's
/// `ONEDNN_MAX_CPU_ISA` does; unset, the fastest kernel present runs.
pub const KERNEL_ENV: &str = "FASTNET_BF16_KERNEL";

/// The kernel this process runs bf16 products on: AMX where the CPU has it and the OS grants the
/// tile state, else AVX512-BF16 where present (or the one [`KERNEL_ENV`] names); else why none
/// can run (for the log line that says which path runs). Checked once per process.
pub fn available() -> Result<Kernel, &'static str> {
    static STATE: OnceLock<Result<Kernel, String>> = OnceLock::new();
    STATE.get_or_init(|| choose(std::env::var(KERNEL_ENV).ok().as_deref())).as_ref().copied().map_err(String::as_str)
}

/// The kernel for a [`KERNEL_ENV`] value (`None`: unset).
fn choose(asked: Option<&str>) -> Result<Kernel, String> {
    let named = |kernel: Kernel, runs: Result<(), &'static str>| {
        runs.map(|()| kernel).map_err(|why| format!("{KERNEL_ENV}={} asked for, and {why}", kernel.env_name()))
    };
    match asked {
        None | Some("") => match (amx::available(), avx512_bf16::available()) {
            (Ok(()), _) => Ok(Kernel::Amx),
            (Err(_), Ok(())) => Ok(Kernel::Avx512Bf16),
            (Err(no_amx), Err(no_avx)) => Err(format!("{no_amx} and {no_avx}")),
        },
        Some("amx") => named(Kernel::Amx, amx::available()),
        Some("avx512-bf16") => named(Kernel::Avx512Bf16, avx512_bf16::available()),
        Some(other) => Err(format!("{KERNEL_ENV}={other:?} is not a kernel (valid: amx, avx512-bf16, or unset)")),
    }
}

/// Every kernel this machine can run (the tests check each, not only the one [`available`] picks).
#[must_use]
pub fn kernels_here() -> Vec<Kernel> {
    let mut k = Vec::new();
    if amx::available().is_ok() {
        k.push(Kernel::Amx);
    }
    if avx512_bf16::available().is_ok() {
        k.push(Kernel::Avx512Bf16);
    }
    k
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
        self.n_pad = n.div_ceil(N_STEP) * N_STEP;
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

/// `dst = a · b`, or `dst += a · b` when `accumulate`, in bf16 with f32 accumulation, on the
/// calling thread, on the machine's kernel ([`available`]). `d` must be row-major (`col_stride` 1) with
/// `a.rows` rows and `b`'s N columns, and `a`'s K must be `b`'s padded K.
///
/// # Panics
/// If the shapes disagree, a view leaves its slice or the destination view is not row-major
/// (checked first, on any machine), or no bf16 kernel is [`available`]: programming errors of the
/// caller, never data-dependent.
pub fn matmul(dst: &mut [f32], d: View, accumulate: bool, a: &[u16], av: AView, b: &PackedB) {
    check(dst, d, a, av, b);
    let kernel = available().unwrap_or_else(|why| panic!("bf16_matmul::matmul without a bf16 kernel: {why}"));
    // SAFETY: the kernel runs here (checked just above) and the operands passed `check`.
    #[allow(unsafe_code)]
    unsafe {
        run(kernel, dst, d, accumulate, a, av, b);
    }
}

/// [`matmul`] on a kernel of [`kernels_here`].
///
/// # Panics
/// As [`matmul`], or if `kernel` cannot run here.
pub fn matmul_on(kernel: Kernel, dst: &mut [f32], d: View, accumulate: bool, a: &[u16], av: AView, b: &PackedB) {
    check(dst, d, a, av, b);
    let runs = match kernel {
        Kernel::Amx => amx::available(),
        Kernel::Avx512Bf16 => avx512_bf16::available(),
    };
    if let Err(why) = runs {
        panic!("bf16_matmul::matmul on {}: {why}", kernel.name());
    }
    // SAFETY: the kernel runs here (checked just above) and the operands passed `check`.
    #[allow(unsafe_code)]
    unsafe {
        run(kernel, dst, d, accumulate, a, av, b);
    }
}

/// The checks that make [`run`] safe: shapes that agree, views inside their slices, a row-major
/// destination.
fn check(dst: &[f32], d: View, a: &[u16], av: AView, b: &PackedB) {
    assert!(d.col_stride == 1 && d.row_stride >= d.cols, "bf16_matmul::matmul: destination {d:?} is not row-major");
    assert!(d.rows == av.rows && d.cols == b.n && av.k() == b.k_pad, "bf16_matmul::matmul shapes: {d:?} = {av:?} · {}×{}", b.k_pad, b.n);
    assert!(av.seg_len.is_multiple_of(K_STEP), "bf16_matmul::matmul: segment of {} values is not a multiple of {K_STEP}", av.seg_len);
    assert!(av.end().is_some_and(|end| end <= a.len()), "bf16_matmul::matmul: left view {av:?} leaves a slice of {}", a.len());
    let d_end = if d.rows == 0 || d.cols == 0 {
        Some(d.offset)
    } else {
        (d.rows - 1).checked_mul(d.row_stride).and_then(|r| r.checked_add(d.offset + d.cols))
    };
    assert!(d_end.is_some_and(|end| end <= dst.len()), "bf16_matmul::matmul: destination view {d:?} leaves a slice of {}", dst.len());
    assert!(b.data.len() == b.k_pad * b.n_pad, "bf16_matmul::matmul: a PackedB of {} values for {}×{}", b.data.len(), b.k_pad, b.n_pad);
}

/// The product on `kernel` of checked operands.
///
/// # Safety
/// `kernel` runs here, and the operands passed [`check`].
#[allow(unsafe_code)]
unsafe fn run(kernel: Kernel, dst: &mut [f32], d: View, accumulate: bool, a: &[u16], av: AView, b: &PackedB) {
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
    // SAFETY: the caller's contract, and rows, columns and K steps are non-zero (above).
    unsafe {
        match kernel {
            Kernel::Amx => amx::matmul_unchecked(dst, d, accumulate, a, av, b),
            Kernel::Avx512Bf16 => avx512_bf16::matmul_unchecked(dst, d, accumulate, a, av, b),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::bf16;
    use super::*;

    /// Whether to run a bf16 test here; says so when not (a skip is never silent).
    pub(crate) fn bf16_or_skip(test: &str) -> bool {
        match available() {
            Ok(_) => true,
            Err(why) => {
                eprintln!("SKIPPED {test}: no bf16 kernel here ({why}); the f32 path is tested instead");
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
        if !bf16_or_skip("every_block_shape_multiplies_like_the_definition") {
            return;
        }
        // Rows and columns that exercise full 32 × 32 tile blocks, single strips and partial tiles,
        // the AVX-512 kernel's 6-row and 64-column blocks and their remainders, a segment longer
        // than one K block; segmented, overlapping rows of A as a convolution reads them.
        let shapes = [
            (1, 1, 1, 32, 32, 0),
            (16, 16, 1, 64, 64, 0),
            (45, 70, 3, 64, 7, 100),
            (100, 64, 3, 192, 64, 64 * 44),
            (33, 17, 2, 32, 40, 33),
            (13, 80, 1, 288, 300, 0),
            (7, 33, 3, 96, 5, 400),
        ];
        for kernel in kernels_here() {
            for (m, n, segments, seg_len, row_stride, seg_stride) in shapes {
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
                matmul_on(kernel, &mut out, View::rows(0, m, n, ld), false, &a, av, &packed);
                for acc in [false, true] {
                    if acc {
                        matmul_on(kernel, &mut out, View::rows(0, m, n, ld), true, &a, av, &packed);
                    }
                    let scale = if acc { 2.0 } else { 1.0 };
                    for i in 0..m {
                        for j in 0..n {
                            let (x, e) = (f64::from(out[i * ld + j]), scale * expected[i * n + j]);
                            assert!((x - e).abs() <= 1e-5 * (k as f64) * 4.0, "{kernel:?} {m}×{n}×{k} ({i}, {j}): {x} vs {e}");
                        }
                        // Nothing outside the destination view is written.
                        for j in n..ld {
                            assert!(out[i * ld + j].is_nan(), "{kernel:?} {m}×{n}: column {j} of row {i} written");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn the_environment_narrows_the_choice_and_names_a_bad_value() {
        assert_eq!(choose(None), choose(Some("")));
        let bad = choose(Some("avx2")).unwrap_err();
        assert!(bad.contains("\"avx2\"") && bad.contains("valid: amx, avx512-bf16"), "{bad}");
        for (name, kernel, runs) in [("amx", Kernel::Amx, amx::available()), ("avx512-bf16", Kernel::Avx512Bf16, avx512_bf16::available())]
        {
            match (choose(Some(name)), runs) {
                (Ok(k), Ok(())) => assert_eq!(k, kernel),
                (Err(why), Err(no)) => assert!(why.contains(name) && why.contains(no), "{why}"),
                (got, runs) => panic!("{name}: chose {got:?} where the kernel's check says {runs:?}"),
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
