//! The fast CPU implementation of the Q-network: convolutions as `gemm` calls over zero-padded
//! NHWC images (no im2col for wide layers, no col2im), bias, ReLU and pooling fused in one pass,
//! hand-written backward passes, buffers reused across steps, and the batch split across threads.
//! Training and the actors' inference use it; candle's network (`crate::reference`, behind the
//! `candle` feature) is what it is tested against.
//!
//! - [`gemm`]: the bounds-checked safe wrapper around the `gemm` crate (`unsafe`, with the two
//!   bf16 kernels).
//! - [`bf16_matmul`]: the bf16 product's bounds-checked safe interface and the choice of kernel:
//!   [`amx`] (Intel's tiles) or [`avx512_bf16`] (`vdpbf16ps`, where AMX is absent).
//! - [`bf16_layout`]: the layouts of that product's operands, which both kernels multiply.
//! - [`bf16`]: bfloat16 rounding and conversion.
//! - [`aligned`]: buffers that start a cache line, for the bf16 kernels' operands.
//! - [`conv`]: 3×3 convolution forward, kernel gradient and input gradient of one image.
//! - [`conv_bf16`]: the wide layers' convolution on a bf16 kernel.
//! - [`conv_direct`]: the first layer computed directly, fused with bias, ReLU and pooling.
//! - [`dense_bf16`]: the first dense layer on a bf16 kernel, for a training batch.
//! - [`pool`]: fused bias + ReLU + 2×2 average pooling and its backward pass.
//! - [`model`]: the whole network, forward and backward, over a batch.
//! - [`thread_split`]: one image's layers split across threads (the actors' small batches).
//! - [`inference`]: acting: greedy actions for a batch of observations.
//! - [`precision`]: `[agent] precision` (auto, f32, bf16) resolved against the machine.
//! - [`params`]: parameters in candle's layout, their seeded initialisation, and Adam.

pub mod aligned;
pub mod amx;
pub mod avx512_bf16;
pub mod bf16;
pub mod bf16_layout;
pub mod bf16_matmul;
pub mod conv;
pub mod conv_bf16;
pub mod conv_direct;
pub mod dense_bf16;
pub mod gemm;
pub mod inference;
pub mod model;
pub mod params;
pub mod pool;
pub mod precision;
pub mod thread_split;

pub use inference::{Inference, argmax};
pub use model::FastNet;
pub use params::{Adam, Params};
pub use precision::Precision;

/// Threads to use by default: every core the process may run on.
#[must_use]
pub fn default_threads() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
}
