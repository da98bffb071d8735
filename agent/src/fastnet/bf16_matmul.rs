//! A bf16 matrix multiply with f32 accumulation, behind a bounds-checked safe interface, and the
//! choice between the machine's two kernels for it, Intel's AMX tiles (`amx`, `tdpbf16ps`) and
//! AVX512-BF16's `vdpbf16ps` (`avx512_bf16`, Xeons without AMX and AMD Zen 4). Both multiply the
//! same layouts (`bf16_layout`, re-exported here) in the same K blocks; where a CPU has both, AMX
//! runs (16× the products per instruction).

use std::sync::OnceLock;

pub use super::bf16_layout::{AView, K_STEP, PackedB};
use super::gemm::View;
use super::{amx, avx512_bf16};

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

    /// Whether this process may run it, else why not.
    ///
    /// # Errors
    /// The reason the CPU or the OS rules it out.
    pub fn runs_here(self) -> Result<(), &'static str> {
        match self {
            Self::Amx => amx::available(),
            Self::Avx512Bf16 => avx512_bf16::available(),
        }
    }
}

/// Every kernel, fastest first (AMX has 16× the products per instruction).
const KERNELS: [Kernel; 2] = [Kernel::Amx, Kernel::Avx512Bf16];

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
    match asked {
        None | Some("") => KERNELS.into_iter().find(|k| k.runs_here().is_ok()).ok_or_else(|| {
            let why: Vec<&str> = KERNELS.iter().filter_map(|k| k.runs_here().err()).collect();
            why.join(" and ")
        }),
        Some(name) => {
            let Some(kernel) = KERNELS.into_iter().find(|k| k.env_name() == name) else {
                return Err(format!("{KERNEL_ENV}={name:?} is not a kernel (valid: amx, avx512-bf16, or unset)"));
            };
            kernel.runs_here().map(|()| kernel).map_err(|why| format!("{KERNEL_ENV}={name} asked for, and {why}"))
        }
    }
}

/// Every kernel this machine can run (the tests check each, not only the one [`available`] picks).
#[must_use]
pub fn kernels_here() -> Vec<Kernel> {
    KERNELS.into_iter().filter(|k| k.runs_here().is_ok()).collect()
}

/// Why [`Product::new`] refused a bf16 product's operands: a programming error of the caller,
/// never data-dependent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum OperandError {
    #[error("destination {0:?} is not row-major")]
    NotRowMajor(View),
    #[error("shapes: {d:?} = {av:?} · {k_pad}×{n}")]
    Shapes { d: View, av: AView, k_pad: usize, n: usize },
    #[error("segment of {0} values is not a multiple of {K_STEP}")]
    Segment(usize),
    #[error("left view {view:?} leaves a slice of {len}")]
    LeftOutside { view: AView, len: usize },
    #[error("destination view {view:?} leaves a slice of {len}")]
    DestinationOutside { view: View, len: usize },
    #[error("a PackedB of {len} values for {k_pad}×{n_pad}")]
    Packed { len: usize, k_pad: usize, n_pad: usize },
}

/// `dst = a · b` in bf16 with f32 accumulation, its operands checked once by the checked
/// constructor: shapes that agree, views inside slices of the lengths it is told, a row-major
/// destination. [`Product::run_on`] then needs only slices that long and the same `b`'s shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Product {
    d: View,
    av: AView,
    /// The lengths of the destination and left slices the views were checked against.
    lens: [usize; 2],
    /// `b`'s K (padded), N and padded N.
    b: [usize; 3],
}

impl Product {
    /// The product of view `av` of a slice of `a_len` and `b` into view `d` of a slice of
    /// `dst_len`. `d` must be row-major (`col_stride` 1) with `av.rows` rows and `b`'s N columns,
    /// and `av`'s K must be `b`'s padded K.
    ///
    /// # Errors
    /// Which of those does not hold, or a `b` whose data does not match its shape.
    pub fn new(dst_len: usize, d: View, a_len: usize, av: AView, b: &PackedB) -> Result<Self, OperandError> {
        if !(d.col_stride == 1 && d.row_stride >= d.cols) {
            return Err(OperandError::NotRowMajor(d));
        }
        if !(d.rows == av.rows && d.cols == b.n && av.k() == b.k_pad) {
            return Err(OperandError::Shapes { d, av, k_pad: b.k_pad, n: b.n });
        }
        if !av.seg_len.is_multiple_of(K_STEP) {
            return Err(OperandError::Segment(av.seg_len));
        }
        if av.end().is_none_or(|end| end > a_len) {
            return Err(OperandError::LeftOutside { view: av, len: a_len });
        }
        let d_end = if d.rows == 0 || d.cols == 0 {
            Some(d.offset)
        } else {
            (d.rows - 1).checked_mul(d.row_stride).and_then(|r| r.checked_add(d.offset + d.cols))
        };
        if d_end.is_none_or(|end| end > dst_len) {
            return Err(OperandError::DestinationOutside { view: d, len: dst_len });
        }
        if b.data.len() != b.k_pad * b.n_pad {
            return Err(OperandError::Packed { len: b.data.len(), k_pad: b.k_pad, n_pad: b.n_pad });
        }
        Ok(Self { d, av, lens: [dst_len, a_len], b: [b.k_pad, b.n, b.n_pad] })
    }

    /// `dst = a · b`, or `dst += a · b` when `accumulate`, on the calling thread, on `kernel`.
    ///
    /// # Panics
    /// If `kernel` cannot run here, a slice is shorter than the constructor was told, or `b`'s
    /// shape is not the one it was told.
    pub fn run_on(&self, kernel: Kernel, dst: &mut [f32], accumulate: bool, a: &[u16], b: &PackedB) {
        assert!(
            dst.len() >= self.lens[0] && a.len() >= self.lens[1] && [b.k_pad, b.n, b.n_pad] == self.b && b.data.len() == b.k_pad * b.n_pad,
            "bf16_matmul::Product::run_on: operands other than the ones checked ({self:?})"
        );
        if let Err(why) = kernel.runs_here() {
            panic!("bf16_matmul::matmul on {}: {why}", kernel.name());
        }
        // SAFETY: the kernel runs here and the operands are those `new` checked (both just above).
        #[allow(unsafe_code)]
        unsafe {
            run(kernel, dst, self.d, accumulate, a, self.av, b);
        }
    }
}

/// `dst = a · b`, or `dst += a · b` when `accumulate`, in bf16 with f32 accumulation, on the
/// calling thread, on the machine's kernel ([`available`]): a [`Product`] made and run at once.
///
/// # Panics
/// If the operands are refused ([`Product::new`]'s [`OperandError`]s, checked first, on any
/// machine), or no bf16 kernel is [`available`]: programming errors of the caller, never
/// data-dependent.
pub fn matmul(dst: &mut [f32], d: View, accumulate: bool, a: &[u16], av: AView, b: &PackedB) {
    let product = Product::new(dst.len(), d, a.len(), av, b).unwrap_or_else(|e| panic!("bf16_matmul::matmul: {e}"));
    let kernel = available().unwrap_or_else(|why| panic!("bf16_matmul::matmul without a bf16 kernel: {why}"));
    product.run_on(kernel, dst, accumulate, a, b);
}

/// [`matmul`] on a kernel of [`kernels_here`].
///
/// # Panics
/// As [`matmul`], or if `kernel` cannot run here.
pub fn matmul_on(kernel: Kernel, dst: &mut [f32], d: View, accumulate: bool, a: &[u16], av: AView, b: &PackedB) {
    let product = Product::new(dst.len(), d, a.len(), av, b).unwrap_or_else(|e| panic!("bf16_matmul::matmul: {e}"));
    product.run_on(kernel, dst, accumulate, a, b);
}

/// The product on `kernel` of checked operands.
///
/// # Safety
/// `kernel` runs here, and the operands passed [`Product::new`]'s checks.
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
    fn a_left_view_past_the_end_is_refused() {
        let mut packed = PackedB::default();
        packed.pack(&[0.0; 64], View::rows(0, 32, 2, 2));
        let av = AView::rows(0, 4, 32, 30);
        let refused = Product::new(8, View::rows(0, 4, 2, 2), 100, av, &packed);
        assert_eq!(refused, Err(OperandError::LeftOutside { view: av, len: 100 }));
        assert!(refused.unwrap_err().to_string().contains("leaves a slice of 100"));
        // And a destination that is not row-major, or too short.
        let cols = View { col_stride: 2, ..View::rows(0, 4, 2, 4) };
        assert_eq!(Product::new(64, cols, 200, av, &packed), Err(OperandError::NotRowMajor(cols)));
        let d = View::rows(0, 4, 2, 2);
        assert_eq!(Product::new(7, d, 200, av, &packed), Err(OperandError::DestinationOutside { view: d, len: 7 }));
        assert!(Product::new(8, d, 200, av, &packed).is_ok());
    }
}
