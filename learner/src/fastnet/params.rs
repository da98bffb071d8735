//! The network's parameters as flat `f32` vectors in candle's layouts and in the order of
//! [`NetShape::parameters`], so that weights files are the same whichever implementation made
//! them; and Adam over them.

use std::collections::HashMap;

use candle_core::{Device, Tensor};
use candle_nn::VarMap;

use crate::net::{self, NetShape};

/// Indices into [`Params::values`], in [`NetShape::parameters`] order.
pub const CONV_W: [usize; 3] = [0, 2, 4];
pub const CONV_B: [usize; 3] = [1, 3, 5];
pub const FC1_W: usize = 6;
pub const FC1_B: usize = 7;
pub const FC2_W: usize = 8;
pub const FC2_B: usize = 9;
pub const Q_W: usize = 10;
pub const Q_B: usize = 11;

/// Why a weights file could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ParamsFileError {
    #[error("not a safetensors file: {0}")]
    NotSafetensors(String),
    /// A parameter is missing or has another shape than the network's.
    #[error("{0}")]
    Mismatch(String),
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

    /// The seeded initialisation of [`net::init_parameters`].
    pub fn init(shape: NetShape, seed: u64) -> candle_core::Result<Self> {
        Self::from_var_map(shape, &net::init_parameters(&shape, seed, &Device::Cpu)?)
    }

    /// Copies the parameters out of a candle variable map.
    pub fn from_var_map(shape: NetShape, vars: &VarMap) -> candle_core::Result<Self> {
        let data = vars.data().lock().expect("var map lock");
        let mut p = Self::zeros(shape);
        for ((name, dims), v) in p.names.iter().zip(&mut p.values) {
            let var = data.get(name).ok_or_else(|| candle_core::Error::Msg(format!("missing parameter `{name}`")))?;
            if var.dims() != dims.as_slice() {
                candle_core::bail!("parameter `{name}` has shape {:?}, expected {dims:?}", var.dims());
            }
            *v = var.as_tensor().flatten_all()?.to_vec1()?;
        }
        Ok(p)
    }

    /// The parameters as named tensors.
    pub fn tensors(&self) -> candle_core::Result<Vec<(String, Tensor)>> {
        self.names.iter().zip(&self.values).map(|((n, d), v)| Ok((n.clone(), Tensor::from_slice(v, d.as_slice(), &Device::Cpu)?))).collect()
    }

    /// A candle variable map holding these parameters (for the reference network).
    pub fn to_var_map(&self) -> candle_core::Result<VarMap> {
        let map = VarMap::new();
        {
            let mut data = map.data().lock().expect("var map lock");
            for (name, t) in self.tensors()? {
                data.insert(name, candle_core::Var::from_tensor(&t)?);
            }
        }
        Ok(map)
    }

    /// A safetensors file of the parameters, each under its name with `prefix` (byte-identical to
    /// [`net::to_safetensors`] of the same values when `prefix` is empty).
    pub fn to_safetensors(&self, prefix: &str) -> candle_core::Result<Vec<u8>> {
        let mut named: Vec<(String, Tensor)> = self.tensors()?.into_iter().map(|(n, t)| (format!("{prefix}{n}"), t)).collect();
        named.sort_by(|a, b| a.0.cmp(&b.0));
        safetensors::serialize(named.iter().map(|(k, t)| (k.as_str(), t)), None)
            .map_err(|e| candle_core::Error::Msg(format!("serialising parameters: {e}")))
    }

    /// Parameters of `shape` read from a safetensors file (names with `prefix`), checking in name
    /// order that each is present with its shape, so that the error names the same parameter
    /// every time.
    pub fn from_safetensors(shape: NetShape, bytes: &[u8], prefix: &str) -> Result<Self, ParamsFileError> {
        let tensors: HashMap<String, Tensor> =
            candle_core::safetensors::load_buffer(bytes, &Device::Cpu).map_err(|e| ParamsFileError::NotSafetensors(e.to_string()))?;
        let kind = if prefix.is_empty() { "parameter" } else { "tensor" };
        let mut p = Self::zeros(shape);
        let mut order: Vec<usize> = (0..p.names.len()).collect();
        order.sort_by(|&a, &b| p.names[a].0.cmp(&p.names[b].0));
        for i in order {
            let (name, dims) = &p.names[i];
            let key = format!("{prefix}{name}");
            let t = tensors.get(&key).ok_or_else(|| ParamsFileError::Mismatch(format!("lacks {kind} `{key}`")))?;
            if t.dims() != dims.as_slice() {
                return Err(ParamsFileError::Mismatch(format!("{kind} `{key}` has shape {:?}, expected {dims:?}", t.dims())));
            }
            p.values[i] = t
                .to_dtype(candle_core::DType::F32)
                .and_then(|t| t.flatten_all()?.to_vec1())
                .map_err(|e| ParamsFileError::Mismatch(format!("{kind} `{key}`: {e}")))?;
        }
        Ok(p)
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

    /// One step on `params` with `grads` rescaled so that their global norm is at most `clip`.
    /// Returns the norm before clipping.
    pub fn step(&mut self, params: &mut Params, grads: &Params, clip: f32) -> f32 {
        let norm = grads.norm();
        let scale = if norm > clip { clip / norm } else { 1.0 };
        self.t += 1;
        let (b1, b2) = (self.beta1 as f32, self.beta2 as f32);
        let bc1 = (1.0 - self.beta1.powi(self.t as i32)) as f32;
        let bc2 = (1.0 - self.beta2.powi(self.t as i32)) as f32;
        let (lr, eps) = (self.lr as f32, self.eps as f32);
        for (((p, g), m), v) in params.values.iter_mut().zip(&grads.values).zip(&mut self.m.values).zip(&mut self.v.values) {
            for (((p, &g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
                let g = g * scale;
                *m = b1 * *m + (1.0 - b1) * g;
                *v = b2 * *v + (1.0 - b2) * g * g;
                *p -= (*m / bc1) / ((*v / bc2).sqrt() + eps) * lr;
            }
        }
        norm
    }
}
