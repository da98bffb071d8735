//! `learner bench train --candle`: candle's own network on the same update, the "before" of
//! fastnet.

use anyhow::Result;

use super::machine::median_ms;
use agent::NetShape;
use agent::fastnet::Params;
use learner::training::dqn::Batch;

/// The median time of [`candle_step`] over `runs` runs, ms.
pub fn candle_ms_per_update(shape: &NetShape, params: &Params, b: &Batch, runs: usize) -> Result<f64> {
    candle_step(shape, params, b)?;
    Ok(median_ms(runs, || {
        if let Err(e) = candle_step(shape, params, b) {
            tracing::error!("candle step: {e}");
        }
    }))
}

/// candle's own forward and backward passes of one update (target forward on the next states,
/// online forward, a clipped squared loss, backward): the "before" of the fast implementation. The optimizer
/// step is left out, which only flatters candle.
fn candle_step(shape: &NetShape, params: &Params, b: &Batch) -> candle_core::Result<()> {
    use agent::candle_net::{images_tensor, network, var_map};
    use candle_core::{D, Device, Tensor};
    let dev = Device::Cpu;
    let vars = var_map(params)?;
    let net = network(&vars, *shape, &dev)?;
    let n = b.len();
    let frame = shape.image_bytes();
    let images = |bytes: &[u8]| images_tensor(&(0..n).map(|i| &bytes[i * frame..(i + 1) * frame]).collect::<Vec<_>>(), shape, &dev);
    let scalars = |v: &[f32]| Tensor::from_slice(v, (n, shape.scalars), &dev);
    let q_next = net.forward(&images(&b.next_images)?, &scalars(&b.next_scalars)?)?.max(D::Minus1)?.detach();
    let y = (Tensor::from_slice(&b.rewards, n, &dev)? + (Tensor::from_slice(&b.discounts, n, &dev)? * q_next)?)?;
    let q = net.forward(&images(&b.images)?, &scalars(&b.scalars)?)?;
    let taken = q.gather(&Tensor::from_slice(&b.actions, (n, 1), &dev)?, 1)?.squeeze(1)?;
    let td = (taken - y)?;
    let loss = td.abs()?.minimum(1.0)?.sqr()?.mean_all()?;
    loss.backward()?;
    Ok(())
}
