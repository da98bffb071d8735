//! candle's version of the Q-network (behind the `candle` feature): the implementation
//! `fastnet` is tested and benchmarked against, and the future device backend. The same
//! parameters ([`Params`], candle's layouts) drive both.

use candle_core::{DType, Device, Result, Tensor, Var};
use candle_nn::{Conv2d, Conv2dConfig, Linear, Module, VarBuilder, VarMap};

use crate::fastnet::Params;
use crate::shape::NetShape;

/// The Q-network on candle.
#[derive(Debug, Clone)]
pub struct QNetwork {
    pub shape: NetShape,
    /// The three convolutions; none without an image (the multilayer perceptron).
    conv: Vec<Conv2d>,
    fc1: Linear,
    fc2: Linear,
    q: Linear,
}

impl QNetwork {
    /// Builds the network on the parameters of `vb` (which must hold every parameter of
    /// [`NetShape::parameters`], e.g. a [`VarMap`] made by [`var_map`]).
    pub fn new(vb: &VarBuilder, shape: NetShape) -> Result<Self> {
        let cfg = Conv2dConfig { padding: 1, ..Default::default() };
        let conv = |name: &str, cin: usize| candle_nn::conv2d(cin, shape.filters, 3, cfg, vb.pp(name));
        let conv = if shape.has_image() {
            vec![conv("conv1", shape.channels)?, conv("conv2", shape.filters)?, conv("conv3", shape.filters)?]
        } else {
            Vec::new()
        };
        let fc1 = candle_nn::linear(shape.flat(), shape.hidden, vb.pp("fc1"))?;
        let fc2 = candle_nn::linear(shape.hidden, shape.hidden, vb.pp("fc2"))?;
        let q = candle_nn::linear(shape.hidden, shape.actions, vb.pp("q"))?;
        Ok(Self { shape, conv, fc1, fc2, q })
    }

    /// Q values `[B, actions]` of images `[B, C, H, W]` (f32 in 0–1) and scalars `[B, S]`;
    /// without an image, of the scalars alone (`images` is not read).
    pub fn forward(&self, images: &Tensor, scalars: &Tensor) -> Result<Tensor> {
        let x = if self.shape.has_image() {
            let mut x = images.clone();
            for conv in &self.conv {
                x = conv.forward(&x)?.relu()?.avg_pool2d(2)?;
            }
            Tensor::cat(&[&x.flatten_from(1)?, scalars], 1)?
        } else {
            scalars.clone()
        };
        let x = self.fc1.forward(&x)?.relu()?;
        let x = self.fc2.forward(&x)?.relu()?;
        self.q.forward(&x)
    }
}

/// A candle variable map holding `params`.
pub fn var_map(params: &Params) -> Result<VarMap> {
    let map = VarMap::new();
    {
        let mut data = map.data().lock().expect("var map lock");
        for ((name, dims), values) in params.names.iter().zip(&params.values) {
            data.insert(name.clone(), Var::from_tensor(&Tensor::from_slice(values, dims.as_slice(), &Device::Cpu)?)?);
        }
    }
    Ok(map)
}

/// The parameters of a variable map, checked against `shape`.
pub fn params_of(shape: NetShape, vars: &VarMap) -> Result<Params> {
    let data = vars.data().lock().expect("var map lock");
    let mut p = Params::zeros(shape);
    for ((name, dims), v) in p.names.iter().zip(&mut p.values) {
        let var = data.get(name).ok_or_else(|| candle_core::Error::Msg(format!("missing parameter `{name}`")))?;
        if var.dims() != dims.as_slice() {
            candle_core::bail!("parameter `{name}` has shape {:?}, expected {dims:?}", var.dims());
        }
        *v = var.as_tensor().flatten_all()?.to_vec1()?;
    }
    Ok(p)
}

/// A network built on `vars`.
pub fn network(vars: &VarMap, shape: NetShape, device: &Device) -> Result<QNetwork> {
    QNetwork::new(&VarBuilder::from_varmap(vars, DType::F32, device), shape)
}

/// candle's own safetensors file of `vars` (sorted by name), to check the weights format against.
pub fn candle_safetensors(vars: &VarMap) -> Result<Vec<u8>> {
    let data = vars.data().lock().expect("var map lock");
    let mut named: Vec<(String, Tensor)> = data.iter().map(|(k, v)| (k.clone(), v.as_tensor().clone())).collect();
    named.sort_by(|a, b| a.0.cmp(&b.0));
    safetensors::serialize(named.iter().map(|(k, t)| (k.as_str(), t)), None)
        .map_err(|e| candle_core::Error::Msg(format!("serialising weights: {e}")))
}

/// Images (row-major u8, `H×W×C` each) as an f32 tensor `[B, C, H, W]` scaled to 0–1 (with no
/// elements without an image).
pub fn images_tensor(images: &[&[u8]], shape: &NetShape, device: &Device) -> Result<Tensor> {
    let (h, w, c) = (shape.height, shape.width, shape.channels);
    let mut data = vec![0f32; images.len() * c * h * w];
    for (b, img) in images.iter().enumerate() {
        let base = b * c * h * w;
        for (p, px) in img.chunks_exact(c.max(1)).enumerate() {
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
    use crate::weights;

    fn tiny() -> NetShape {
        NetShape { height: 16, width: 16, channels: 1, scalars: 2, actions: 3, filters: 4, hidden: 8 }
    }

    #[test]
    fn forward_gives_one_q_per_action() {
        let dev = Device::Cpu;
        let shape = tiny();
        let net = network(&var_map(&Params::init(shape, 1)).unwrap(), shape, &dev).unwrap();
        let img = vec![128u8; 16 * 16];
        let images = images_tensor(&[&img, &img], &shape, &dev).unwrap();
        let scalars = Tensor::new(&[[0.5f32, 0.1], [0.0, 0.0]], &dev).unwrap();
        assert_eq!(net.forward(&images, &scalars).unwrap().dims(), &[2, 3]);
    }

    #[test]
    fn the_mlp_has_no_convolutions_and_takes_the_scalars_alone() {
        let dev = Device::Cpu;
        let shape = NetShape::mlp(2, 8, 3);
        let vars = var_map(&Params::init(shape, 1)).unwrap();
        let net = network(&vars, shape, &dev).unwrap();
        assert!(net.conv.is_empty());
        let images = images_tensor(&[&[], &[]], &shape, &dev).unwrap();
        let scalars = Tensor::new(&[[0.5f32, 0.1], [0.0, 0.0]], &dev).unwrap();
        assert_eq!(net.forward(&images, &scalars).unwrap().dims(), &[2, 3]);
        let mut names: Vec<String> = vars.data().lock().unwrap().keys().cloned().collect();
        names.sort();
        assert_eq!(names, ["fc1.bias", "fc1.weight", "fc2.bias", "fc2.weight", "q.bias", "q.weight"]);
    }

    #[test]
    fn the_weights_format_is_byte_identical_to_candles() {
        for shape in [tiny(), NetShape::mlp(37, 16, 5)] {
            let p = Params::init(shape, 1);
            let vars = var_map(&p).unwrap();
            assert_eq!(weights::to_safetensors(&p, "").unwrap(), candle_safetensors(&vars).unwrap());
            assert_eq!(params_of(shape, &vars).unwrap(), p);
        }
        let p = Params::init(tiny(), 1);
        // And candle reads ours.
        let loaded = candle_core::safetensors::load_buffer(&weights::to_safetensors(&p, "").unwrap(), &Device::Cpu).unwrap();
        let fc1: Vec<f32> = loaded["fc1.weight"].flatten_all().unwrap().to_vec1().unwrap();
        assert_eq!(fc1, p.values[crate::fastnet::params::DenseSlots::of(&p.shape).fc1_w]);
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
