//! The fast CPU implementation of the Q-network: convolutions as `gemm` calls over zero-padded
//! NHWC images (no im2col for wide layers, no col2im), bias, ReLU and pooling fused in one pass,
//! hand-written backward passes, buffers reused across steps, and the batch split across threads.
//! Training and the actors' inference use it; candle's network (`crate::reference`, behind the
//! `reference` feature) is what it is tested against.
//!
//! - [`gemm`]: the bounds-checked safe wrapper around the `gemm` crate (the only `unsafe` code).
//! - [`conv`]: 3×3 convolution forward, kernel gradient and input gradient of one image.
//! - [`pool`]: fused bias + ReLU + 2×2 average pooling and its backward pass.
//! - [`model`]: the whole network, forward and backward, over a batch.
//! - [`bands`]: one image's layers split across threads (the actors' small batches).
//! - [`inference`]: acting: greedy actions for a batch of observations.
//! - [`params`]: parameters in candle's layout, their seeded initialisation, and Adam.

pub mod bands;
pub mod conv;
pub mod gemm;
pub mod inference;
pub mod model;
pub mod params;
pub mod pool;

pub use inference::{Inference, argmax};
pub use model::FastNet;
pub use params::{Adam, Params};

/// Threads to use by default: every core the process may run on.
#[must_use]
pub fn default_threads() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
}
