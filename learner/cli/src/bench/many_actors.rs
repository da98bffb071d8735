//! `learner bench ingest --actors N`: many actors against a learner that trains, each on its own
//! connection, with the replay ratio's hold on and off: how promptly Status answers meanwhile,
//! and the transitions stored per second (issue 52: a held learner must still look alive).

use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use proto::v1 as pb;
use tokio::time::timeout_at;

use super::machine::{cpu_model, load_average};
use super::synthetic_actor::SyntheticActor;
use agent::config::{Durability, RunConfig};
use learner::serve::{ServeOptions, start};

/// Steps per batch, as a small actor sends them.
const BATCH_STEPS: u32 = 16;

/// Pause between two Status calls of the poller (a scraper polls; it does not hammer).
const STATUS_EVERY: Duration = Duration::from_millis(100);

/// [`one_run`] with the hold on (`update_lag_limit` 4, the default) and then off (0).
pub async fn many_actors(actors: usize, seconds: f64, durability: Durability) -> Result<serde_json::Value> {
    let load_before = load_average();
    let mut by = serde_json::Map::new();
    for (hold, limit) in [("on", 4), ("off", 0)] {
        let m = one_run(actors, seconds, durability, limit).await?;
        tracing::info!(hold, stored_per_sec = m["stored_per_sec"].as_f64(), status_p99_ms = m["status_p99_ms"].as_f64(), "measured");
        by.insert(hold.into(), m);
    }
    Ok(serde_json::json!({
        "actors": actors,
        "seconds": seconds,
        "batch_steps": BATCH_STEPS,
        "frame": "84x84x1",
        "durability": durability.name(),
        "by_hold": by,
        "cpu": cpu_model(),
        "load_before": load_before,
        "load_after": load_average(),
    }))
}

/// A learner with the default configuration but `service.update_lag_limit = limit`, and `actors`
/// actors streaming batches of [`BATCH_STEPS`] 84×84 gray transitions as fast as it takes them
/// for `seconds` (counted once every actor has registered), while one client asks for Status
/// every [`STATUS_EVERY`].
async fn one_run(actors: usize, seconds: f64, durability: Durability, limit: u64) -> Result<serde_json::Value> {
    let dir = std::env::temp_dir().join(format!("learner-bench-actors-{}-{limit}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut cfg = RunConfig::default();
    cfg.service.durability = durability;
    cfg.service.update_lag_limit = limit;
    cfg.service.listen = "127.0.0.1:0".into();
    cfg.service.run_dir = dir.display().to_string();
    let cfg_path = dir.with_extension("toml");
    std::fs::write(&cfg_path, cfg.to_toml())?;
    let running = start(ServeOptions { config: Some(cfg_path.clone()), ..ServeOptions::default() }).await?;
    let target = proto::client::Target::new(&running.addr.to_string(), None, false)?;

    let registered = std::sync::Arc::new(tokio::sync::Barrier::new(actors + 1));
    let go = std::sync::Arc::new(tokio::sync::watch::Sender::new(None::<tokio::time::Instant>));
    let tasks: Vec<_> = (0..actors)
        .map(|k| {
            let (target, registered, mut deadline) = (target.clone(), registered.clone(), go.subscribe());
            tokio::spawn(async move {
                let mut client = proto::client::connect_to(&target, None).await?;
                let reg = client
                    .register(pb::RegisterRequest { name: format!("bench-{k}"), envs: 1, protocol: pb::PROTOCOL, ..Default::default() })
                    .await?
                    .into_inner();
                registered.wait().await;
                let deadline = *deadline.wait_for(Option::is_some).await?.as_ref().expect("set");
                stream_until(&mut client, reg.actor_id, deadline).await
            })
        })
        .collect();
    registered.wait().await;
    let mut status = proto::client::connect_to(&target, None).await?;
    let first = status.status(pb::StatusRequest {}).await?.into_inner();
    let started = Instant::now();
    let deadline = tokio::time::Instant::now() + Duration::from_secs_f64(seconds);
    go.send_replace(Some(deadline));
    let mut latencies = Vec::new();
    while tokio::time::Instant::now() < deadline {
        let t = Instant::now();
        status.status(pb::StatusRequest {}).await?;
        latencies.push(t.elapsed().as_secs_f64() * 1000.0);
        tokio::time::sleep(STATUS_EVERY).await;
    }
    let last = status.status(pb::StatusRequest {}).await?.into_inner();
    let secs = started.elapsed().as_secs_f64();
    for t in tasks {
        t.await.context("an actor task")?.context("an actor")?;
    }
    running.stop().await?;
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&cfg_path);
    if latencies.is_empty() {
        bail!("no Status call completed in {seconds} s");
    }
    latencies.sort_by(f64::total_cmp);
    let at = |q: f64| latencies[((latencies.len() - 1) as f64 * q).round() as usize];
    let stored = last.transitions_stored - first.transitions_stored;
    let updates = last.learner_step - first.learner_step;
    Ok(serde_json::json!({
        "update_lag_limit": limit,
        "stored_per_sec": stored as f64 / secs,
        "updates_per_sec": updates as f64 / secs,
        "updates_per_1000_stored": if stored > 0 { 1000.0 * updates as f64 / stored as f64 } else { 0.0 },
        "status_calls": latencies.len(),
        "status_p50_ms": at(0.5),
        "status_p99_ms": at(0.99),
        "status_max_ms": at(1.0),
        "held_secs": last.held_secs - first.held_secs,
    }))
}

/// Streams batches (two in flight, as an actor's outbox sends them) until `deadline`.
async fn stream_until(client: &mut proto::client::Client, actor_id: String, deadline: tokio::time::Instant) -> Result<()> {
    let (tx, rx) = tokio::sync::mpsc::channel::<pb::ExperienceBatch>(2);
    let mut acks = client.stream_experience(tokio_stream::wrappers::ReceiverStream::new(rx)).await?.into_inner();
    let producer = tokio::spawn(async move {
        let mut actor = SyntheticActor::new(actor_id);
        loop {
            let batch = actor.next_batch(BATCH_STEPS);
            if tx.send(batch).await.is_err() {
                break;
            }
        }
    });
    while let Ok(ack) = timeout_at(deadline, acks.message()).await {
        if ack.context("reading acknowledgements")?.is_none() {
            break;
        }
    }
    producer.abort();
    Ok(())
}
