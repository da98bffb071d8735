//! The paper's Q-network, defined once and shared by the learner (training) and the actor
//! (inference): three identical convolution layers (F filters 3×3, 'same' padding, ReLU), each
//! followed by 2×2 average pooling; flatten; concatenate the scalar inputs (speed, and d for the
//! hybrid agent); two fully connected layers with ReLU; a linear output of one Q value per action.

use std::collections::HashMap;

use candle_core::{DType, Device, Result, Tensor, Var};
use candle_nn::{Conv2d, Conv2dConfig, Linear, Module, VarBuilder, VarMap};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Sizes of the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NetShape {
    pub height: usize,
    pub width: usize,
    pub channels: usize,
    /// Scalar inputs besides the image.
    pub scalars: usize,
    pub actions: usize,
    pub filters: usize,
    pub hidden: usize,
}

impl NetShape {
    /// Height and width after the three pooling layers.
    #[must_use]
    pub fn pooled(&self) -> (usize, usize) {
        (self.height / 8, self.width / 8)
    }

    /// Inputs of the first fully connected layer.
    #[must_use]
    pub fn flat(&self) -> usize {
        let (h, w) = self.pooled();
        self.filters * h * w + self.scalars
    }

    /// Every parameter: name and shape, in a fixed order.
    #[must_use]
    pub fn parameters(&self) -> Vec<(String, Vec<usize>)> {
        let (c, f, h) = (self.channels, self.filters, self.hidden);
        vec![
            ("conv1.weight".into(), vec![f, c, 3, 3]),
            ("conv1.bias".into(), vec![f]),
            ("conv2.weight".into(), vec![f, f, 3, 3]),
            ("conv2.bias".into(), vec![f]),
            ("conv3.weight".into(), vec![f, f, 3, 3]),
            ("conv3.bias".into(), vec![f]),
            ("fc1.weight".into(), vec![h, self.flat()]),
            ("fc1.bias".into(), vec![h]),
            ("fc2.weight".into(), vec![h, h]),
            ("fc2.bias".into(), vec![h]),
            ("q.weight".into(), vec![self.actions, h]),
            ("q.bias".into(), vec![self.actions]),
        ]
    }
}

/// The Q-network.
#[derive(Debug, Clone)]
pub struct QNetwork {
    pub shape: NetShape,
    conv: [Conv2d; 3],
    fc1: Linear,
    fc2: Linear,
    q: Linear,
}

impl QNetwork {
    /// Builds the network on the parameters of `vb` (which must hold every parameter of
    /// [`NetShape::parameters`], e.g. a [`VarMap`] made by [`init_parameters`]).
    pub fn new(vb: &VarBuilder, shape: NetShape) -> Result<Self> {
        let cfg = Conv2dConfig { padding: 1, ..Default::default() };
        let conv = |name: &str, cin: usize| candle_nn::conv2d(cin, shape.filters, 3, cfg, vb.pp(name));
        let conv = [conv("conv1", shape.channels)?, conv("conv2", shape.filters)?, conv("conv3", shape.filters)?];
        let fc1 = candle_nn::linear(shape.flat(), shape.hidden, vb.pp("fc1"))?;
        let fc2 = candle_nn::linear(shape.hidden, shape.hidden, vb.pp("fc2"))?;
        let q = candle_nn::linear(shape.hidden, shape.actions, vb.pp("q"))?;
        Ok(Self { shape, conv, fc1, fc2, q })
    }

    /// Q values `[B, actions]` of images `[B, C, H, W]` (f32 in 0–1) and scalars `[B, S]`.
    pub fn forward(&self, images: &Tensor, scalars: &Tensor) -> Result<Tensor> {
        let mut x = images.clone();
        for conv in &self.conv {
            x = conv.forward(&x)?.relu()?.avg_pool2d(2)?;
        }
        let x = Tensor::cat(&[&x.flatten_from(1)?, scalars], 1)?;
        let x = self.fc1.forward(&x)?.relu()?;
        let x = self.fc2.forward(&x)?.relu()?;
        self.q.forward(&x)
    }
}

/// A [`VarMap`] holding every parameter of `shape`, initialised from a seeded stream (candle's own
/// CPU initialisation cannot be seeded): weights uniform in ±√(6/fan_in) (He/Kaiming uniform),
/// biases uniform in ±1/√fan_in.
pub fn init_parameters(shape: &NetShape, seed: u64, device: &Device) -> Result<VarMap> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let map = VarMap::new();
    {
        let mut data = map.data().lock().expect("var map lock");
        for (name, dims) in shape.parameters() {
            let fan_in: usize = if dims.len() > 1 { dims[1..].iter().product() } else { 0 };
            let bias_fan_in = shape_fan_in(shape, &name);
            let bound = if dims.len() > 1 { (6.0 / fan_in as f64).sqrt() } else { 1.0 / (bias_fan_in as f64).sqrt() };
            let n: usize = dims.iter().product();
            let values: Vec<f32> = (0..n).map(|_| ((rng.next_u32() as f64 / u32::MAX as f64 * 2.0 - 1.0) * bound) as f32).collect();
            let t = Tensor::from_vec(values, dims.as_slice(), device)?;
            data.insert(name, Var::from_tensor(&t)?);
        }
    }
    Ok(map)
}

/// The fan-in of the layer a bias belongs to.
fn shape_fan_in(shape: &NetShape, bias: &str) -> usize {
    match bias.split('.').next().unwrap_or("") {
        "conv1" => shape.channels * 9,
        "conv2" | "conv3" => shape.filters * 9,
        "fc1" => shape.flat(),
        _ => shape.hidden,
    }
}

/// A network built on `vars`.
pub fn network(vars: &VarMap, shape: NetShape, device: &Device) -> Result<QNetwork> {
    QNetwork::new(&VarBuilder::from_varmap(vars, DType::F32, device), shape)
}

/// The parameters of `vars` by name (sorted, so that serialisation is deterministic).
pub fn named_tensors(vars: &VarMap) -> Vec<(String, Tensor)> {
    let data = vars.data().lock().expect("var map lock");
    let mut out: Vec<(String, Tensor)> = data.iter().map(|(k, v)| (k.clone(), v.as_tensor().clone())).collect();
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// The parameters of `vars` as a safetensors file in memory.
pub fn to_safetensors(vars: &VarMap) -> Result<Vec<u8>> {
    let named = named_tensors(vars);
    safetensors::serialize(named.iter().map(|(k, t)| (k.as_str(), t)), None)
        .map_err(|e| candle_core::Error::Msg(format!("serialising weights: {e}")))
}

/// Copies parameters from a safetensors file in memory into `vars`, checking that every parameter
/// is present with the right shape.
pub fn load_safetensors(vars: &VarMap, bytes: &[u8], device: &Device) -> Result<()> {
    let tensors: HashMap<String, Tensor> = candle_core::safetensors::load_buffer(bytes, device)?;
    let data = vars.data().lock().expect("var map lock");
    for (name, var) in data.iter() {
        let t = tensors.get(name).ok_or_else(|| candle_core::Error::Msg(format!("weights lack parameter `{name}`")))?;
        if t.dims() != var.dims() {
            candle_core::bail!("parameter `{name}` has shape {:?}, expected {:?}", t.dims(), var.dims());
        }
        var.set(&t.to_dtype(DType::F32)?)?;
    }
    Ok(())
}

/// Images (row-major u8, `H×W×C` each) as an f32 tensor `[B, C, H, W]` scaled to 0–1.
pub fn images_tensor(images: &[&[u8]], shape: &NetShape, device: &Device) -> Result<Tensor> {
    let (h, w, c) = (shape.height, shape.width, shape.channels);
    let mut data = vec![0f32; images.len() * c * h * w];
    for (b, img) in images.iter().enumerate() {
        let base = b * c * h * w;
        for (p, px) in img.chunks_exact(c).enumerate() {
            for (k, &v) in px.iter().enumerate() {
                data[base + k * h * w + p] = f32::from(v) / 255.0;
            }
        }
    }
    Tensor::from_vec(data, (images.len(), c, h, w), device)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> NetShape {
        NetShape { height: 16, width: 16, channels: 1, scalars: 2, actions: 3, filters: 4, hidden: 8 }
    }

    #[test]
    fn forward_gives_one_q_per_action_and_init_is_seeded() {
        let dev = Device::Cpu;
        let shape = tiny();
        let vars = init_parameters(&shape, 1, &dev).unwrap();
        let net = network(&vars, shape, &dev).unwrap();
        let img = vec![128u8; 16 * 16];
        let images = images_tensor(&[&img, &img], &shape, &dev).unwrap();
        let scalars = Tensor::new(&[[0.5f32, 0.1], [0.0, 0.0]], &dev).unwrap();
        let q = net.forward(&images, &scalars).unwrap();
        assert_eq!(q.dims(), &[2, 3]);
        // Same seed, same bytes; another seed, other bytes.
        let again = init_parameters(&shape, 1, &dev).unwrap();
        assert_eq!(to_safetensors(&vars).unwrap(), to_safetensors(&again).unwrap());
        let other = init_parameters(&shape, 2, &dev).unwrap();
        assert_ne!(to_safetensors(&vars).unwrap(), to_safetensors(&other).unwrap());
    }

    #[test]
    fn safetensors_round_trip_is_bit_exact_and_shape_checked() {
        let dev = Device::Cpu;
        let shape = tiny();
        let a = init_parameters(&shape, 1, &dev).unwrap();
        let b = init_parameters(&shape, 2, &dev).unwrap();
        load_safetensors(&b, &to_safetensors(&a).unwrap(), &dev).unwrap();
        assert_eq!(to_safetensors(&a).unwrap(), to_safetensors(&b).unwrap());
        let wider = init_parameters(&NetShape { hidden: 9, ..shape }, 1, &dev).unwrap();
        let e = load_safetensors(&b, &to_safetensors(&wider).unwrap(), &dev).unwrap_err();
        assert!(e.to_string().contains("has shape"), "{e}");
    }

    #[test]
    fn images_are_laid_out_channel_first() {
        let shape = NetShape { height: 1, width: 2, channels: 3, ..tiny() };
        let img = [0u8, 51, 102, 153, 204, 255];
        let t = images_tensor(&[&img], &shape, &Device::Cpu).unwrap();
        let v: Vec<f32> = t.flatten_all().unwrap().to_vec1().unwrap();
        assert_eq!(v, vec![0.0, 0.6, 0.2, 0.8, 0.4, 1.0]);
    }
}
