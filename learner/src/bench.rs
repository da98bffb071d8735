//! `learner bench`: the cost of a full DQN update, and ingestion throughput over gRPC on loopback.

use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use proto::v1 as pb;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::dqn::{Batch, Dqn};
use crate::serve::{ServeOptions, start};
use agent::NetShape;
use agent::config::{AgentConfig, Durability, RunConfig};
use agent::fastnet::{FastNet, Params, Precision};

/// Parses `WxHxC`, e.g. `84x84x3`.
pub fn parse_input(s: &str) -> Result<(usize, usize, usize), String> {
    let parts: Vec<&str> = s.split('x').collect();
    let [w, h, c] = parts.as_slice() else { return Err(format!("`{s}` is not WIDTHxHEIGHTxCHANNELS, e.g. 84x84x3")) };
    let num = |v: &str| v.parse::<usize>().map_err(|_| format!("`{v}` in `{s}` is not a whole number"));
    let (w, h, c) = (num(w)?, num(h)?, num(c)?);
    if !(8..=1024).contains(&w) || !(8..=1024).contains(&h) || !(c == 1 || c == 3) {
        return Err(format!("`{s}`: width and height must be 8..=1024 and channels 1 or 3"));
    }
    Ok((w, h, c))
}

/// The system's 1-minute load average, to print beside timings (2-thread figures collapse on a
/// busy machine).
fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg").ok()?.split_whitespace().next()?.parse().ok()
}

/// The CPU's model name (`/proc/cpuinfo`), to print beside timings.
fn cpu_model() -> Option<String> {
    let text = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("model name"))?;
    Some(line.split_once(':')?.1.trim().to_owned())
}

/// Side of the square matrices the calibration multiplies.
const CALIBRATION_N: usize = 1024;

/// The machine's practical limit: GFLOP/s of a square `CALIBRATION_N` f32 matrix product on
/// `threads` threads through the same `gemm` crate the network uses (the median of `reps`
/// products after a warm-up). The figures below are read as fractions of it.
#[must_use]
pub fn gemm_peak_gflops(threads: usize, reps: usize) -> f64 {
    use agent::fastnet::gemm::{View, matmul};
    let n = CALIBRATION_N;
    let a: Vec<f32> = (0..n * n).map(|i| ((i * 7 + 3) % 1000) as f32 / 500.0 - 1.0).collect();
    let b: Vec<f32> = (0..n * n).map(|i| ((i * 13 + 5) % 1000) as f32 / 500.0 - 1.0).collect();
    let mut c = vec![0f32; n * n];
    let v = View::rows(0, n, n, n);
    let ms = median_ms(reps, || matmul(&mut c, v, false, &a, v, &b, v, threads));
    2.0 * (n * n * n) as f64 / (ms * 1e6)
}

/// Floating-point operations of one DQN update of `batch` transitions: the target network's
/// forward pass on the next states (and the online network's too for double DQN), the online
/// forward pass and its backward pass. The optimizer's few element-wise passes are left out.
#[must_use]
pub fn update_flops(shape: &NetShape, batch: usize, double_dqn: bool) -> f64 {
    let forwards = if double_dqn { 3.0 } else { 2.0 };
    batch as f64 * (forwards * shape.forward_flops() + shape.backward_flops())
}

/// GFLOP/s of `flops` done in `ms`, and that as a fraction of `peak` GFLOP/s.
fn rate(flops: f64, ms: f64, peak: f64) -> (f64, f64) {
    let gflops = flops / (ms * 1e6);
    (gflops, gflops / peak)
}

/// A batch of random transitions for the paper's network at `shape`.
fn random_batch(shape: &NetShape, batch: usize) -> Batch {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let frame = shape.height * shape.width * shape.channels;
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
    }
}

/// Milliseconds per call of `f`, the median of `reps` timed calls after one warm-up call.
fn median_ms(reps: usize, mut f: impl FnMut()) -> f64 {
    f();
    let mut t: Vec<f64> = (0..reps.max(1))
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1000.0
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Times full DQN updates (online forward and backward, target forward on the next states,
/// optimizer step) of the paper's network at `input` with batch `batch` on `threads` threads,
/// and forward passes at batch 1 and at `forward_batch`, in each of `precisions` (`f32`, `bf16`),
/// alternating between them call by call so that both see the same machine; calibrates the
/// machine (a square f32 GEMM on 1 and on `threads` threads, and a bf16 one where AMX runs) and
/// gives each figure as a fraction of that peak. With one precision the figures are top-level
/// fields; with two, each has its own object and `bf16_over_f32` their ratios. With `reference`,
/// also times candle's own implementation of the same update's forward and backward passes.
///
/// # Errors
/// `bf16` where AMX is absent (the message says why), or candle's failure.
pub fn train(
    input: (usize, usize, usize),
    batch: usize,
    forward_batch: usize,
    updates: usize,
    threads: usize,
    reference: bool,
    precisions: &[Precision],
) -> Result<serde_json::Value> {
    let (w, h, c) = input;
    let agent = AgentConfig::default();
    let shape = NetShape { height: h, width: w, channels: c, scalars: 2, actions: 6, filters: agent.conv_filters, hidden: agent.hidden };
    let chosen: Vec<(Precision, bool)> = precisions
        .iter()
        .map(|&p| Ok((p, p.resolve().with_context(|| format!("--precision {}", p.name()))?.bf16)))
        .collect::<Result<_>>()?;
    let load_before = load_average();
    let peak_1 = gemm_peak_gflops(1, 5);
    let peak = if threads == 1 { peak_1 } else { gemm_peak_gflops(threads, 5) };
    let peak_bf16 = agent::fastnet::amx::available().is_ok().then(|| bf16_peak_gflops(5));
    tracing::info!(peak_gflops_1_thread = peak_1, peak_gflops = peak, ?peak_bf16, threads, "GEMM calibration");
    let update_batch = random_batch(&shape, batch);
    let b = random_batch(&shape, forward_batch);
    let (frame, s) = (h * w * c, shape.scalars);
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
        "input": format!("{w}x{h}x{c}"),
        "threads": threads,
        "forward_batch": forward_batch,
        "forward_mflop_per_image": f / 1e6,
        "peak_gflops_1_thread": peak_1,
        "peak_gflops": peak,
        "calibration": format!("{CALIBRATION_N}x{CALIBRATION_N}x{CALIBRATION_N} f32 GEMM, median of 5"),
        "peak_gflops_bf16_1_thread": peak_bf16,
        "amx": agent::fastnet::amx::available().err().unwrap_or("available"),
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

/// The machine's bf16 limit as this code reaches it: GFLOP/s of a square `CALIBRATION_N` bf16
/// product on one thread through the AMX kernel (`agent::fastnet::amx`), median of `reps`.
fn bf16_peak_gflops(reps: usize) -> f64 {
    use agent::fastnet::amx::{AView, PackedB, matmul};
    use agent::fastnet::gemm::View;
    let n = CALIBRATION_N;
    let a: Vec<u16> = (0..n * n).map(|i| agent::fastnet::bf16::from_f32(((i * 7 + 3) % 1000) as f32 / 500.0 - 1.0)).collect();
    let b: Vec<f32> = (0..n * n).map(|i| ((i * 13 + 5) % 1000) as f32 / 500.0 - 1.0).collect();
    let mut packed = PackedB::default();
    packed.pack(&b, View::rows(0, n, n, n));
    let mut c = vec![0f32; n * n];
    let ms = median_ms(reps, || matmul(&mut c, View::rows(0, n, n, n), false, &a, AView::rows(0, n, n, n), &packed));
    2.0 * (n * n * n) as f64 / (ms * 1e6)
}

/// The median time of [`candle_step`] over `runs` runs, ms.
#[cfg(feature = "reference")]
fn candle_ms_per_update(shape: &NetShape, params: &Params, b: &Batch, runs: usize) -> Result<f64> {
    candle_step(shape, params, b)?;
    Ok(median_ms(runs, || {
        if let Err(e) = candle_step(shape, params, b) {
            tracing::error!("candle reference step: {e}");
        }
    }))
}

#[cfg(not(feature = "reference"))]
fn candle_ms_per_update(_: &NetShape, _: &Params, _: &Batch, _: usize) -> Result<f64> {
    bail!("--reference needs the learner built with its `reference` feature (candle)")
}

/// candle's own forward and backward passes of one update (target forward on the next states,
/// online forward, a clipped squared loss, backward): the "before" of the fast implementation. The optimizer
/// step is left out, which only flatters candle.
#[cfg(feature = "reference")]
fn candle_step(shape: &NetShape, params: &Params, b: &Batch) -> candle_core::Result<()> {
    use agent::reference::{images_tensor, network, var_map};
    use candle_core::{D, Device, Tensor};
    let dev = Device::Cpu;
    let vars = var_map(params)?;
    let net = network(&vars, *shape, &dev)?;
    let n = b.len();
    let frame = shape.height * shape.width * shape.channels;
    let images = |bytes: &[u8]| images_tensor(&bytes.chunks_exact(frame).collect::<Vec<_>>(), shape, &dev);
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

/// [`ingest_one`] for each of `modes`, in the same run: `transitions_per_sec` is the last mode's,
/// and `by_durability` has each (`none` is the learner before the replay log; `ack` acknowledges a
/// batch once it is synced to disk), with, for `ack`, the replay log's size and the time a
/// `--resume` took to rebuild the replay from it (`resume_secs`).
pub async fn ingest(seconds: f64, modes: &[Durability], tls: bool) -> Result<serde_json::Value> {
    let load_before = load_average();
    let mut by = serde_json::Map::new();
    let mut last = 0.0;
    for &mode in modes {
        let m = ingest_one(seconds, mode, tls).await?;
        last = m.transitions_per_sec;
        tracing::info!(durability = mode.name(), transitions_per_sec = last, "ingestion measured");
        by.insert(mode.name().into(), serde_json::json!(last));
        if let Some(r) = m.resume {
            by.insert("ack_replay_log_bytes".into(), serde_json::json!(r.log_bytes));
            by.insert("ack_resume_secs".into(), serde_json::json!(r.secs));
            by.insert("ack_resume_replay_size".into(), serde_json::json!(r.replay_size));
        }
    }
    Ok(serde_json::json!({
        "transitions_per_sec": last,
        "by_durability": by,
        "tls": tls,
        "load_before": load_before,
        "load_after": load_average(),
    }))
}

/// What [`ingest_one`] measured.
#[derive(Debug, Clone, Copy)]
pub struct Ingested {
    pub transitions_per_sec: f64,
    /// With a replay log: rebuilding the replay from it.
    pub resume: Option<Resumed>,
}

#[derive(Debug, Clone, Copy)]
pub struct Resumed {
    pub log_bytes: u64,
    pub secs: f64,
    pub replay_size: u64,
}

/// Streams batches of 64 transitions of 84×84 gray frames to an in-process learner on loopback for
/// `seconds` and counts the transitions acknowledged per second. Training is held off (the replay
/// never reaches its minimum) so that only ingestion is measured. The run directory is under the
/// system's temporary directory: with `durability = "ack"`, its disk is what is measured. With
/// `tls`, the learner serves mutual TLS with certificates made in that directory
/// (`crate::certs`), and the client presents one.
pub async fn ingest_one(seconds: f64, durability: Durability, tls: bool) -> Result<Ingested> {
    let dir = std::env::temp_dir().join(format!("learner-bench-ingest-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut cfg = RunConfig::default();
    cfg.service.durability = durability;
    cfg.agent.replay_capacity = 200_000;
    cfg.agent.min_replay = 200_000;
    cfg.service.listen = "127.0.0.1:0".into();
    cfg.service.run_dir = dir.display().to_string();
    cfg.service.checkpoint_interval_secs = 3600;
    let target = if tls {
        let certs = dir.join("certs");
        crate::certs::write_set(&certs, &["127.0.0.1".to_owned()], 1)?;
        cfg.service.tls_cert = certs.join(crate::certs::SERVER_CERT).display().to_string();
        cfg.service.tls_key = certs.join(crate::certs::SERVER_KEY).display().to_string();
        cfg.service.tls_client_ca = certs.join(crate::certs::CA_CERT).display().to_string();
        Some(proto::client::TlsFiles {
            ca: certs.join(crate::certs::CA_CERT),
            identity: Some((certs.join(crate::certs::CLIENT_CERT), certs.join(crate::certs::CLIENT_KEY))),
        })
    } else {
        None
    };
    let cfg_path = dir.with_extension("toml");
    std::fs::write(&cfg_path, cfg.to_toml())?;
    let running = start(ServeOptions { config: Some(cfg_path.clone()), ..ServeOptions::default() }).await?;
    let target = proto::client::Target::new(&running.addr.to_string(), target, false)?;
    let mut client = proto::client::connect_to(&target, None).await?;
    let reg = client.register(pb::RegisterRequest { name: "bench".into(), envs: 1, protocol: proto::v1::PROTOCOL }).await?.into_inner();
    let frame = vec![100u8; 84 * 84];
    let actor_id = reg.actor_id.clone();
    let (mut episode, mut t) = (0u64, 0u32);
    let mut make_batch = move |seq: u64| {
        let steps = (0..64)
            .map(|_| {
                let s = pb::Step {
                    env: 0,
                    episode,
                    t,
                    obs: Some(pb::Observation { image: frame.clone(), speed: 1.0, d: 0.5, path: Vec::new() }),
                    action: 1,
                    reward: 0.1,
                    terminated: false,
                    truncated: t == 199,
                };
                t += 1;
                if t == 200 {
                    t = 0;
                    episode += 1;
                }
                s
            })
            .collect();
        pb::ExperienceBatch { actor_id: actor_id.clone(), seq, steps, episodes: vec![], weights_version: 1, epsilon: 1.0, dropped_steps: 0 }
    };
    // Keep a window of batches in flight: a pipelined stream, as actors send.
    let (tx, rx) = tokio::sync::mpsc::channel::<pb::ExperienceBatch>(8);
    let mut acks = client.stream_experience(tokio_stream::wrappers::ReceiverStream::new(rx)).await?.into_inner();
    let deadline = Instant::now() + Duration::from_secs_f64(seconds);
    let producer = tokio::spawn(async move {
        let mut seq = 0u64;
        while Instant::now() < deadline {
            seq += 1;
            if tx.send(make_batch(seq)).await.is_err() {
                break;
            }
        }
    });
    let start_t = Instant::now();
    let mut stored = 0u64;
    while let Some(ack) = acks.message().await.context("reading acknowledgements")? {
        stored += u64::from(ack.stored);
        if Instant::now() >= deadline {
            break;
        }
    }
    let secs = start_t.elapsed().as_secs_f64();
    producer.abort();
    drop(acks);
    let log_bytes = crate::service::status(&running.shared).replay_log_bytes;
    running.stop().await?;
    let resume = if durability == Durability::Ack {
        let t = Instant::now();
        let again = start(ServeOptions { config: Some(cfg_path.clone()), resume: true, ..ServeOptions::default() }).await?;
        let secs = t.elapsed().as_secs_f64();
        let replay_size = crate::service::status(&again.shared).replay_size;
        again.stop().await?;
        Some(Resumed { log_bytes, secs, replay_size })
    } else {
        None
    };
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&cfg_path);
    if stored == 0 {
        bail!("no transition was acknowledged");
    }
    Ok(Ingested { transitions_per_sec: stored as f64 / secs, resume })
}

/// Runs a learner here (default configuration, so the paper network at the default camera) and
/// `actors` actor processes (the `actor` program next to this one) for `seconds`, and measures
/// what they produce: environment steps per second, updates per second, and the mean lag
/// between the newest weights and the weights actors act with (sampled every second).
///
/// Without `train`, the learner only ingests (its replay never reaches its minimum): the actors'
/// own rate with nothing else on the cores.
///
/// `precision` is the run's `[agent] precision` (learner and actors alike).
pub async fn e2e(
    actors: usize,
    envs: usize,
    seconds: f64,
    train: bool,
    durability: Durability,
    precision: Precision,
) -> Result<serde_json::Value> {
    let chosen = precision.resolve().with_context(|| format!("--precision {}", precision.name()))?;
    let exe = std::env::current_exe()?;
    let actor_exe = exe.with_file_name(if cfg!(windows) { "actor.exe" } else { "actor" });
    if !actor_exe.exists() {
        bail!("the actor program is not next to this one ({}): build it with `cargo build --release -p actor`", actor_exe.display());
    }
    let load_before = load_average();
    let threads = agent::fastnet::default_threads();
    let peak = gemm_peak_gflops(threads, 5);
    let mut cfg = RunConfig::default();
    cfg.service.durability = durability;
    cfg.agent.precision = precision;
    if !train {
        cfg.agent.min_replay = cfg.agent.replay_capacity;
    }
    let dir = std::env::temp_dir().join(format!("learner-bench-e2e-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir)?;
    let cfg_path = dir.join("bench.toml");
    std::fs::write(&cfg_path, cfg.to_toml())?;
    let running = start(ServeOptions {
        config: Some(cfg_path),
        listen: Some("127.0.0.1:0".into()),
        run_dir: Some(dir.join("run")),
        ..ServeOptions::default()
    })
    .await?;
    let addr = running.addr.to_string();
    let mut children = Vec::new();
    for k in 0..actors {
        children.push(
            std::process::Command::new(&actor_exe)
                .args(["--learner", &addr, "--envs", &envs.to_string(), "--id", &format!("bench-{k}"), "--seed", &k.to_string()])
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::null())
                .spawn()
                .with_context(|| format!("starting {}", actor_exe.display()))?,
        );
    }
    // Warm-up: until every actor has delivered something.
    let warm = Instant::now();
    while running.shared.actors.lock().expect("actors lock").iter().filter(|a| a.transitions > 0).count() < actors {
        if warm.elapsed() > Duration::from_secs(120) {
            bail!("actors did not start streaming within 120 s");
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let counters = |r: &crate::serve::Running| {
        let c = r.shared.counters.lock().expect("counters lock");
        (c.env_steps, c.learner_step, r.shared.stats.lock().expect("stats lock").idle_secs)
    };
    let (s0, u0, idle0) = counters(&running);
    let t0 = Instant::now();
    let mut lags = Vec::new();
    while t0.elapsed().as_secs_f64() < seconds {
        tokio::time::sleep(Duration::from_secs(1)).await;
        let st = crate::service::status(&running.shared);
        lags.extend(st.actors.iter().filter(|a| a.connected).map(|a| a.version_lag as f64));
        tracing::info!(secs = t0.elapsed().as_secs(), env_steps = st.transitions_received, updates = st.learner_step, "benchmarking");
    }
    let (s1, u1, idle1) = counters(&running);
    let secs = t0.elapsed().as_secs_f64();
    for c in &mut children {
        let _ = c.kill();
        let _ = c.wait();
    }
    running.stop().await?;
    let _ = std::fs::remove_dir_all(&dir);
    let mean_lag = if lags.is_empty() { 0.0 } else { lags.iter().sum::<f64>() / lags.len() as f64 };
    let (steps_per_sec, updates_per_sec) = ((s1 - s0) as f64 / secs, (u1 - u0) as f64 / secs);
    // The arithmetic the run did: one forward pass per environment step, and the updates'.
    let shape = cfg.net_shape();
    let gflops =
        (steps_per_sec * shape.forward_flops() + updates_per_sec * update_flops(&shape, cfg.agent.batch_size, cfg.agent.double_dqn)) / 1e9;
    Ok(serde_json::json!({
        "env_steps_per_sec": steps_per_sec,
        "updates_per_sec": updates_per_sec,
        "gflops": gflops,
        "peak_gflops": peak,
        "fraction_of_peak": gflops / peak,
        "threads": threads,
        "cpu": cpu_model(),
        "mean_weight_lag": mean_lag,
        "learner_idle_fraction": ((idle1 - idle0) / secs).clamp(0.0, 1.0),
        "replay_ratio": cfg.agent.replay_ratio,
        "training": train,
        "precision": if chosen.bf16 { "bf16" } else { "f32" },
        "load_before": load_before,
        "load_after": load_average(),
        "actors": actors,
        "envs_per_actor": envs,
        "durability": durability.name(),
    }))
}
