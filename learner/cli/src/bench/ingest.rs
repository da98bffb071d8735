//! `learner bench ingest`: transitions per second an in-process learner accepts over gRPC on
//! loopback, per durability mode, optionally over mutual TLS.

use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use proto::v1 as pb;

use super::machine::load_average;
use super::synthetic_actor::SyntheticActor;
use agent::config::{Durability, RunConfig};
use learner::serve::{ServeOptions, start};

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
    let reg = client
        .register(pb::RegisterRequest { name: "bench".into(), envs: 1, protocol: proto::v1::PROTOCOL, ..Default::default() })
        .await?
        .into_inner();
    let mut actor = SyntheticActor::new(reg.actor_id.clone());
    // Keep a window of batches in flight: a pipelined stream, as actors send.
    let (tx, rx) = tokio::sync::mpsc::channel::<pb::ExperienceBatch>(8);
    let mut acks = client.stream_experience(tokio_stream::wrappers::ReceiverStream::new(rx)).await?.into_inner();
    let deadline = Instant::now() + Duration::from_secs_f64(seconds);
    let producer = tokio::spawn(async move {
        while Instant::now() < deadline {
            if tx.send(actor.next_batch(64)).await.is_err() {
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
    let log_bytes = learner::service::status(&running.shared).replay_log_bytes;
    running.stop().await?;
    let resume = if durability == Durability::Ack {
        let t = Instant::now();
        let again = start(ServeOptions { config: Some(cfg_path.clone()), resume: true, ..ServeOptions::default() }).await?;
        let secs = t.elapsed().as_secs_f64();
        let replay_size = learner::service::status(&again.shared).replay_size;
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
