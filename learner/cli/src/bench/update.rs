//! `learner bench train`: full DQN updates and forward passes of the paper network (or of the
//! multilayer perceptron of a vector input), in f32 and bf16, as fractions of the machine's GEMM
//! peak.

use std::time::Instant;

use anyhow::{Context, Result, bail};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::candle::candle_ms_per_update;
use super::machine::{CALIBRATION_N, bf16_peak_gflops, cpu_model, gemm_peak_gflops, load_average, rate, update_flops};
use agent::NetShape;
use agent::config::AgentConfig;
use agent::fastnet::{FastNet, Precision};
use learner::training::dqn::{Batch, Dqn};

/// A batch of random transitions for the network of `shape` (scalar inputs in 0–1).
fn random_batch(shape: &NetShape, batch: usize) -> Batch {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let frame = shape.image_bytes();
    let mut bytes = |n: usize| -> Vec<u8> { (0..n).map(|_| (rng.next_u32() & 0xff) as u8).collect() };
    let (images, next_images) = (bytes(batch * frame), bytes(batch * frame));
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let mut floats = |n: usize| -> Vec<f32> { (0..n).map(|_| rng.next_u32() as f32 / u32::MAX as f32).collect() };
    Batch {
        images,
        next_images,
        scalars: floats(batch * shape.scalars),
        next_scalars: floats(batch * shape.scalars),
        actions: (0..batch as u32).map(|i| i % shape.actions as u32).collect(),
        rewards: floats(batch),
        discounts: vec![0.99; batch],
        weights: vec![1.0; batch],
        demos: 0,
    }
}

/// Times full DQN updates (online forward and backward, target forward on the next states,
/// optimizer step) of the network of `shape` (`input` names it in the output), trained as `agent`
/// says (its double DQN and loss; its precision is replaced by each of `precisions`), with batch
/// `batch` on `threads` threads,
/// and forward passes at batch 1 and at `forward_batch`, in each of `precisions` (`f32`, `bf16`),
/// alternating between them call by call so that both see the same machine; calibrates the
/// machine (a square f32 GEMM on 1 and on `threads` threads, and a bf16 one where a bf16 kernel
/// runs) and gives each figure as a fraction of that peak. With one precision the figures are top-level
/// fields; with two, each has its own object and `bf16_over_f32` their ratios. With `reference`,
/// also times candle's own implementation of the same update's forward and backward passes.
///
/// # Errors
/// `bf16` where no bf16 kernel runs (the message says why), or candle's failure.
#[allow(clippy::too_many_arguments)]
pub fn train(
    shape: NetShape,
    input: &str,
    agent: &AgentConfig,
    batch: usize,
    forward_batch: usize,
    updates: usize,
    threads: usize,
    reference: bool,
    precisions: &[Precision],
) -> Result<serde_json::Value> {
    let chosen: Vec<(Precision, bool)> = precisions
        .iter()
        .map(|&p| Ok((p, p.resolve().with_context(|| format!("--precision {}", p.name()))?.bf16)))
        .collect::<Result<_>>()?;
    let load_before = load_average();
    let peak_1 = gemm_peak_gflops(1, 5);
    let peak = if threads == 1 { peak_1 } else { gemm_peak_gflops(threads, 5) };
    let peak_bf16 = agent::fastnet::bf16_matmul::available().is_ok().then(|| bf16_peak_gflops(5));
    tracing::info!(peak_gflops_1_thread = peak_1, peak_gflops = peak, ?peak_bf16, threads, "GEMM calibration");
    let update_batch = random_batch(&shape, batch);
    let b = random_batch(&shape, forward_batch);
    let (frame, s) = (shape.image_bytes(), shape.scalars);
    let mut paths: Vec<(Dqn, FastNet)> = chosen
        .iter()
        .map(|&(p, bf16)| {
            let cfg = AgentConfig { precision: p, ..agent.clone() };
            (Dqn::with_threads(shape, &cfg, threads), FastNet::with_precision(shape, threads, bf16))
        })
        .collect();
    let update_ms = alternating_median_ms(updates, &mut paths, |(dqn, _)| {
        dqn.update(&update_batch);
    });
    let forward_1 = alternating_median_ms(updates.max(20), &mut paths, |(dqn, net)| {
        net.forward(&dqn.online, &b.images[..frame], &b.scalars[..s]);
    });
    let forward_b = alternating_median_ms(updates.max(10), &mut paths, |(dqn, net)| {
        net.forward(&dqn.online, &b.images, &b.scalars);
    });
    let f = shape.forward_flops();
    let figures: Vec<serde_json::Value> = chosen
        .iter()
        .enumerate()
        .map(|(i, &(p, bf16))| {
            let (ms, per_sample) = (update_ms[i], forward_b[i] / forward_batch as f64);
            tracing::info!(precision = p.name(), bf16, ms_per_update = ms, forward_batch1_ms = forward_1[i], "timed");
            let (gf_1, frac_1) = rate(f, forward_1[i], peak);
            let (gf_b, frac_b) = rate(f, per_sample, peak);
            let (gf_u, frac_u) = rate(update_flops(&shape, batch, agent.double_dqn), ms, peak);
            serde_json::json!({
                "precision": if bf16 { "bf16" } else { "f32" },
                "updates_per_sec": 1000.0 / ms,
                "ms_per_update": ms,
                "update_gflops": gf_u,
                "update_fraction_of_peak": frac_u,
                "forward_batch1_ms": forward_1[i],
                "forward_batch1_gflops": gf_1,
                "forward_batch1_fraction_of_peak": frac_1,
                "forward_ms_per_sample": per_sample,
                "forward_gflops": gf_b,
                "forward_fraction_of_peak": frac_b,
            })
        })
        .collect();
    let mut out = serde_json::json!({
        "batch": batch,
        "input": input,
        "net": if shape.has_image() { "conv" } else { "mlp" },
        "scalars": shape.scalars,
        "actions": shape.actions,
        "hidden": shape.hidden,
        "double_dqn": agent.double_dqn,
        "threads": threads,
        // What the network runs on: one thread for a network with no image (`FastNet::new`).
        "network_threads": paths[0].1.threads(),
        "forward_batch": forward_batch,
        "forward_mflop_per_image": f / 1e6,
        "peak_gflops_1_thread": peak_1,
        "peak_gflops": peak,
        "calibration": format!("{CALIBRATION_N}x{CALIBRATION_N}x{CALIBRATION_N} f32 GEMM, median of 5"),
        "peak_gflops_bf16_1_thread": peak_bf16,
        "amx": agent::fastnet::amx::available().err().unwrap_or("available"),
        "bf16_kernel": agent::fastnet::bf16_matmul::available().map_or_else(|why| format!("none: {why}"), |k| k.name().to_string()),
        "cpu": cpu_model(),
        "implementation": "fastnet",
        "load_before": load_before,
    });
    match figures.as_slice() {
        [one] => merge(&mut out, one),
        [f32, bf16] => {
            let ratio = |k: &str| bf16[k].as_f64().zip(f32[k].as_f64()).map(|(b, f)| b / f);
            out["precision"] = "both".into();
            out["bf16_over_f32"] = serde_json::json!({
                "ms_per_update": ratio("ms_per_update"),
                "forward_batch1_ms": ratio("forward_batch1_ms"),
                "forward_ms_per_sample": ratio("forward_ms_per_sample"),
            });
            out["f32"] = f32.clone();
            out["bf16"] = bf16.clone();
        }
        _ => bail!("bench train: one or two precisions, not {}", figures.len()),
    }
    if reference {
        let candle_ms = candle_ms_per_update(&shape, &paths[0].0.online, &update_batch, updates.min(3))?;
        tracing::info!(candle_ms_per_update = candle_ms, "candle reference timed");
        out["candle_ms_per_update"] = serde_json::json!(candle_ms);
        out["speedup_over_candle"] = serde_json::json!(candle_ms / update_ms[0]);
    }
    out["load_after"] = serde_json::json!(load_average());
    Ok(out)
}

/// Copies `from`'s fields into `into`.
fn merge(into: &mut serde_json::Value, from: &serde_json::Value) {
    if let (Some(into), Some(from)) = (into.as_object_mut(), from.as_object()) {
        into.extend(from.iter().map(|(k, v)| (k.clone(), v.clone())));
    }
}

/// The median milliseconds of `f` on each of `items`, calling them in turn `reps` times (after
/// one warm-up call each), so that a change in the machine's speed reaches all alike.
fn alternating_median_ms<T>(reps: usize, items: &mut [T], mut f: impl FnMut(&mut T)) -> Vec<f64> {
    items.iter_mut().for_each(&mut f);
    let mut times = vec![Vec::with_capacity(reps); items.len()];
    for _ in 0..reps.max(1) {
        for (item, t) in items.iter_mut().zip(&mut times) {
            let start = Instant::now();
            f(item);
            t.push(start.elapsed().as_secs_f64() * 1000.0);
        }
    }
    times
        .into_iter()
        .map(|mut t| {
            t.sort_by(f64::total_cmp);
            t[t.len() / 2]
        })
        .collect()
}
