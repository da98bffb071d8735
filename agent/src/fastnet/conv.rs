//! 3×3 'same' convolution of one NHWC image as GEMMs over a zero-padded input, with no im2col
//! for wide inputs: one GEMM per kernel row, whose left matrix is the padded image read as
//! overlapping rows of 3·C values (stride C).
//!
//! Layouts, for an image of `h × w` with `pw = w + 2`:
//! - *padded*: `(h + 2) × pw × channels`, zero borders, pixel (y, x) at padded (y + 1, x + 1).
//! - *conv-out*: `h × pw × channels`, output (y, x) at row `y·pw + x`; the two rows per line at
//!   x = w, w + 1 are scratch (they are computed but never read as outputs).
//!
//! Output row q = y·pw + x needs padded rows q + ky·pw + kx for kx in 0..3, which are 3·C
//! consecutive values starting at (q + ky·pw)·C: hence one GEMM per ky with K = 3·C.
//! The gradients reuse the same views: the weight gradient is the transposed product against the
//! output gradient, and the input gradient is the forward convolution of the zero-padded output
//! gradient with the flipped, transposed kernel (no col2im).

use super::gemm::{View, matmul};

/// Sizes of one convolution layer (input and output share `h × w`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConvGeom {
    pub h: usize,
    pub w: usize,
    pub cin: usize,
    pub cout: usize,
}

impl ConvGeom {
    /// Padded width.
    #[must_use]
    pub fn pw(&self) -> usize {
        self.w + 2
    }

    /// Floats of one padded input image.
    #[must_use]
    pub fn padded_in(&self) -> usize {
        (self.h + 2) * self.pw() * self.cin
    }

    /// Floats of one padded output-gradient image.
    #[must_use]
    pub fn padded_out(&self) -> usize {
        (self.h + 2) * self.pw() * self.cout
    }

    /// Floats of one conv-out image.
    #[must_use]
    pub fn out_len(&self) -> usize {
        self.h * self.pw() * self.cout
    }

    /// Floats of one input gradient in conv-out layout.
    #[must_use]
    pub fn in_grad_len(&self) -> usize {
        self.h * self.pw() * self.cin
    }

    /// Rows each GEMM computes (the last line's two scratch rows would read past the padding).
    #[must_use]
    pub fn rows(&self) -> usize {
        self.h * self.pw() - 2
    }

    /// Whether K = 3·C is too narrow for an efficient GEMM, so that the layer gathers its 3×3
    /// patches first (K = 9·C): the first layer, with 1 or 3 channels.
    #[must_use]
    pub fn gathers(&self) -> bool {
        self.cin < 8
    }

    /// Floats of the patch buffer [`ConvGeom::gathers`] needs (0 if it does not).
    #[must_use]
    pub fn patches_len(&self) -> usize {
        if self.gathers() { self.rows() * 9 * self.cin } else { 0 }
    }

    /// The geometry of the input gradient's convolution (channels swapped).
    #[must_use]
    pub fn transposed(&self) -> Self {
        Self { cin: self.cout, cout: self.cin, ..*self }
    }
}

/// candle's `[cout, cin, 3, 3]` kernel as the `(ky, kx, c) × cout` matrix the GEMMs use.
pub fn kernel_k_major(w: &[f32], g: &ConvGeom, out: &mut Vec<f32>) {
    out.clear();
    out.resize(9 * g.cin * g.cout, 0.0);
    // A transpose, in blocks of 16 filters: a block's weights (16 × 9·cin, 36 KiB at 64 channels)
    // stay in L1 while its column of the output is written. Filter by filter, every write fell
    // 9·cin·cout apart, on one L1 set, and the copy was a large share of a batch-1 forward pass
    // (experiments/performance/CHANGELOG.md, fc1 on the tiles).
    for f0 in (0..g.cout).step_by(16) {
        let f1 = (f0 + 16).min(g.cout);
        for (row, out_row) in out.chunks_exact_mut(g.cout).enumerate() {
            let (k, c) = (row / g.cin, row % g.cin);
            for (f, o) in (f0..f1).zip(&mut out_row[f0..f1]) {
                *o = w[(f * g.cin + c) * 9 + k];
            }
        }
    }
}

/// The kernel rotated by 180° with input and output swapped, `(ky, kx, f) × cin`: the forward
/// kernel of the input gradient.
pub fn kernel_flipped(w: &[f32], g: &ConvGeom, out: &mut Vec<f32>) {
    out.clear();
    out.resize(9 * g.cin * g.cout, 0.0);
    // Written in order, as `kernel_k_major` is: the reads of a row are 9 values apart.
    for (row, out_row) in out.chunks_exact_mut(g.cin).enumerate() {
        let (k, f) = (8 - row / g.cout, row % g.cout);
        for (c, o) in out_row.iter_mut().enumerate() {
            *o = w[(f * g.cin + c) * 9 + k];
        }
    }
}

/// Adds a `(ky, kx, c) × cout` kernel gradient into candle's `[cout, cin, 3, 3]` layout.
pub fn add_k_major_to_candle(dk: &[f32], g: &ConvGeom, out: &mut [f32]) {
    // Read in order (see `kernel_k_major`); each value is added once, so the order changes no bit.
    for (row, dk_row) in dk[..9 * g.cin * g.cout].chunks_exact(g.cout).enumerate() {
        let (k, c) = (row / g.cin, row % g.cin);
        for (f, &d) in dk_row.iter().enumerate() {
            out[(f * g.cin + c) * 9 + k] += d;
        }
    }
}

/// Gathers the 3×3 patches of output rows `first..first + n` of a padded image into `patches`
/// (`n` rows of `(ky, kx, c)` values).
fn gather_patches(input: &[f32], g: &ConvGeom, first: usize, patches: &mut [f32]) {
    let (pw, c) = (g.pw(), g.cin);
    for (q, row) in patches.chunks_exact_mut(9 * c).enumerate() {
        for ky in 0..3 {
            let src = (first + q + ky * pw) * c;
            row[ky * 3 * c..(ky + 1) * 3 * c].copy_from_slice(&input[src..src + 3 * c]);
        }
    }
}

/// Convolution of one padded image (`padded_in` floats) with the k-major kernel, bias excluded,
/// into `out` (conv-out layout), on `threads` of `gemm`'s threads. `patches` is scratch of
/// [`ConvGeom::patches_len`] floats. (`fastnet::thread_split` splits one image's rows across threads
/// instead, which pays off where `gemm`'s threading does not.)
pub fn forward(input: &[f32], kernel: &[f32], g: &ConvGeom, out: &mut [f32], patches: &mut [f32], threads: usize) {
    let rows = g.rows();
    let patch_row = if g.gathers() { 9 * g.cin } else { 0 };
    forward_rows(input, kernel, g, 0, &mut out[..rows * g.cout], &mut patches[..rows * patch_row], threads);
}

/// Output rows `first..first + out.len() / cout` of [`forward`] (`patches` holds their patches
/// when the layer gathers).
pub fn forward_rows(input: &[f32], kernel: &[f32], g: &ConvGeom, first: usize, out: &mut [f32], patches: &mut [f32], threads: usize) {
    let (cin, cout) = (g.cin, g.cout);
    let n = out.len() / cout;
    let dst = View::rows(0, n, cout, cout);
    if g.gathers() {
        gather_patches(input, g, first, patches);
        matmul(out, dst, false, patches, View::rows(0, n, 9 * cin, 9 * cin), kernel, View::rows(0, 9 * cin, cout, cout), threads);
    } else {
        for ky in 0..3 {
            let lhs = View::rows((first + ky * g.pw()) * cin, n, 3 * cin, cin);
            let rhs = View::rows(ky * 3 * cin * cout, 3 * cin, cout, cout);
            matmul(out, dst, ky > 0, input, lhs, kernel, rhs, threads);
        }
    }
}

/// Adds the k-major kernel gradient of one image to `dk`, from its padded input and its padded
/// output gradient (`padded_out` floats, zero borders).
pub fn kernel_grad(input: &[f32], grad_padded: &[f32], g: &ConvGeom, dk: &mut [f32], patches: &mut [f32], threads: usize) {
    let (rows, cin, cout) = (g.rows(), g.cin, g.cout);
    // Output row q's gradient sits at padded row q + pw + 1; the scratch rows map onto the zero
    // border, so they add nothing.
    let grad = View::rows((g.pw() + 1) * cout, rows, cout, cout);
    if g.gathers() {
        let patches = &mut patches[..g.patches_len()];
        gather_patches(input, g, 0, patches);
        let lhs = View::rows(0, rows, 9 * cin, 9 * cin).t();
        matmul(dk, View::rows(0, 9 * cin, cout, cout), true, patches, lhs, grad_padded, grad, threads);
    } else {
        for ky in 0..3 {
            let lhs = View::rows(ky * g.pw() * cin, rows, 3 * cin, cin).t();
            matmul(dk, View::rows(ky * 3 * cin * cout, 3 * cin, cout, cout), true, input, lhs, grad_padded, grad, threads);
        }
    }
}

/// The input gradient of one image (conv-out layout, `in_grad_len` floats) from its padded output
/// gradient and the flipped kernel ([`kernel_flipped`]).
pub fn input_grad(grad_padded: &[f32], flipped: &[f32], g: &ConvGeom, out: &mut [f32], patches: &mut [f32], threads: usize) {
    forward(grad_padded, flipped, &g.transposed(), out, patches, threads);
}
