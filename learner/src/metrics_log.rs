//! The metrics log: appends the run's records (`crate::records`) to `episodes.jsonl` and
//! `train.jsonl` in the run directory.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::Path;
use std::sync::Mutex;

use crate::records::{EPISODES_FILE, EVAL_FILE, EpisodeRecord, EvalRecord, TRAIN_FILE, TrainRecord};

/// Appends JSON lines to the run directory's metrics files.
#[derive(Debug)]
pub struct MetricsLog {
    episodes: Mutex<BufWriter<File>>,
    train: Mutex<BufWriter<File>>,
    eval: Mutex<BufWriter<File>>,
}

impl MetricsLog {
    /// Opens (appending) the files in `run_dir`.
    pub fn open(run_dir: &Path) -> std::io::Result<Self> {
        let open = |name: &str| OpenOptions::new().create(true).append(true).open(run_dir.join(name)).map(BufWriter::new);
        Ok(Self { episodes: Mutex::new(open(EPISODES_FILE)?), train: Mutex::new(open(TRAIN_FILE)?), eval: Mutex::new(open(EVAL_FILE)?) })
    }

    /// Writes one episode line.
    pub fn episode(&self, e: &EpisodeRecord) -> std::io::Result<()> {
        writeln!(self.episodes.lock().expect("metrics lock"), "{}", serde_json::to_string(e)?)
    }

    /// Writes one interval line, and flushes both files.
    pub fn interval(&self, t: &TrainRecord) -> std::io::Result<()> {
        writeln!(self.train.lock().expect("metrics lock"), "{}", serde_json::to_string(t)?)?;
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
        self.train.lock().expect("metrics lock").flush()
    }
}
