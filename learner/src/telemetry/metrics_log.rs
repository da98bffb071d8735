//! The metrics log: appends the run's records (`crate::telemetry::records`) to `episodes.jsonl` and
//! `train.jsonl` in the run directory, and the same figures as TensorBoard scalars to this
//! session's `events.out.tfevents.*` file there (`crate::telemetry::tfevents`), with env steps as the step.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::Path;
use std::sync::Mutex;

use crate::telemetry::records::{EPISODES_FILE, EVAL_FILE, EpisodeRecord, EvalRecord, TRAIN_FILE, TrainRecord};
use crate::telemetry::tfevents::EventWriter;

/// Appends JSON lines to the run directory's metrics files.
#[derive(Debug)]
pub struct MetricsLog {
    episodes: Mutex<BufWriter<File>>,
    train: Mutex<BufWriter<File>>,
    eval: Mutex<BufWriter<File>>,
    events: EventWriter,
}

impl MetricsLog {
    /// Opens (appending) the files in `run_dir`.
    pub fn open(run_dir: &Path) -> std::io::Result<Self> {
        let open = |name: &str| OpenOptions::new().create(true).append(true).open(run_dir.join(name)).map(BufWriter::new);
        Ok(Self {
            episodes: Mutex::new(open(EPISODES_FILE)?),
            train: Mutex::new(open(TRAIN_FILE)?),
            eval: Mutex::new(open(EVAL_FILE)?),
            events: EventWriter::create(run_dir)?,
        })
    }

    /// Writes one episode line.
    pub fn episode(&self, e: &EpisodeRecord) -> std::io::Result<()> {
        writeln!(self.episodes.lock().expect("metrics lock"), "{}", serde_json::to_string(e)?)?;
        self.events.scalars(e.env_steps, &[("episode/return", Some(e.episode_return)), ("episode/steps", Some(f64::from(e.steps)))])
    }

    /// Writes one interval line, and flushes both files.
    pub fn interval(&self, t: &TrainRecord) -> std::io::Result<()> {
        writeln!(self.train.lock().expect("metrics lock"), "{}", serde_json::to_string(t)?)?;
        self.events.scalars(t.env_steps, &scalars(t))?;
        self.flush()
    }

    /// Writes one periodic evaluation line, flushed at once (they are few).
    pub fn eval(&self, e: &EvalRecord) -> std::io::Result<()> {
        let mut f = self.eval.lock().expect("metrics lock");
        writeln!(f, "{}", serde_json::to_string(e)?)?;
        f.flush()
    }

    /// Flushes both files.
    pub fn flush(&self) -> std::io::Result<()> {
        self.episodes.lock().expect("metrics lock").flush()?;
        self.train.lock().expect("metrics lock").flush()?;
        self.events.flush()
    }
}

/// The TensorBoard scalars of an interval: tag and value (`None` is left out).
#[must_use]
pub fn scalars(t: &TrainRecord) -> Vec<(&'static str, Option<f64>)> {
    vec![
        ("train/loss", t.loss),
        ("train/mean_q", t.mean_q),
        ("train/epsilon", Some(t.epsilon)),
        ("episodes/return_mean", t.episode_return_mean),
        ("episodes/completion_rate", t.completion_rate),
        ("episodes/collision_rate", t.collision_rate),
        ("throughput/env_steps_per_sec", Some(t.env_steps_per_sec)),
        ("throughput/updates_per_sec", Some(t.updates_per_sec)),
        ("actors/weights_lag_mean", t.weights_lag_mean),
        ("replay/size", Some(t.replay_size as f64)),
        ("train/updates", Some(t.learner_step as f64)),
    ]
}
