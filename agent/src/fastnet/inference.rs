//! Acting with the network: parameters, buffers, and greedy actions for a batch of observations.

use super::model::FastNet;
use super::params::Params;
use crate::shape::NetShape;
use crate::weights::{self, WeightsError};

/// Index of the largest value (the first of equals): the greedy action of a row of Q values.
#[must_use]
pub fn argmax(v: &[f32]) -> usize {
    v.iter().enumerate().fold(0, |best, (i, &x)| if x > v[best] { i } else { best })
}

/// A Q-network ready to act: the actors' and the evaluator's view of the network.
#[derive(Debug)]
pub struct Inference {
    pub params: Params,
    net: FastNet,
    /// The batch's frames, back to back.
    frames: Vec<u8>,
}

impl Inference {
    /// The network initialised from `seed` (as the learner's, before any weights arrive), on
    /// `threads` threads.
    #[must_use]
    pub fn new(shape: NetShape, seed: u64, threads: usize) -> Self {
        Self { params: Params::init(shape, seed), net: FastNet::new(shape, threads), frames: Vec::new() }
    }

    /// Replaces the parameters with a weights file's (as the learner publishes them).
    pub fn load(&mut self, bytes: &[u8]) -> Result<(), WeightsError> {
        self.params = weights::from_safetensors(self.net.shape, bytes, "")?;
        Ok(())
    }

    /// Q values (`batch × actions`) of frames (`H × W × C` bytes each) and scalar inputs
    /// (`batch × S`).
    pub fn q_values<'a>(&mut self, frames: impl IntoIterator<Item = &'a [u8]>, scalars: &[f32]) -> &[f32] {
        self.frames.clear();
        for f in frames {
            self.frames.extend_from_slice(f);
        }
        self.net.forward(&self.params, &self.frames, scalars)
    }

    /// The greedy action of each observation (the first of equal values).
    pub fn greedy<'a>(&mut self, frames: impl IntoIterator<Item = &'a [u8]>, scalars: &[f32]) -> Vec<u32> {
        let actions = self.net.shape.actions;
        self.q_values(frames, scalars).chunks_exact(actions).map(|q| argmax(q) as u32).collect()
    }
}
