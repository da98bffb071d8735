//! Acting with the network: parameters, buffers, and greedy actions for a batch of observations.

use super::model::FastNet;
use super::params::Params;
use super::precision::{Chosen, Precision};
use crate::shape::NetShape;
use crate::weights::{self, WeightsError};

/// Index of the largest value (the first of equals): the greedy action of a row of Q values.
#[must_use]
pub fn argmax(v: &[f32]) -> usize {
    v.iter().enumerate().fold(0, |best, (i, &x)| if x > v[best] { i } else { best })
}

/// A Q-network ready to act: the actors' and the evaluator's view of the network. Its kernels
/// are laid out once per weights version, not at every step.
#[derive(Debug)]
pub struct Inference {
    params: Params,
    net: FastNet,
    /// The batch's frames, back to back.
    frames: Vec<u8>,
}

impl Inference {
    /// The network initialised from `seed` (as the learner's, before any weights arrive), on
    /// `threads` threads.
    #[must_use]
    pub fn new(shape: NetShape, seed: u64, threads: usize) -> Self {
        Self::with_params(Params::init(shape, seed), threads)
    }

    /// The network with these parameters, on `threads` threads, in f32.
    #[must_use]
    pub fn with_params(params: Params, threads: usize) -> Self {
        Self::with_arithmetic(params, threads, false)
    }

    /// The network initialised from `seed`, in the arithmetic `precision` resolves to here (bf16
    /// where a bf16 kernel runs it: faster at the actors' batches too, see docs/PERFORMANCE.md), and what was
    /// chosen and why, for the caller's log.
    #[must_use]
    pub fn with_precision(shape: NetShape, seed: u64, threads: usize, precision: Precision) -> (Self, Chosen) {
        let chosen = precision.resolve_or_f32();
        (Self::with_arithmetic(Params::init(shape, seed), threads, chosen.bf16), chosen)
    }

    /// The network with these parameters, in bf16 when `bf16` (see `FastNet::with_precision`).
    fn with_arithmetic(params: Params, threads: usize, bf16: bool) -> Self {
        let mut net = FastNet::with_precision(params.shape, threads, bf16);
        net.pack_for_inference(&params);
        Self { params, net, frames: Vec::new() }
    }

    /// The parameters acted with.
    #[must_use]
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// Replaces the parameters (new weights from the learner).
    pub fn set_params(&mut self, params: Params) {
        assert_eq!(params.shape, self.net.shape, "set_params: parameters of another network shape");
        self.params = params;
        self.net.pack_for_inference(&self.params);
    }

    /// Replaces the parameters with a weights file's (as the learner publishes them).
    pub fn load(&mut self, bytes: &[u8]) -> Result<(), WeightsError> {
        self.params = weights::from_safetensors(self.net.shape, bytes, "")?;
        self.net.pack_for_inference(&self.params);
        Ok(())
    }

    /// Q values (`batch × actions`) of frames (`H × W × C` bytes each) and scalar inputs
    /// (`batch × S`).
    pub fn q_values<'a>(&mut self, frames: impl IntoIterator<Item = &'a [u8]>, scalars: &[f32]) -> &[f32] {
        self.frames.clear();
        for f in frames {
            self.frames.extend_from_slice(f);
        }
        self.net.forward_packed(&self.params, &self.frames, scalars)
    }

    /// The greedy action of each observation (the first of equal values).
    pub fn greedy<'a>(&mut self, frames: impl IntoIterator<Item = &'a [u8]>, scalars: &[f32]) -> Vec<u32> {
        let actions = self.net.shape.actions;
        self.q_values(frames, scalars).chunks_exact(actions).map(|q| argmax(q) as u32).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Inference lays its kernels out once per weights version: new parameters must be re-laid
    /// out, or it would act with the old kernels and the new dense layers.
    #[test]
    fn new_parameters_act_with_their_own_kernels() {
        let shape = NetShape { height: 12, width: 12, channels: 1, scalars: 2, actions: 3, filters: 4, hidden: 8 };
        let image: Vec<u8> = (0..144).map(|i| (i * 37 % 251) as u8).collect();
        let scalars = [0.3, -0.2];
        let mut inference = Inference::new(shape, 1, 2);
        let first = inference.q_values([image.as_slice()], &scalars).to_vec();
        let other = Params::init(shape, 2);
        let expected = FastNet::new(shape, 1).forward(&other, &image, &scalars).to_vec();
        inference.set_params(other);
        let second = inference.q_values([image.as_slice()], &scalars).to_vec();
        assert_ne!(first, second);
        for (a, e) in second.iter().zip(&expected) {
            assert!((a - e).abs() <= 1e-5 * e.abs().max(1e-3), "{second:?} vs {expected:?}");
        }
    }
}
