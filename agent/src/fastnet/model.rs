//! The paper's Q-network (see `crate::shape`) computed on the CPU with the kernels of this module: the
//! forward pass for inference and training, and the backward pass to every parameter's gradient.
//!
//! The convolution stack runs image by image, so the batch is split across threads with no
//! synchronisation between layers; each thread keeps its own buffers and kernel-gradient partial
//! sums (summed at the end, in a fixed order, so that results do not depend on timing). The dense
//! layers run on the whole batch with `gemm`'s own threads. A single image (an actor's inference)
//! is split across the threads instead, by bands of lines and of units (`fastnet::thread_split`).
//!
//! A shape with no image (`NetShape::has_image`) is the dense layers alone, the multilayer
//! perceptron over the scalar inputs: no convolution buffer is allocated and no kernel laid out,
//! the image slices are empty, and the backward pass stops at fc1's weight gradient (nothing needs
//! its input's).

use super::aligned::Aligned;
use super::bf16;
use super::bf16_matmul::PackedB;
use super::conv::{self, ConvGeom};
use super::conv_bf16::{self, Operands};
use super::conv_direct;
use super::dense_bf16::{self, DenseBf16};
use super::gemm::{View, matmul};
use super::params::{CONV_B, CONV_W, DenseSlots, Params};
use super::pool::{self, Strided};
use super::thread_split;
use crate::shape::NetShape;

/// The buffers of one thread's share of the batch.
#[derive(Debug, Default)]
struct Part {
    /// First image of the batch and number of images.
    start: usize,
    images: usize,
    /// Padded input of each layer, per image.
    input: [Vec<f32>; 3],
    /// Convolution output (before bias and ReLU) of each layer, per image.
    pre: [Aligned<f32>; 3],
    /// Padded gradient of each layer's pre-activation, per image (allocated on first backward).
    grad_padded: [Vec<f32>; 3],
    /// Gradient of layers 2 and 3's input, conv-out layout, per image.
    in_grad: [Aligned<f32>; 3],
    patches: Vec<f32>,
    /// bf16 path: each layer's padded input in bf16, per image (layers that run on a bf16 kernel).
    input_bf16: [Aligned<u16>; 3],
    /// bf16 path, one image at a time: the input transposed and the output gradient packed (a
    /// buffer per layer, so that each keeps its shape and its zeroed padding), and the output
    /// gradient in bf16.
    input_t: [Aligned<u16>; 3],
    grad_packed: [PackedB; 3],
    grad_bf16: Aligned<u16>,
    /// Kernel (k-major) and bias gradient partial sums.
    dk: [Aligned<f32>; 3],
    db: [Vec<f32>; 3],
}

/// The network's computation and its reusable buffers; parameters are passed in.
#[derive(Debug)]
pub struct FastNet {
    pub shape: NetShape,
    /// Where the dense layers' parameters sit in a [`Params`] of `shape`.
    slots: DenseSlots,
    /// The convolution layers' geometry (unused without an image).
    geoms: [ConvGeom; 3],
    threads: usize,
    batch: usize,
    parts: Vec<Part>,
    /// Dense activations and their gradients, `batch × width`.
    x: Vec<f32>,
    h1: Vec<f32>,
    h2: Vec<f32>,
    q: Vec<f32>,
    dx: Vec<f32>,
    dh1: Vec<f32>,
    dh2: Vec<f32>,
    /// The dense layers' output, transposed, when one image is split across threads.
    dense_t: Vec<f32>,
    /// The hidden dense layers' weights transposed (`k × n`, row-major: fc1, fc2), laid out for
    /// inference (`pack_for_inference`; empty otherwise). `gemm` multiplies them without packing
    /// a copy; the candle layout (`n × k`) made it pack the whole weight matrix at every call, a
    /// copy as large as the arithmetic it fed at an actor's small batches
    /// (experiments/performance/CHANGELOG.md, "where the cores go").
    dense_wt: [Vec<f32>; 2],
    /// fc1's bf16 operands, where it runs on the bf16 kernel (`dense_bf16`).
    fc1_bf16: DenseBf16,
    k_major: [Vec<f32>; 3],
    flipped: [Vec<f32>; 3],
    /// Whether the layers that fit (`conv_bf16::fits`) run in bf16, and their kernels
    /// packed for it.
    bf16: bool,
    k_packed: [PackedB; 3],
    flipped_packed: [PackedB; 3],
    /// The first layer's kernel grouped for `conv_direct` (empty where the layer is a GEMM).
    k_direct: Vec<f32>,
}

impl FastNet {
    /// A network of `shape` using up to `threads` threads (at least 1; one for a network with no
    /// image), in f32.
    #[must_use]
    pub fn new(shape: NetShape, threads: usize) -> Self {
        Self::with_precision(shape, threads, false)
    }

    /// A network of `shape` on up to `threads` threads whose wide convolutions run in bf16 on
    /// the machine's bf16 kernel (AMX or AVX512-BF16) when `bf16` (see `fastnet::precision` for
    /// choosing it), and fc1 too for a batch of `dense_bf16::MIN_BATCH` or more; the first
    /// layer, the other dense layers, the gradients' sums and everything after them stay f32.
    ///
    /// # Panics
    /// If `bf16` is asked for where neither bf16 kernel is available, or `shape` has neither an
    /// image nor scalar inputs.
    #[must_use]
    pub fn with_precision(shape: NetShape, threads: usize, bf16: bool) -> Self {
        if bf16 && let Err(why) = super::bf16_matmul::available() {
            panic!("FastNet::with_precision: bf16 without a bf16 kernel ({why})");
        }
        assert!(shape.has_image() || shape.scalars > 0, "FastNet: a network with no input ({shape:?})");
        let (f, mut h, mut w) = (shape.filters, shape.height, shape.width);
        let mut geoms = [ConvGeom { h, w, cin: shape.channels, cout: f }; 3];
        for g in &mut geoms {
            *g = ConvGeom { h, w, cin: if h == shape.height { shape.channels } else { f }, cout: f };
            (h, w) = (h / 2, w / 2);
        }
        Self {
            shape,
            slots: DenseSlots::of(&shape),
            geoms,
            // A multilayer perceptron's products are too small for a second thread to pay for its
            // hand-offs: the update runs faster on one (docs/PERFORMANCE.md, "The multilayer
            // perceptron"), and the other core is the actors'.
            threads: if shape.has_image() { threads.max(1) } else { 1 },
            batch: 0,
            parts: Vec::new(),
            x: Vec::new(),
            h1: Vec::new(),
            h2: Vec::new(),
            q: Vec::new(),
            dx: Vec::new(),
            dh1: Vec::new(),
            dh2: Vec::new(),
            dense_t: Vec::new(),
            dense_wt: Default::default(),
            fc1_bf16: DenseBf16::default(),
            k_major: Default::default(),
            flipped: Default::default(),
            bf16,
            k_packed: Default::default(),
            flipped_packed: Default::default(),
            k_direct: Vec::new(),
        }
    }

    /// Whether fc1 runs on the bf16 kernel for a batch of `b`: on the bf16 path, for a training
    /// batch (`dense_bf16::MIN_BATCH`), behind an image. Without one (the multilayer perceptron)
    /// fc1 is a small product (inputs of a vector observation, not thousands of convolution
    /// features) and the network stays f32 on every path: its bf16 gain is unmeasured, as no
    /// machine with a bf16 kernel was at hand (docs/PERFORMANCE.md, "The multilayer perceptron").
    fn fc1_on_bf16(&self, b: usize) -> bool {
        self.bf16 && self.shape.has_image() && b >= dense_bf16::MIN_BATCH
    }

    /// Whether layer `l` is computed directly ([`is_direct`]).
    fn layer_direct(&self, l: usize) -> bool {
        is_direct(l, &self.geoms[l])
    }

    /// Whether layer `l` runs on the bf16 kernel.
    /// Threads the network computes on.
    #[must_use]
    pub fn threads(&self) -> usize {
        self.threads
    }

    fn layer_bf16(&self, l: usize) -> bool {
        self.bf16 && conv_bf16::fits(&self.geoms[l])
    }

    fn flat(&self) -> usize {
        self.shape.flat()
    }

    /// Sizes the buffers for `batch` images (kept when the batch size repeats).
    fn prepare(&mut self, batch: usize) {
        if batch == self.batch {
            return;
        }
        self.batch = batch;
        // Without an image there is no convolution stack to split.
        let n_parts = if self.shape.has_image() { self.threads.min(batch).max(1) } else { 0 };
        self.parts = (0..n_parts)
            .map(|p| {
                let start = p * batch / n_parts;
                let images = (p + 1) * batch / n_parts - start;
                let mut part = Part { start, images, ..Part::default() };
                for (l, g) in self.geoms.iter().enumerate() {
                    part.input[l] = vec![0.0; images * g.padded_in()];
                    // A direct layer's pre-activations are recomputed, never kept.
                    part.pre[l] = if is_direct(l, g) { Aligned::default() } else { Aligned::zeroed(images * g.out_len()) };
                    part.dk[l] = Aligned::zeroed(9 * g.cin * g.cout);
                    part.db[l] = vec![0.0; g.cout];
                    if self.bf16 && conv_bf16::fits(g) {
                        part.input_bf16[l] = Aligned::zeroed(images * g.padded_in());
                    }
                }
                // Patches of the layers that gather them for a GEMM (not a direct first layer).
                let gathering = self.geoms.iter().enumerate().map(|(l, g)| {
                    let forward = if is_direct(l, g) { 0 } else { g.patches_len() };
                    forward.max(g.transposed().patches_len())
                });
                part.patches = vec![0.0; gathering.max().unwrap_or(0)];
                part
            })
            .collect();
        let (flat, hidden, actions) = (self.flat(), self.shape.hidden, self.shape.actions);
        self.x = vec![0.0; batch * flat];
        self.h1 = vec![0.0; batch * hidden];
        self.h2 = vec![0.0; batch * hidden];
        self.q = vec![0.0; batch * actions];
        // fc1's input gradient feeds the convolutions' backward pass only.
        self.dx = if self.shape.has_image() { vec![0.0; batch * flat] } else { Vec::new() };
        self.dh1 = vec![0.0; batch * hidden];
        self.dh2 = vec![0.0; batch * hidden];
    }

    /// Q values (`batch × actions`, row-major) of `images` (`batch` frames of `H × W × C` bytes,
    /// scaled by 1/255; empty without an image, the batch is then the scalars') and `scalars`
    /// (`batch × S`). Keeps the activations for [`Self::backward`].
    ///
    /// # Panics
    /// If the slices' lengths do not fit the network's shape.
    pub fn forward(&mut self, params: &Params, images: &[u8], scalars: &[f32]) -> &[f32] {
        self.pack_kernels(params);
        self.forward_packed(params, images, scalars)
    }

    /// Lays out the convolution kernels of `params` for the GEMMs (a copy of their weights):
    /// what [`Self::forward`] does first. Inference lays out once per weights version, with
    /// [`Self::pack_for_inference`], and then calls [`Self::forward_packed`].
    pub fn pack_kernels(&mut self, params: &Params) {
        let layers = if self.shape.has_image() { self.geoms.len() } else { 0 };
        for (l, g) in self.geoms.iter().enumerate().take(layers) {
            conv::kernel_k_major(&params.values[CONV_W[l]], g, &mut self.k_major[l]);
            if self.layer_bf16(l) {
                self.k_packed[l].pack(&self.k_major[l], View::rows(0, 9 * g.cin, g.cout, g.cout));
            }
            if is_direct(l, g) {
                conv_direct::pack(&self.k_major[l], g, &mut self.k_direct);
            }
        }
        // Transposes of other weights would be stale: the dense layers read `params` again.
        self.dense_wt.iter_mut().for_each(Vec::clear);
    }

    /// [`Self::pack_kernels`], and on one thread the hidden dense layers' weights transposed too:
    /// worth its copy where one weights version serves many forward passes (an actor's), not where
    /// every update changes them (training, whose batch of 32 amortises `gemm`'s own packing). On
    /// more threads the dense layers are split by units and read `W`'s rows (`dense`).
    pub fn pack_for_inference(&mut self, params: &Params) {
        self.pack_kernels(params);
        if self.threads > 1 {
            return;
        }
        let s = self.shape;
        // Not the Q head: a few columns, cheap to pack, and on its own layout the same bits as ever.
        let sizes = [(self.flat(), s.hidden), (s.hidden, s.hidden)];
        for ((wt, w), (k, n)) in self.dense_wt.iter_mut().zip([self.slots.fc1_w, self.slots.fc2_w]).zip(sizes) {
            transpose(&params.values[w], n, k, wt);
        }
    }

    /// [`Self::forward`] with the kernels of the last [`Self::pack_kernels`], which must have
    /// been given the same `params`.
    ///
    /// # Panics
    /// As [`Self::forward`], or if the kernels were never packed.
    pub fn forward_packed(&mut self, params: &Params, images: &[u8], scalars: &[f32]) -> &[f32] {
        let s = self.shape;
        assert!(!s.has_image() || !self.k_major[0].is_empty(), "forward_packed before pack_kernels");
        let frame = s.image_bytes();
        let batch = if s.has_image() { images.len() / frame } else { scalars.len() / s.scalars };
        assert!(
            images.len() == batch * frame && scalars.len() == batch * s.scalars,
            "forward: {} image bytes, {} scalars",
            images.len(),
            scalars.len()
        );
        self.prepare(batch);
        if batch <= 1 && self.threads > 1 {
            // One image split across the threads: the whole pass runs on a worker of the pool, so
            // that each layer's bands are handed to the other worker directly (local queue, a
            // worker that is still awake) rather than injected from outside and woken for, six
            // times per image.
            rayon::scope(|_| self.run_forward(params, images, scalars, batch));
        } else {
            self.run_forward(params, images, scalars, batch);
        }
        &self.q
    }

    /// The body of [`Self::forward_packed`] once the buffers fit `batch`.
    fn run_forward(&mut self, params: &Params, images: &[u8], scalars: &[f32], batch: usize) {
        let s = self.shape;
        let flat = self.flat();
        if s.has_image() {
            self.conv_forward(params, images);
        }
        let conv_flat = flat - s.scalars;
        for (row, sc) in self.x.chunks_exact_mut(flat).zip(scalars.chunks_exact(s.scalars.max(1))) {
            row[conv_flat..].copy_from_slice(&sc[..s.scalars]);
        }
        let (h, t, b, d) = (s.hidden, self.threads, batch, self.slots);
        let fc1_on_bf16 = self.fc1_on_bf16(b);
        let scratch = &mut self.dense_t;
        let [fc1_t, fc2_t] = &self.dense_wt;
        if fc1_on_bf16 {
            self.fc1_bf16.forward(&mut self.h1, &self.x, &params.values[d.fc1_w], b, flat, h, t);
            bias_act(&mut self.h1, &params.values[d.fc1_b], h, true);
        } else {
            dense(&mut self.h1, &self.x, (&params.values[d.fc1_w], fc1_t), &params.values[d.fc1_b], (b, flat, h), true, t, scratch);
        }
        dense(&mut self.h2, &self.h1, (&params.values[d.fc2_w], fc2_t), &params.values[d.fc2_b], (b, h, h), true, t, scratch);
        dense(&mut self.q, &self.h2, (&params.values[d.q_w], &[]), &params.values[d.q_b], (b, h, s.actions), false, t, scratch);
    }

    /// The convolution stack of the forward pass: each image's row of `x` up to its scalars.
    fn conv_forward(&mut self, params: &Params, images: &[u8]) {
        let s = self.shape;
        let frame = s.image_bytes();
        let flat = self.flat();
        // One part: the image's layers are split across the threads; several: one thread each.
        let bands = if self.parts.len() == 1 { self.threads } else { 1 };
        let kernels = Kernels {
            k_major: &self.k_major,
            packed: &self.k_packed,
            bf16: [0, 1, 2].map(|l| self.layer_bf16(l)),
            direct: self.layer_direct(0).then_some(&self.k_direct[..]),
        };
        let geoms = &self.geoms;
        let n = self.parts.len();
        let mut x_rest = &mut self.x[..];
        std::thread::scope(|scope| {
            for (i, part) in self.parts.iter_mut().enumerate() {
                let (x, rest) = std::mem::take(&mut x_rest).split_at_mut(part.images * flat);
                x_rest = rest;
                let imgs = &images[part.start * frame..(part.start + part.images) * frame];
                let mut work = move || part.forward(geoms, kernels, params, imgs, x, flat, bands);
                if i + 1 == n { work() } else { drop(scope.spawn(work)) }
            }
        });
    }

    /// Gradients of every parameter (written into `grads`) given `dq`, the loss's gradient with
    /// respect to the Q values of the last [`Self::forward`].
    ///
    /// # Panics
    /// If `dq` does not match the last forward's batch.
    pub fn backward(&mut self, params: &Params, dq: &[f32], grads: &mut Params) {
        let s = self.shape;
        let (b, h, a, flat, t, d) = (self.batch, s.hidden, s.actions, self.flat(), self.threads, self.slots);
        assert_eq!(dq.len(), b * a, "backward: dq for a batch of {b}");
        // Dense layers, last to first: weight gradient = upstreamᵀ · input, bias = column sums,
        // input gradient = upstream · weights, masked by the ReLU (fc1's only for the convolutions).
        dense_grads(dq, &self.h2, b, a, h, weight_and_bias(grads, d.q_w, d.q_b), t);
        back_through(&mut self.dh2, dq, &params.values[d.q_w], b, a, h, Some(&self.h2), t);
        dense_grads(&self.dh2, &self.h1, b, h, h, weight_and_bias(grads, d.fc2_w, d.fc2_b), t);
        back_through(&mut self.dh1, &self.dh2, &params.values[d.fc2_w], b, h, h, Some(&self.h1), t);
        let image = s.has_image();
        if self.fc1_on_bf16(b) {
            let (dw, db) = weight_and_bias(grads, d.fc1_w, d.fc1_b);
            self.fc1_bf16.weight_grad(dw, &self.dh1, &self.x, b, h, flat, t);
            bias_grad(&self.dh1, h, db);
            if image {
                self.fc1_bf16.input_grad(&mut self.dx, &self.dh1, &params.values[d.fc1_w], b, h, flat, t);
            }
        } else {
            dense_grads(&self.dh1, &self.x, b, h, flat, weight_and_bias(grads, d.fc1_w, d.fc1_b), t);
            if image {
                back_through(&mut self.dx, &self.dh1, &params.values[d.fc1_w], b, h, flat, None, t);
            }
        }
        if image {
            self.conv_backward(params, grads);
        }
    }

    /// The convolution stack's backward pass from fc1's input gradient (`dx`), into the
    /// convolutions' gradients in `grads`.
    fn conv_backward(&mut self, params: &Params, grads: &mut Params) {
        let flat = self.flat();
        if self.layer_direct(0) {
            // The forward pass laid it out, but maybe from other parameters (a target network's).
            let g = &self.geoms[0];
            conv::kernel_k_major(&params.values[CONV_W[0]], g, &mut self.k_major[0]);
            conv_direct::pack(&self.k_major[0], g, &mut self.k_direct);
        }
        for (l, g) in self.geoms.iter().enumerate().skip(1) {
            conv::kernel_flipped(&params.values[CONV_W[l]], g, &mut self.flipped[l]);
            if self.bf16 && conv_bf16::fits(&g.transposed()) {
                self.flipped_packed[l].pack(&self.flipped[l], View::rows(0, 9 * g.cout, g.cin, g.cin));
            }
        }
        let gemm_threads = if self.parts.len() == 1 { self.threads } else { 1 };
        let flipped = Kernels {
            k_major: &self.flipped,
            packed: &self.flipped_packed,
            bf16: [0, 1, 2].map(|l| self.bf16 && l > 0 && conv_bf16::fits(&self.geoms[l].transposed())),
            direct: self.layer_direct(0).then_some(&self.k_direct[..]),
        };
        let bf16_grads = [0, 1, 2].map(|l| self.layer_bf16(l));
        let (geoms, dx) = (&self.geoms, &self.dx);
        let n = self.parts.len();
        std::thread::scope(|scope| {
            for (i, part) in self.parts.iter_mut().enumerate() {
                let dx = &dx[part.start * flat..(part.start + part.images) * flat];
                let mut work = move || part.backward(geoms, flipped, bf16_grads, params, dx, flat, gemm_threads);
                if i + 1 == n { work() } else { drop(scope.spawn(work)) }
            }
        });
        for (l, g) in self.geoms.iter().enumerate() {
            let (w, bias) = (CONV_W[l], CONV_B[l]);
            grads.values[w].fill(0.0);
            grads.values[bias].fill(0.0);
            for part in &self.parts {
                conv::add_k_major_to_candle(&part.dk[l], g, &mut grads.values[w]);
                for (d, &x) in grads.values[bias].iter_mut().zip(&part.db[l]) {
                    *d += x;
                }
            }
        }
    }
}

impl Part {
    /// The convolution stack of this part's images; writes each image's row of `x` (the conv part).
    #[allow(clippy::too_many_arguments)]
    fn forward(
        &mut self,
        geoms: &[ConvGeom; 3],
        kernels: Kernels<'_>,
        params: &Params,
        images: &[u8],
        x: &mut [f32],
        flat: usize,
        bands: usize,
    ) {
        let g0 = geoms[0];
        let frame = g0.h * g0.w * g0.cin;
        for (img, bytes) in images.chunks_exact(frame).enumerate() {
            // Scale into the interior of the first padded input (its border stays zero).
            let input = &mut self.input[0][img * g0.padded_in()..(img + 1) * g0.padded_in()];
            let row = g0.pw() * g0.cin;
            for (y, line) in bytes.chunks_exact(g0.w * g0.cin).enumerate() {
                let o = (y + 1) * row + g0.cin;
                for (d, &v) in input[o..o + line.len()].iter_mut().zip(line) {
                    *d = f32::from(v) * (1.0 / 255.0);
                }
            }
            for (l, g) in geoms.iter().enumerate() {
                let (pi, po) = (g.padded_in(), g.out_len());
                let (inputs, next_inputs) = self.input.split_at_mut(l + 1);
                let input = &inputs[l][img * pi..(img + 1) * pi];
                let bias = &params.values[CONV_B[l]];
                if l == 0
                    && let Some(kernel) = kernels.direct
                {
                    let next = &geoms[1];
                    let dst = &mut next_inputs[0][img * next.padded_in()..(img + 1) * next.padded_in()];
                    thread_split::direct_pool(input, kernel, bias, g, dst, Strided::padded(next.w, next.cin), bands);
                    continue;
                }
                let pre = &mut self.pre[l][img * po..(img + 1) * po];
                let ops = if kernels.bf16[l] {
                    let input_bf16 = &mut self.input_bf16[l][img * pi..(img + 1) * pi];
                    bf16::convert(input, input_bf16);
                    Operands::Bf16 { input: input_bf16, kernel: &kernels.packed[l] }
                } else {
                    Operands::F32 { input, kernel: &kernels.k_major[l] }
                };
                if l < 2 {
                    let next = &geoms[l + 1];
                    let dst = &mut next_inputs[0][img * next.padded_in()..(img + 1) * next.padded_in()];
                    let to = Strided::padded(next.w, next.cin);
                    thread_split::conv_pool(ops, g, bias, pre, &mut self.patches, dst, to, bands);
                } else {
                    thread_split::conv(ops, g, pre, &mut self.patches, bands);
                    let dst = &mut x[img * flat..(img + 1) * flat];
                    pool::forward(pre, bias, g.h, g.w, dst, Strided::channel_major(g.h / 2, g.w / 2));
                }
            }
        }
    }

    /// The backward pass of the convolution stack for this part's images, from their rows of
    /// `dx`; leaves the partial kernel and bias gradients in `dk` and `db`.
    #[allow(clippy::too_many_arguments)]
    fn backward(
        &mut self,
        geoms: &[ConvGeom; 3],
        flipped: Kernels<'_>,
        bf16_grads: [bool; 3],
        params: &Params,
        dx: &[f32],
        flat: usize,
        threads: usize,
    ) {
        for (l, g) in geoms.iter().enumerate() {
            self.dk[l].fill(0.0);
            self.db[l].fill(0.0);
            if l == 0 && flipped.direct.is_some() {
                continue;
            }
            if self.grad_padded[l].len() != self.images * g.padded_out() {
                self.grad_padded[l] = vec![0.0; self.images * g.padded_out()];
            }
            if l > 0 && self.in_grad[l].len() != self.images * g.in_grad_len() {
                self.in_grad[l] = Aligned::zeroed(self.images * g.in_grad_len());
            }
        }
        for img in 0..self.images {
            for l in (0..3).rev() {
                let g = &geoms[l];
                let (pi, po, pg) = (g.padded_in(), g.out_len(), g.padded_out());
                if l == 0
                    && let Some(kernel) = flipped.direct
                {
                    let next = &geoms[1];
                    let len = next.in_grad_len();
                    let upstream = &self.in_grad[1][img * len..(img + 1) * len];
                    let input = &self.input[0][img * pi..(img + 1) * pi];
                    let from = Strided::conv_out(next.w, next.cin);
                    conv_direct::backward(input, kernel, &params.values[CONV_B[0]], g, upstream, from, &mut self.dk[0], &mut self.db[0]);
                    continue;
                }
                let pre = &self.pre[l][img * po..(img + 1) * po];
                let grad_padded = &mut self.grad_padded[l][img * pg..(img + 1) * pg];
                let bias = &params.values[CONV_B[l]];
                if l == 2 {
                    let from = Strided::channel_major(g.h / 2, g.w / 2);
                    pool::backward(pre, bias, g.h, g.w, &dx[img * flat..(img + 1) * flat], from, grad_padded, &mut self.db[l]);
                } else {
                    let next = &geoms[l + 1];
                    let len = next.in_grad_len();
                    let upstream = &self.in_grad[l + 1][img * len..(img + 1) * len];
                    pool::backward(pre, bias, g.h, g.w, upstream, Strided::conv_out(next.w, next.cin), grad_padded, &mut self.db[l]);
                }
                let input = &self.input[l][img * pi..(img + 1) * pi];
                if bf16_grads[l] {
                    // The forward pass's bf16 copy of this image (the same condition wrote it).
                    conv_bf16::transpose_padded(&self.input_bf16[l][img * pi..(img + 1) * pi], g, &mut self.input_t[l]);
                    conv_bf16::pack_output_grad(grad_padded, g, &mut self.grad_packed[l]);
                    conv_bf16::kernel_grad(&self.input_t[l], &self.grad_packed[l], g, &mut self.dk[l]);
                } else {
                    conv::kernel_grad(input, grad_padded, g, &mut self.dk[l], &mut self.patches, threads);
                }
                if l > 0 {
                    let len = g.in_grad_len();
                    let in_grad = &mut self.in_grad[l][img * len..(img + 1) * len];
                    if flipped.bf16[l] {
                        self.grad_bf16.resize(pg, 0);
                        bf16::convert(grad_padded, &mut self.grad_bf16);
                        let t = g.transposed();
                        conv_bf16::forward_rows(&self.grad_bf16, &flipped.packed[l], &t, 0, &mut in_grad[..t.rows() * t.cout]);
                    } else {
                        conv::input_grad(grad_padded, &flipped.k_major[l], g, in_grad, &mut self.patches, threads);
                    }
                }
            }
        }
    }
}

/// Whether layer `l` of geometry `g` is computed directly, fused with its pooling
/// (`conv_direct`): the first layer, which needs no input gradient, where it has few channels.
fn is_direct(l: usize, g: &ConvGeom) -> bool {
    l == 0 && conv_direct::fits(g)
}

/// Each layer's kernels in both layouts and which one it runs on; the first layer's grouped
/// kernel where it is computed directly (`conv_direct`).
#[derive(Debug, Clone, Copy)]
struct Kernels<'a> {
    k_major: &'a [Vec<f32>; 3],
    packed: &'a [PackedB; 3],
    bf16: [bool; 3],
    direct: Option<&'a [f32]>,
}

/// A layer's weight and bias gradients (bias right after weight in the parameter order).
fn weight_and_bias(grads: &mut Params, w: usize, b: usize) -> (&mut [f32], &mut [f32]) {
    assert_eq!(b, w + 1, "a bias follows its weight");
    let (head, tail) = grads.values.split_at_mut(b);
    (&mut head[w], &mut tail[0])
}

/// `out = act(input · Wᵀ + bias)` for a candle `Linear` weight `W` (`n × k`), given with its
/// transpose `wt` (`k × n`; empty: not laid out, `W` is used), and a batch of `b`; on more than
/// one thread the units are split across them (`scratch` holds the bands' output), each band
/// reading its rows of `W`.
#[allow(clippy::too_many_arguments)]
fn dense(
    out: &mut [f32],
    input: &[f32],
    (w, wt): (&[f32], &[f32]),
    bias: &[f32],
    (b, k, n): (usize, usize, usize),
    relu: bool,
    threads: usize,
    scratch: &mut Vec<f32>,
) {
    if threads > 1 {
        // Also for the learner's batch of 32: on fc1's product `gemm`'s own two threads were
        // slower than its one, and two bands of units, one per thread, faster than either
        // (docs/PERFORMANCE.md, "Design, in short").
        thread_split::dense(out, input, w, b, k, n, scratch, threads);
    } else if wt.is_empty() || b == 1 {
        // One image: `gemm` takes its matrix-vector path, which reads `W`'s rows in place (no
        // packing either way) and sums in the order it always has.
        matmul(out, View::rows(0, b, n, n), false, input, View::rows(0, b, k, k), w, View::rows(0, n, k, k).t(), threads);
    } else {
        // `gemm` computes a row-major `out` as outᵀ = W · inputᵀ; with `wt` given, that left
        // matrix W has contiguous columns, which it reads in place instead of packing them.
        matmul(out, View::rows(0, b, n, n), false, input, View::rows(0, b, k, k), wt, View::rows(0, k, n, n), threads);
    }
    bias_act(out, bias, n, relu);
}

/// Adds `bias` to each row of `out` (`n` wide), then the ReLU where `relu`.
fn bias_act(out: &mut [f32], bias: &[f32], n: usize, relu: bool) {
    for row in out.chunks_exact_mut(n) {
        for (o, &bv) in row.iter_mut().zip(bias) {
            *o += bv;
            if relu {
                *o = o.max(0.0);
            }
        }
    }
}

/// `wt = wᵀ` for `w` of `rows × cols` (row-major), in tiles that stay in cache.
fn transpose(w: &[f32], rows: usize, cols: usize, wt: &mut Vec<f32>) {
    const TILE: usize = 32;
    assert_eq!(w.len(), rows * cols, "transpose: {} values for {rows} × {cols}", w.len());
    wt.resize(rows * cols, 0.0);
    for r0 in (0..rows).step_by(TILE) {
        for c0 in (0..cols).step_by(TILE) {
            for r in r0..(r0 + TILE).min(rows) {
                for c in c0..(c0 + TILE).min(cols) {
                    wt[c * rows + r] = w[r * cols + c];
                }
            }
        }
    }
}

/// A dense layer's weight gradient `upstreamᵀ · input` (`n × k`) and bias gradient (column sums).
#[allow(clippy::too_many_arguments)]
fn dense_grads(upstream: &[f32], input: &[f32], b: usize, n: usize, k: usize, (dw, db): (&mut [f32], &mut [f32]), threads: usize) {
    matmul(dw, View::rows(0, n, k, k), false, upstream, View::rows(0, b, n, n).t(), input, View::rows(0, b, k, k), threads);
    bias_grad(upstream, n, db);
}

/// A dense layer's bias gradient: the column sums of `upstream` (`n` wide).
fn bias_grad(upstream: &[f32], n: usize, db: &mut [f32]) {
    db.fill(0.0);
    for row in upstream.chunks_exact(n) {
        for (d, &u) in db.iter_mut().zip(row) {
            *d += u;
        }
    }
}

/// The gradient of a dense layer's input, `upstream · W` (`b × k`), masked by the ReLU that made
/// the input when `relu_out` (the input itself) is given.
#[allow(clippy::too_many_arguments)]
fn back_through(out: &mut [f32], upstream: &[f32], w: &[f32], b: usize, n: usize, k: usize, relu_out: Option<&[f32]>, threads: usize) {
    matmul(out, View::rows(0, b, k, k), false, upstream, View::rows(0, b, n, n), w, View::rows(0, n, k, k), threads);
    if let Some(act) = relu_out {
        for (o, &a) in out.iter_mut().zip(act) {
            *o *= f32::from(u8::from(a > 0.0));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(seed: u32) -> impl FnMut() -> f32 {
        let mut seed = seed | 1;
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            f32::from(u16::try_from(seed >> 16).unwrap()) / 32768.0 - 1.0
        }
    }

    /// `input · Wᵀ` the old way (candle's `n × k` as the right matrix) and the new (its
    /// transpose), on one thread.
    fn both_ways(b: usize, k: usize, n: usize, seed: u32) -> (Vec<f32>, Vec<f32>) {
        let mut next = noise(seed);
        let w: Vec<f32> = (0..n * k).map(|_| next()).collect();
        let input: Vec<f32> = (0..b * k).map(|_| next()).collect();
        let mut old = vec![0.0; b * n];
        matmul(&mut old, View::rows(0, b, n, n), false, &input, View::rows(0, b, k, k), &w, View::rows(0, n, k, k).t(), 1);
        let mut wt = Vec::new();
        transpose(&w, n, k, &mut wt);
        assert_eq!(wt[3 * n + 1], w[k + 3], "wt is wᵀ");
        let mut new = vec![0.0; b * n];
        matmul(&mut new, View::rows(0, b, n, n), false, &input, View::rows(0, b, k, k), &wt, View::rows(0, k, n, n), 1);
        (old, new)
    }

    /// For the presets' hidden layers the transposed weights give the same bits as the candle
    /// layout did (the same products summed in the same order; only `gemm`'s packing copy is
    /// gone), at the batches that use them (2 and more: an actor's 4, the learner's 32; one image
    /// keeps `W`). So no run of a preset changed with the layout.
    #[test]
    fn the_presets_hidden_layers_on_transposed_weights_are_bit_identical_to_the_candle_layout() {
        for (name, _) in crate::presets::PRESETS {
            let shape = crate::config::RunConfig::preset(name).unwrap().net_shape();
            for (k, n) in [(shape.flat(), shape.hidden), (shape.hidden, shape.hidden)] {
                for b in [2, 3, 4, 8, 32] {
                    let (old, new) = both_ways(b, k, n, 7);
                    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&old), bits(&new), "{name}: b {b}, k {k}, n {n}");
                }
            }
        }
    }

    /// Other shapes may round differently in the last bits (`gemm` picks another kernel for a
    /// left matrix it does not pack), never by more than the f32 sums' own error.
    #[test]
    fn any_shape_on_transposed_weights_agrees_within_rounding() {
        for (b, k, n) in [(5, 37, 19), (4, 100, 48), (2, 64, 40), (3, 300, 17)] {
            let (old, new) = both_ways(b, k, n, 11);
            for (o, w) in old.iter().zip(&new) {
                // Inputs in [-1, 1): a sum of k products is off by at most ~k·ε in each order.
                assert!((o - w).abs() <= 2.0 * k as f32 * f32::EPSILON, "b {b}, k {k}, n {n}: {o} vs {w}");
            }
        }
    }
}
