//! The first layer's 3×3 convolution computed directly, fused with bias, ReLU and 2×2 pooling,
//! forward and backward. With 1–3 input channels its K = 9·C is a poor GEMM (packing and edge
//! handling cost more than the 9 products), and its 64-channel output at full resolution is the
//! network's largest array: the GEMM path wrote it, read it to pool, kept it for the backward
//! pass and wrote and read a padded gradient of the same size. Here each output pixel's channels
//! are computed in registers, 16 at a time, and pooled at once; the backward pass computes them
//! again (9 products per channel) to know the ReLU's mask, instead of keeping them.
//!
//! The kernel is laid out in groups of 16 output channels (`[group][tap][16]`, the last group
//! padded with zeros). Each product is a fused multiply-add (`mul_add`), so the bits are the
//! same on every machine: the AVX-512 and AVX2 builds of the same code only differ in width.

#![allow(unsafe_code)]

use std::sync::OnceLock;

use super::conv::ConvGeom;
use super::pool::Strided;

/// Output channels computed together (one AVX-512 register).
const LANES: usize = 16;
type Lanes = [f32; LANES];

/// Whether a layer of this geometry runs here: the first layer (few channels, so that its
/// patches are worth gathering for the GEMM path; see [`ConvGeom::gathers`]).
#[must_use]
pub fn fits(g: &ConvGeom) -> bool {
    g.gathers()
}

/// The k-major kernel (`(ky, kx, c) × cout`, `conv::kernel_k_major`) in groups of [`LANES`]
/// output channels.
pub fn pack(k_major: &[f32], g: &ConvGeom, out: &mut Vec<f32>) {
    let (taps, groups) = (9 * g.cin, g.cout.div_ceil(LANES));
    assert_eq!(k_major.len(), taps * g.cout, "conv_direct::pack: a kernel of {} values for {g:?}", k_major.len());
    out.clear();
    out.resize(groups * taps * LANES, 0.0);
    for (t, row) in k_major.chunks_exact(g.cout).enumerate() {
        for (f, &v) in row.iter().enumerate() {
            out[((f / LANES) * taps + t) * LANES + f % LANES] = v;
        }
    }
}

/// The instruction set the kernels are compiled for, chosen once per process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Isa {
    Avx512,
    Avx2,
    Portable,
}

fn isa() -> Isa {
    static ISA: OnceLock<Isa> = OnceLock::new();
    *ISA.get_or_init(|| {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("fma") {
                return Isa::Avx512;
            }
            if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
                return Isa::Avx2;
            }
        }
        Isa::Portable
    })
}

/// Lines `y0..y1` (`y0` even) of one padded image (`padded_in` floats) convolved with the grouped
/// kernel ([`pack`]), `relu(· + bias)` and pooled into `dst`: pooled line `i` (of `y0 / 2..y1 / 2`)
/// at `to.at(i - y0 / 2, j)`, channel `f` `f·to.chan` further.
///
/// # Panics
/// If the slices do not match the geometry or `y0` is odd.
#[allow(clippy::too_many_arguments)]
pub fn forward_pool(input: &[f32], kernel: &[f32], bias: &[f32], g: &ConvGeom, (y0, y1): (usize, usize), dst: &mut [f32], to: Strided) {
    check(input, kernel, bias, g, (y0, y1));
    let args = Forward { input, kernel, bias, g, lines: (y0, y1), to };
    match isa() {
        // SAFETY: the CPU has the features these builds are compiled for (checked by `isa`).
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { args.run_avx512(dst) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { args.run_avx2(dst) },
        _ => args.run(dst),
    }
}

/// The backward pass of [`forward_pool`] over a whole image: from the gradient of the pooled
/// output (read through `from`, as [`forward_pool`] writes), adds the kernel gradient (k-major,
/// `9·cin × cout`) to `dk` and the bias gradient to `db`.
///
/// # Panics
/// If the slices do not match the geometry.
#[allow(clippy::too_many_arguments)]
pub fn backward(
    input: &[f32],
    kernel: &[f32],
    bias: &[f32],
    g: &ConvGeom,
    upstream: &[f32],
    from: Strided,
    dk: &mut [f32],
    db: &mut [f32],
) {
    check(input, kernel, bias, g, (0, g.h));
    assert!(dk.len() == 9 * g.cin * g.cout && db.len() == g.cout, "conv_direct::backward: gradients of {} and {}", dk.len(), db.len());
    let args = Backward { input, kernel, bias, g, upstream, from };
    match isa() {
        // SAFETY: as in `forward_pool`.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { args.run_avx512(dk, db) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { args.run_avx2(dk, db) },
        _ => args.run(dk, db),
    }
}

fn check(input: &[f32], kernel: &[f32], bias: &[f32], g: &ConvGeom, (y0, y1): (usize, usize)) {
    assert!(input.len() >= g.padded_in(), "conv_direct: an image of {} values for {g:?}", input.len());
    assert_eq!(kernel.len(), g.cout.div_ceil(LANES) * 9 * g.cin * LANES, "conv_direct: a grouped kernel for {g:?}");
    assert_eq!(bias.len(), g.cout, "conv_direct: a bias for {g:?}");
    assert!(y0.is_multiple_of(2) && y0 <= y1 && y1 <= g.h, "conv_direct: lines {y0}..{y1} of {}", g.h);
}

/// One group's 16 lanes of the bias (zeros past `cout`).
fn bias_lanes(bias: &[f32], group: usize) -> Lanes {
    let mut b = [0.0; LANES];
    for (d, &v) in b.iter_mut().zip(bias.iter().skip(group * LANES)) {
        *d = v;
    }
    b
}

/// 16 f32 lanes in one instruction set's registers: the operations the kernels are written in,
/// each lane computed exactly as [`Portable`] computes it (so every build gives the same bits).
trait Vector: Copy {
    fn splat(x: f32) -> Self;
    fn load(v: &Lanes) -> Self;
    fn store(self, out: &mut Lanes);
    /// `x·w + self`, fused (one rounding).
    fn fma(self, x: f32, w: Self) -> Self;
    fn add(self, other: Self) -> Self;
    fn mul(self, other: Self) -> Self;
    /// `self` where it is above zero, else +0 (NaN too).
    fn relu(self) -> Self;
    /// `self` where `by` is above zero, else +0.
    fn where_positive(self, by: Self) -> Self;
}

/// Plain lanes: what every build must equal.
#[derive(Clone, Copy)]
struct Portable(Lanes);

impl Vector for Portable {
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Self([x; LANES])
    }
    #[inline(always)]
    fn load(v: &Lanes) -> Self {
        Self(*v)
    }
    #[inline(always)]
    fn store(self, out: &mut Lanes) {
        *out = self.0;
    }
    #[inline(always)]
    fn fma(self, x: f32, w: Self) -> Self {
        Self(std::array::from_fn(|i| x.mul_add(w.0[i], self.0[i])))
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self(std::array::from_fn(|i| self.0[i] + o.0[i]))
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self(std::array::from_fn(|i| self.0[i] * o.0[i]))
    }
    #[inline(always)]
    fn relu(self) -> Self {
        Self(self.0.map(|v| if v > 0.0 { v } else { 0.0 }))
    }
    #[inline(always)]
    fn where_positive(self, by: Self) -> Self {
        Self(std::array::from_fn(|i| if by.0[i] > 0.0 { self.0[i] } else { 0.0 }))
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    //! [`Vector`] on AVX-512 (one register) and AVX2 (two). Their methods are called only from
    //! the `run_avx512` and `run_avx2` functions, which the dispatch enters only on a CPU with
    //! those features (the reason each `unsafe` below holds).
    use std::arch::x86_64::*;

    use super::{LANES, Lanes, Vector};

    #[derive(Clone, Copy)]
    pub(super) struct Avx512(__m512);

    impl Vector for Avx512 {
        #[inline(always)]
        fn splat(x: f32) -> Self {
            // SAFETY: see the module's comment.
            Self(unsafe { _mm512_set1_ps(x) })
        }
        #[inline(always)]
        fn load(v: &Lanes) -> Self {
            // SAFETY: 16 readable floats; see the module's comment.
            Self(unsafe { _mm512_loadu_ps(v.as_ptr()) })
        }
        #[inline(always)]
        fn store(self, out: &mut Lanes) {
            // SAFETY: 16 writable floats; see the module's comment.
            unsafe { _mm512_storeu_ps(out.as_mut_ptr(), self.0) }
        }
        #[inline(always)]
        fn fma(self, x: f32, w: Self) -> Self {
            // SAFETY: see the module's comment.
            Self(unsafe { _mm512_fmadd_ps(_mm512_set1_ps(x), w.0, self.0) })
        }
        #[inline(always)]
        fn add(self, o: Self) -> Self {
            // SAFETY: see the module's comment.
            Self(unsafe { _mm512_add_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn mul(self, o: Self) -> Self {
            // SAFETY: see the module's comment.
            Self(unsafe { _mm512_mul_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn relu(self) -> Self {
            // SAFETY: see the module's comment. Greater-than, ordered: NaN and ±0 give +0.
            Self(unsafe { _mm512_maskz_mov_ps(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(self.0, _mm512_setzero_ps()), self.0) })
        }
        #[inline(always)]
        fn where_positive(self, by: Self) -> Self {
            // SAFETY: see the module's comment.
            Self(unsafe { _mm512_maskz_mov_ps(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(by.0, _mm512_setzero_ps()), self.0) })
        }
    }

    #[derive(Clone, Copy)]
    pub(super) struct Avx2([__m256; 2]);

    impl Avx2 {
        #[inline(always)]
        fn each(self, o: Self, f: impl Fn(__m256, __m256) -> __m256) -> Self {
            Self([f(self.0[0], o.0[0]), f(self.0[1], o.0[1])])
        }
    }

    impl Vector for Avx2 {
        #[inline(always)]
        fn splat(x: f32) -> Self {
            // SAFETY: see the module's comment.
            let v = unsafe { _mm256_set1_ps(x) };
            Self([v, v])
        }
        #[inline(always)]
        fn load(v: &Lanes) -> Self {
            // SAFETY: 16 readable floats; see the module's comment.
            unsafe { Self([_mm256_loadu_ps(v.as_ptr()), _mm256_loadu_ps(v.as_ptr().add(LANES / 2))]) }
        }
        #[inline(always)]
        fn store(self, out: &mut Lanes) {
            // SAFETY: 16 writable floats; see the module's comment.
            unsafe {
                _mm256_storeu_ps(out.as_mut_ptr(), self.0[0]);
                _mm256_storeu_ps(out.as_mut_ptr().add(LANES / 2), self.0[1]);
            }
        }
        #[inline(always)]
        fn fma(self, x: f32, w: Self) -> Self {
            // SAFETY: see the module's comment.
            let x = unsafe { _mm256_set1_ps(x) };
            // SAFETY: as above.
            self.each(w, |a, w| unsafe { _mm256_fmadd_ps(x, w, a) })
        }
        #[inline(always)]
        fn add(self, o: Self) -> Self {
            // SAFETY: see the module's comment.
            self.each(o, |a, b| unsafe { _mm256_add_ps(a, b) })
        }
        #[inline(always)]
        fn mul(self, o: Self) -> Self {
            // SAFETY: see the module's comment.
            self.each(o, |a, b| unsafe { _mm256_mul_ps(a, b) })
        }
        #[inline(always)]
        fn relu(self) -> Self {
            self.where_positive(self)
        }
        #[inline(always)]
        fn where_positive(self, by: Self) -> Self {
            // SAFETY: see the module's comment. Greater-than, ordered: NaN and ±0 give +0.
            self.each(by, |v, b| unsafe { _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(b, _mm256_setzero_ps()), v) })
        }
    }
}

/// One group's kernel, a vector per tap.
#[inline(always)]
fn group_kernel<V: Vector, const TAPS: usize>(kernel: &[f32], group: usize) -> [V; TAPS] {
    let (rows, _) = kernel[group * TAPS * LANES..][..TAPS * LANES].as_chunks::<LANES>();
    std::array::from_fn(|t| V::load(&rows[t]))
}

/// The pre-activation (bias included) of one output pixel's group: the taps start at padded
/// pixel `p` (the output's top-left neighbour). `TAPS` = 9·C.
#[inline(always)]
fn pre_activation<V: Vector, const TAPS: usize>(input: &[f32], p: usize, pw: usize, w: &[V; TAPS], b: V) -> V {
    let c = TAPS / 9;
    let mut acc = b;
    for (ky, taps) in w.chunks_exact(3 * c).enumerate() {
        let xs = &input[(p + ky * pw) * c..][..3 * c];
        for (&wt, &x) in taps.iter().zip(xs) {
            acc = acc.fma(x, wt);
        }
    }
    acc
}

/// The pixels of a pooled output's 2×2 block.
const BLOCK: [(usize, usize); 4] = [(0, 0), (0, 1), (1, 0), (1, 1)];

/// Runs `$f::<V, TAPS>` for the layer's input channels (1 to 7: [`fits`]).
macro_rules! by_channels {
    ($cin:expr, $v:ty, $f:ident ( $($arg:expr),* )) => {
        match $cin {
            1 => $f::<$v, 9>($($arg),*),
            2 => $f::<$v, 18>($($arg),*),
            3 => $f::<$v, 27>($($arg),*),
            4 => $f::<$v, 36>($($arg),*),
            5 => $f::<$v, 45>($($arg),*),
            6 => $f::<$v, 54>($($arg),*),
            7 => $f::<$v, 63>($($arg),*),
            c => unreachable!("conv_direct with {c} input channels"),
        }
    };
}

struct Forward<'a> {
    input: &'a [f32],
    kernel: &'a [f32],
    bias: &'a [f32],
    g: &'a ConvGeom,
    lines: (usize, usize),
    to: Strided,
}

impl Forward<'_> {
    fn run(&self, dst: &mut [f32]) {
        by_channels!(self.g.cin, Portable, forward_taps(self, dst));
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma")]
    fn run_avx512(&self, dst: &mut [f32]) {
        by_channels!(self.g.cin, x86::Avx512, forward_taps(self, dst));
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn run_avx2(&self, dst: &mut [f32]) {
        by_channels!(self.g.cin, x86::Avx2, forward_taps(self, dst));
    }
}

#[inline(always)]
fn forward_taps<V: Vector, const TAPS: usize>(f: &Forward<'_>, dst: &mut [f32]) {
    let (g, to) = (f.g, f.to);
    let (y0, y1) = f.lines;
    let quarter = V::splat(0.25);
    for group in 0..g.cout.div_ceil(LANES) {
        let w = group_kernel::<V, TAPS>(f.kernel, group);
        let b = V::load(&bias_lanes(f.bias, group));
        let lanes = (g.cout - group * LANES).min(LANES);
        for i in y0 / 2..y1 / 2 {
            for j in 0..g.w / 2 {
                let mut sum = V::splat(0.0);
                for (di, dj) in BLOCK {
                    let pre = pre_activation(f.input, (2 * i + di) * g.pw() + 2 * j + dj, g.pw(), &w, b);
                    sum = sum.add(pre.relu());
                }
                let mut pooled = [0.0; LANES];
                sum.mul(quarter).store(&mut pooled);
                let o = to.base + (i - y0 / 2) * to.row + j * to.col + group * LANES * to.chan;
                if to.chan == 1 {
                    dst[o..o + lanes].copy_from_slice(&pooled[..lanes]);
                } else {
                    for (k, &v) in pooled[..lanes].iter().enumerate() {
                        dst[o + k * to.chan] = v;
                    }
                }
            }
        }
    }
}

struct Backward<'a> {
    input: &'a [f32],
    kernel: &'a [f32],
    bias: &'a [f32],
    g: &'a ConvGeom,
    upstream: &'a [f32],
    from: Strided,
}

impl Backward<'_> {
    fn run(&self, dk: &mut [f32], db: &mut [f32]) {
        by_channels!(self.g.cin, Portable, backward_taps(self, dk, db));
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma")]
    fn run_avx512(&self, dk: &mut [f32], db: &mut [f32]) {
        by_channels!(self.g.cin, x86::Avx512, backward_taps(self, dk, db));
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn run_avx2(&self, dk: &mut [f32], db: &mut [f32]) {
        by_channels!(self.g.cin, x86::Avx2, backward_taps(self, dk, db));
    }
}

#[inline(always)]
fn backward_taps<V: Vector, const TAPS: usize>(bw: &Backward<'_>, dk: &mut [f32], db: &mut [f32]) {
    let (g, from) = (bw.g, bw.from);
    let (c, pw) = (TAPS / 9, g.pw());
    let quarter = V::splat(0.25);
    for group in 0..g.cout.div_ceil(LANES) {
        let w = group_kernel::<V, TAPS>(bw.kernel, group);
        let b = V::load(&bias_lanes(bw.bias, group));
        let lanes = (g.cout - group * LANES).min(LANES);
        // This group's kernel gradient, a vector per tap, and its bias gradient.
        let mut dw = [V::splat(0.0); TAPS];
        let mut dbias = V::splat(0.0);
        for i in 0..g.h / 2 {
            for j in 0..g.w / 2 {
                let o = from.at(i, j) + group * LANES * from.chan;
                let mut up = [0.0f32; LANES];
                for (k, u) in up[..lanes].iter_mut().enumerate() {
                    *u = bw.upstream[o + k * from.chan];
                }
                let up = V::load(&up).mul(quarter);
                for (di, dj) in BLOCK {
                    let p = (2 * i + di) * pw + 2 * j + dj;
                    // ReLU's derivative: the pooled gradient where the pre-activation is positive.
                    let gv = up.where_positive(pre_activation(bw.input, p, pw, &w, b));
                    dbias = dbias.add(gv);
                    for (ky, rows) in dw.chunks_exact_mut(3 * c).enumerate() {
                        let xs = &bw.input[(p + ky * pw) * c..][..3 * c];
                        for (row, &x) in rows.iter_mut().zip(xs) {
                            *row = row.fma(x, gv);
                        }
                    }
                }
            }
        }
        let mut lanes_out = [0.0f32; LANES];
        for (t, row) in dw.iter().enumerate() {
            row.store(&mut lanes_out);
            for (d, &v) in dk[t * g.cout + group * LANES..][..lanes].iter_mut().zip(&lanes_out) {
                *d += v;
            }
        }
        dbias.store(&mut lanes_out);
        for (d, &v) in db[group * LANES..][..lanes].iter_mut().zip(&lanes_out) {
            *d += v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{conv, pool};
    use super::*;

    fn values(n: usize, seed: f32) -> Vec<f32> {
        (0..n).map(|i| ((i as f32 + seed) * 0.618).sin()).collect()
    }

    /// A padded image with zero borders.
    fn padded(g: &ConvGeom, seed: f32) -> Vec<f32> {
        let mut img = vec![0f32; g.padded_in()];
        let v = values(img.len(), seed);
        for y in 0..g.h {
            let p = ((y + 1) * g.pw() + 1) * g.cin;
            img[p..p + g.w * g.cin].copy_from_slice(&v[p..p + g.w * g.cin]);
        }
        img
    }

    /// Against the GEMM path (`conv` then `pool`): forward, kernel and bias gradients, for every
    /// instruction set this machine has, which must agree bit for bit.
    #[test]
    fn matches_the_gemm_path_on_every_instruction_set() {
        for g in [
            ConvGeom { h: 9, w: 7, cin: 1, cout: 20 },
            ConvGeom { h: 6, w: 10, cin: 3, cout: 64 },
            ConvGeom { h: 4, w: 4, cin: 1, cout: 2 },
        ] {
            let input = padded(&g, 0.3);
            let weights = values(9 * g.cin * g.cout, 1.1);
            let bias = values(g.cout, 2.3).iter().map(|b| 0.3 * b).collect::<Vec<_>>();
            let mut k_major = Vec::new();
            conv::kernel_k_major(&weights, &g, &mut k_major);
            let mut grouped = Vec::new();
            pack(&k_major, &g, &mut grouped);

            // The GEMM path: pre-activations, pooled; then the pooled gradient back.
            let (hp, wp) = (g.h / 2, g.w / 2);
            let to = Strided { base: 0, row: wp * g.cout, col: g.cout, chan: 1 };
            let mut pre = vec![0f32; g.out_len()];
            let mut patches = vec![0f32; g.patches_len()];
            conv::forward(&input, &k_major, &g, &mut pre, &mut patches, 1);
            let mut expected = vec![0f32; hp * wp * g.cout];
            pool::forward(&pre, &bias, g.h, g.w, &mut expected, to);
            let upstream = values(expected.len(), 4.4);
            let mut grad_padded = vec![0f32; g.padded_out()];
            let (mut dk_expected, mut db_expected) = (vec![0.5f32; 9 * g.cin * g.cout], vec![0.25f32; g.cout]);
            pool::backward(&pre, &bias, g.h, g.w, &upstream, to, &mut grad_padded, &mut db_expected);
            conv::kernel_grad(&input, &grad_padded, &g, &mut dk_expected, &mut patches, 1);

            let mut results = Vec::new();
            for isa_here in [Isa::Avx512, Isa::Avx2, Isa::Portable] {
                #[cfg(target_arch = "x86_64")]
                let runs = match isa_here {
                    Isa::Avx512 => std::is_x86_feature_detected!("avx512f"),
                    Isa::Avx2 => std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma"),
                    Isa::Portable => true,
                };
                #[cfg(not(target_arch = "x86_64"))]
                let runs = isa_here == Isa::Portable;
                if !runs {
                    eprintln!("{isa_here:?} not on this machine: not compared");
                    continue;
                }
                // Two bands of lines, as an actor's split image runs.
                let mut out = vec![f32::NAN; expected.len()];
                let half = 2 * (hp / 2);
                let (top, bottom) = out.split_at_mut(half * wp * g.cout);
                for (lines, dst) in [((0, 2 * half), top), ((2 * half, g.h), bottom)] {
                    let f = Forward { input: &input, kernel: &grouped, bias: &bias, g: &g, lines, to };
                    match isa_here {
                        #[cfg(target_arch = "x86_64")]
                        // SAFETY: checked above that the CPU has the features.
                        Isa::Avx512 => unsafe { f.run_avx512(dst) },
                        #[cfg(target_arch = "x86_64")]
                        // SAFETY: as above.
                        Isa::Avx2 => unsafe { f.run_avx2(dst) },
                        _ => f.run(dst),
                    }
                }
                let (mut dk, mut db) = (vec![0.5f32; dk_expected.len()], vec![0.25f32; g.cout]);
                let bw = Backward { input: &input, kernel: &grouped, bias: &bias, g: &g, upstream: &upstream, from: to };
                match isa_here {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: as above.
                    Isa::Avx512 => unsafe { bw.run_avx512(&mut dk, &mut db) },
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: as above.
                    Isa::Avx2 => unsafe { bw.run_avx2(&mut dk, &mut db) },
                    _ => bw.run(&mut dk, &mut db),
                }
                let close = |x: &[f32], e: &[f32], what: &str| {
                    for (i, (a, b)) in x.iter().zip(e).enumerate() {
                        assert!((a - b).abs() <= 1e-5 * (1.0 + b.abs()), "{g:?} {isa_here:?} {what}[{i}]: {a} vs {b}");
                    }
                };
                close(&out, &expected, "forward");
                close(&dk, &dk_expected, "kernel gradient");
                close(&db, &db_expected, "bias gradient");
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                results.push((bits(&out), bits(&dk), bits(&db)));
            }
            assert!(results.windows(2).all(|w| w[0] == w[1]), "{g:?}: the instruction sets disagree in the last bits");
        }
    }
}
