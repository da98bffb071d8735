//! The network's parameters as flat `f32` vectors in candle's (and PyTorch's) layouts and in the
//! order of [`NetShape::parameters`], so that weights files are the same whichever implementation
//! made them (`crate::weights` reads and writes them); their seeded initialisation; and Adam.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::shape::NetShape;

/// Indices into [`Params::values`] of the convolutions' parameters, where the network has an
/// image (they come first, in [`NetShape::parameters`] order).
pub const CONV_W: [usize; 3] = [0, 2, 4];
pub const CONV_B: [usize; 3] = [1, 3, 5];

/// Indices into [`Params::values`] of the dense layers' parameters: after the convolutions' six
/// where the network has an image, first without one ([`NetShape::parameters`] order).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DenseSlots {
    pub fc1_w: usize,
    pub fc1_b: usize,
    pub fc2_w: usize,
    pub fc2_b: usize,
    pub q_w: usize,
    pub q_b: usize,
}

impl DenseSlots {
    /// The slots of a network of `shape`.
    #[must_use]
    pub fn of(shape: &NetShape) -> Self {
        let o = if shape.has_image() { 2 * CONV_W.len() } else { 0 };
        Self { fc1_w: o, fc1_b: o + 1, fc2_w: o + 2, fc2_b: o + 3, q_w: o + 4, q_b: o + 5 }
    }
}

/// Every parameter of a network (or a gradient or moment of the same shape).
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    pub shape: NetShape,
    /// (name, dims) in [`NetShape::parameters`] order.
    pub names: Vec<(String, Vec<usize>)>,
    pub values: Vec<Vec<f32>>,
}

impl Params {
    /// All zeros.
    #[must_use]
    pub fn zeros(shape: NetShape) -> Self {
        let names = shape.parameters();
        let values = names.iter().map(|(_, d)| vec![0f32; d.iter().product()]).collect();
        Self { shape, names, values }
    }

    /// The seeded initialisation (candle's own CPU initialisation cannot be seeded): weights
    /// uniform in ±√(6/fan_in) (He/Kaiming uniform), biases uniform in ±1/√fan_in, drawn from one
    /// `ChaCha8` stream in [`NetShape::parameters`] order.
    #[must_use]
    pub fn init(shape: NetShape, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut p = Self::zeros(shape);
        for ((name, dims), values) in p.names.iter().zip(&mut p.values) {
            let fan_in = shape.fan_in(name) as f64;
            let bound = if dims.len() > 1 { (6.0 / fan_in).sqrt() } else { 1.0 / fan_in.sqrt() };
            for v in values.iter_mut() {
                *v = ((f64::from(rng.next_u32()) / f64::from(u32::MAX) * 2.0 - 1.0) * bound) as f32;
            }
        }
        p
    }

    /// The L2 norm of all values together.
    #[must_use]
    pub fn norm(&self) -> f32 {
        self.values.iter().flatten().map(|x| f64::from(*x) * f64::from(*x)).sum::<f64>().sqrt() as f32
    }
}

/// Adam (Kingma & Ba 2015) on flat parameters, with gradients clipped to a global norm.
#[derive(Debug, Clone)]
pub struct Adam {
    pub lr: f64,
    pub beta1: f64,
    pub beta2: f64,
    pub eps: f64,
    /// Steps taken.
    pub t: u64,
    /// First and second moments.
    pub m: Params,
    pub v: Params,
}

impl Adam {
    /// Moments at zero.
    #[must_use]
    pub fn new(shape: NetShape, lr: f64) -> Self {
        Self { lr, beta1: 0.9, beta2: 0.999, eps: 1e-8, t: 0, m: Params::zeros(shape), v: Params::zeros(shape) }
    }

    /// One step on `params` with `grads` rescaled so that their global norm is at most `clip`, on
    /// up to `threads` threads (the step is elementwise: any split gives the same bits; it is a
    /// memory-bound pass over four copies of the parameters, which two cores read faster than
    /// one). Returns the norm before clipping.
    pub fn step(&mut self, params: &mut Params, grads: &Params, clip: f32, threads: usize) -> f32 {
        /// Values per piece of work: large enough that a thread's start is noise beside it.
        const PIECE: usize = 1 << 16;
        let norm = grads.norm();
        let scale = if norm > clip { clip / norm } else { 1.0 };
        self.t += 1;
        let (b1, b2) = (self.beta1 as f32, self.beta2 as f32);
        let bc1 = (1.0 - self.beta1.powi(self.t as i32)) as f32;
        let bc2 = (1.0 - self.beta2.powi(self.t as i32)) as f32;
        let (lr, eps) = (self.lr as f32, self.eps as f32);
        let update = move |(p, g, m, v): (&mut [f32], &[f32], &mut [f32], &mut [f32])| {
            for (((p, &g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
                let g = g * scale;
                *m = b1 * *m + (1.0 - b1) * g;
                *v = b2 * *v + (1.0 - b2) * g * g;
                *p -= (*m / bc1) / ((*v / bc2).sqrt() + eps) * lr;
            }
        };
        let mut pieces = Vec::new();
        for (((p, g), m), v) in params.values.iter_mut().zip(&grads.values).zip(&mut self.m.values).zip(&mut self.v.values) {
            pieces.extend(
                p.chunks_mut(PIECE)
                    .zip(g.chunks(PIECE))
                    .zip(m.chunks_mut(PIECE))
                    .zip(v.chunks_mut(PIECE))
                    .map(|(((p, g), m), v)| (p, g, m, v)),
            );
        }
        let per_thread = pieces.len().div_ceil(threads.max(1)).max(1);
        std::thread::scope(|scope| {
            let mut groups = pieces.chunks_mut(per_thread).peekable();
            while let Some(group) = groups.next() {
                let mut work = move || group.iter_mut().for_each(|(p, g, m, v)| update((p, g, m, v)));
                if groups.peek().is_none() { work() } else { drop(scope.spawn(work)) }
            }
        });
        norm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_slots_name_the_dense_parameters_with_and_without_an_image() {
        let camera = NetShape { height: 16, width: 16, channels: 1, scalars: 2, actions: 3, filters: 4, hidden: 8 };
        for shape in [camera, NetShape::mlp(37, 16, 5)] {
            let (names, d) = (shape.parameters(), DenseSlots::of(&shape));
            let at = |i: usize| names[i].0.as_str();
            assert_eq!(
                [d.fc1_w, d.fc1_b, d.fc2_w, d.fc2_b, d.q_w, d.q_b].map(at),
                ["fc1.weight", "fc1.bias", "fc2.weight", "fc2.bias", "q.weight", "q.bias"]
            );
            assert_eq!(names.len(), d.q_b + 1);
        }
    }

    #[test]
    fn adam_gives_the_same_bits_on_any_number_of_threads() {
        // 48×48 input: fc1 alone is several pieces of work, so every thread count splits it.
        let shape = NetShape { height: 48, width: 48, channels: 1, scalars: 2, actions: 5, filters: 64, hidden: 256 };
        let grads = Params::init(shape, 2);
        let runs: Vec<(Params, Adam)> = [1, 2, 3, 8]
            .into_iter()
            .map(|threads| {
                let (mut params, mut adam) = (Params::init(shape, 1), Adam::new(shape, 1e-3));
                for clip in [0.5, 1e9, 2.0] {
                    adam.step(&mut params, &grads, clip, threads);
                }
                (params, adam)
            })
            .collect();
        assert!(runs[0].0.values.iter().flatten().zip(Params::init(shape, 1).values.iter().flatten()).any(|(a, b)| a != b));
        for (params, adam) in &runs[1..] {
            assert!(params.values == runs[0].0.values && adam.m.values == runs[0].1.m.values && adam.v.values == runs[0].1.v.values);
        }
    }
}
