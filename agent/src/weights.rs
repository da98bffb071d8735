//! The weights file: parameters as a safetensors file (the format PyTorch, JAX and candle read),
//! each tensor `f32`, little-endian, under its [`NetShape::parameters`] name (optionally with a
//! prefix, as the optimizer's moments `m.<name>` and `v.<name>` share one file). Written and read
//! with the `safetensors` crate directly; the bytes are the same as candle's `safetensors::save`
//! of the same values (tested against the reference), so every file written before stays readable.

use std::borrow::Cow;

use safetensors::tensor::{Dtype, SafeTensors, View};

use crate::fastnet::Params;
use crate::shape::NetShape;

/// Why a weights file could not be read or written.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WeightsError {
    #[error("not a safetensors file: {0}")]
    NotSafetensors(String),
    /// A parameter is missing, has another shape than the network's, or an unreadable type.
    #[error("{0}")]
    Mismatch(String),
    #[error("serialising weights: {0}")]
    Serialise(String),
}

/// One tensor to write: its shape and its values.
struct F32Tensor<'a> {
    dims: &'a [usize],
    values: &'a [f32],
}

impl View for F32Tensor<'_> {
    fn dtype(&self) -> Dtype {
        Dtype::F32
    }

    fn shape(&self) -> &[usize] {
        self.dims
    }

    fn data(&self) -> Cow<'_, [u8]> {
        Cow::Owned(self.values.iter().flat_map(|v| v.to_le_bytes()).collect())
    }

    fn data_len(&self) -> usize {
        self.values.len() * 4
    }
}

/// A safetensors file of several parameter sets, each tensor named `<prefix><parameter>`.
pub fn to_safetensors_multi(sets: &[(&str, &Params)]) -> Result<Vec<u8>, WeightsError> {
    let named = sets.iter().flat_map(|(prefix, p)| {
        p.names.iter().zip(&p.values).map(move |((name, dims), values)| (format!("{prefix}{name}"), F32Tensor { dims, values }))
    });
    // `serialize` orders tensors by dtype alignment then name, so the bytes do not depend on the
    // order given here.
    safetensors::tensor::serialize(named, None).map_err(|e| WeightsError::Serialise(e.to_string()))
}

/// A safetensors file of `params`, each tensor under its name with `prefix`.
pub fn to_safetensors(params: &Params, prefix: &str) -> Result<Vec<u8>, WeightsError> {
    to_safetensors_multi(&[(prefix, params)])
}

/// Parameters of `shape` read from a safetensors file (names with `prefix`), checking in name
/// order that each is present with its shape, so that the error names the same parameter every
/// time. `f32` tensors are read as they are; `f64` and `bf16` are converted.
pub fn from_safetensors(shape: NetShape, bytes: &[u8], prefix: &str) -> Result<Params, WeightsError> {
    let file = SafeTensors::deserialize(bytes).map_err(|e| WeightsError::NotSafetensors(e.to_string()))?;
    let kind = if prefix.is_empty() { "parameter" } else { "tensor" };
    let mut p = Params::zeros(shape);
    let mut order: Vec<usize> = (0..p.names.len()).collect();
    order.sort_by(|&a, &b| p.names[a].0.cmp(&p.names[b].0));
    for i in order {
        let (name, dims) = &p.names[i];
        let key = format!("{prefix}{name}");
        let t = file.tensor(&key).map_err(|_| WeightsError::Mismatch(format!("lacks {kind} `{key}`")))?;
        if t.shape() != dims.as_slice() {
            return Err(WeightsError::Mismatch(format!("{kind} `{key}` has shape {:?}, expected {dims:?}", t.shape())));
        }
        p.values[i] = decode(t.dtype(), t.data()).ok_or_else(|| {
            WeightsError::Mismatch(format!("{kind} `{key}` has type {:?}; readable types are F32, F64 and BF16", t.dtype()))
        })?;
    }
    Ok(p)
}

/// A tensor's little-endian bytes as `f32` values, if its type is one we read.
fn decode(dtype: Dtype, data: &[u8]) -> Option<Vec<f32>> {
    match dtype {
        Dtype::F32 => Some(data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()),
        Dtype::F64 => Some(data.chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")) as f32).collect()),
        // bf16 is the upper half of an f32.
        Dtype::BF16 => Some(data.chunks_exact(2).map(|b| f32::from_bits(u32::from(u16::from_le_bytes([b[0], b[1]])) << 16)).collect()),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> NetShape {
        NetShape { height: 16, width: 16, channels: 1, scalars: 2, actions: 3, filters: 4, hidden: 8 }
    }

    #[test]
    fn round_trip_is_bit_exact_and_shape_checked() {
        let a = Params::init(tiny(), 1);
        let bytes = to_safetensors(&a, "").unwrap();
        assert_eq!(from_safetensors(tiny(), &bytes, "").unwrap(), a);
        let e = from_safetensors(NetShape { hidden: 9, ..tiny() }, &bytes, "").unwrap_err();
        assert!(e.to_string().contains("has shape"), "{e}");
        let e = from_safetensors(tiny(), &bytes, "m.").unwrap_err();
        assert_eq!(e.to_string(), "lacks tensor `m.conv1.bias`");
        assert!(matches!(from_safetensors(tiny(), b"garbage", ""), Err(WeightsError::NotSafetensors(_))));
    }

    /// The multilayer perceptron's file holds its six dense tensors under the names PyTorch's
    /// `nn.Linear` (`F.linear(x, weight, bias)`, weight `[out, in]`) uses for `fc1`, `fc2` and
    /// `q`, and nothing else; a file of another shape is refused naming the tensor.
    #[test]
    fn an_mlp_round_trips_under_its_dense_names_and_is_shape_checked() {
        let shape = NetShape::mlp(150, 256, 27);
        let a = Params::init(shape, 4);
        let bytes = to_safetensors(&a, "").unwrap();
        assert_eq!(from_safetensors(shape, &bytes, "").unwrap(), a);
        let file = SafeTensors::deserialize(&bytes).unwrap();
        let mut names: Vec<(String, Vec<usize>)> = file.tensors().into_iter().map(|(n, t)| (n, t.shape().to_vec())).collect();
        names.sort();
        let expected = [
            ("fc1.bias", vec![256]),
            ("fc1.weight", vec![256, 150]),
            ("fc2.bias", vec![256]),
            ("fc2.weight", vec![256, 256]),
            ("q.bias", vec![27]),
            ("q.weight", vec![27, 256]),
        ]
        .map(|(n, d)| (n.to_string(), d));
        assert_eq!(names, expected);
        let e = from_safetensors(NetShape::mlp(149, 256, 27), &bytes, "").unwrap_err();
        assert_eq!(e.to_string(), "parameter `fc1.weight` has shape [256, 150], expected [256, 149]");
        let e = from_safetensors(NetShape::mlp(150, 256, 26), &bytes, "").unwrap_err();
        assert_eq!(e.to_string(), "parameter `q.bias` has shape [27], expected [26]");
        // A camera network's file is no MLP's, nor the other way round.
        let e = from_safetensors(tiny(), &bytes, "").unwrap_err();
        assert_eq!(e.to_string(), "lacks parameter `conv1.bias`");
        let camera = to_safetensors(&Params::init(tiny(), 1), "").unwrap();
        let e = from_safetensors(NetShape::mlp(2, 8, 3), &camera, "").unwrap_err();
        assert_eq!(e.to_string(), "parameter `fc1.weight` has shape [8, 18], expected [8, 2]");
    }

    #[test]
    fn prefixed_sets_share_a_file() {
        let (m, v) = (Params::init(tiny(), 2), Params::init(tiny(), 3));
        let bytes = to_safetensors_multi(&[("m.", &m), ("v.", &v)]).unwrap();
        assert_eq!(from_safetensors(tiny(), &bytes, "m.").unwrap(), m);
        assert_eq!(from_safetensors(tiny(), &bytes, "v.").unwrap(), v);
    }
}
