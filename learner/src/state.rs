//! The learner's shared state: what the gRPC handlers, the training thread and the status
//! reporting all see. Locks are held briefly and never across an update or an await.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, RwLock};
use std::time::Instant;

use crate::metrics_log::MetricsLog;
use crate::records::TrainRecord;
use crate::replay::Replay;
use agent::NetShape;
use agent::checkpoint::Counters;
use agent::config::RunConfig;

/// A published version of the online network's weights.
#[derive(Debug, Clone, PartialEq)]
pub struct PublishedWeights {
    pub version: u64,
    /// A safetensors file.
    pub bytes: Arc<Vec<u8>>,
}

/// An actor the learner knows.
#[derive(Debug, Clone)]
pub struct ActorRecord {
    pub id: String,
    pub name: String,
    pub index: u32,
    pub envs: u32,
    pub last_seen: Instant,
    pub weights_version: u64,
    pub transitions: u64,
    pub rejected_batches: u64,
    pub epsilon: f32,
    pub dropped_steps: u64,
}

/// A finished episode, for the rolling statistics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpisodeOutcome {
    pub episode_return: f64,
    pub arrived: bool,
    pub collided: bool,
}

/// Training measurements for status and metrics.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TrainStats {
    pub loss: Option<f64>,
    pub mean_q: Option<f64>,
    pub updates_per_sec: f64,
    pub env_steps_per_sec: f64,
    pub epsilon: f64,
    /// Seconds the training thread has waited for data since it started (replay below its
    /// minimum, or the replay ratio reached): the learner idle for want of data.
    pub idle_secs: f64,
}

/// Everything shared between the server's tasks and the training thread.
#[derive(Debug)]
pub struct Shared {
    pub cfg: RunConfig,
    pub run_id: String,
    pub started: Instant,
    pub shape: NetShape,
    pub frame_bytes: usize,
    pub replay: Mutex<Replay>,
    pub counters: Mutex<Counters>,
    pub weights: RwLock<PublishedWeights>,
    pub actors: Mutex<Vec<ActorRecord>>,
    pub recent_episodes: Mutex<VecDeque<EpisodeOutcome>>,
    pub stats: Mutex<TrainStats>,
    pub metrics: MetricsLog,
    /// Wakes the training thread when transitions arrive.
    pub data_arrived: (Mutex<()>, Condvar),
    pub shutdown: AtomicBool,
    /// Seconds of earlier sessions of this run (from the checkpoint), for `time_secs` in metrics.
    pub elapsed_before: f64,
}

impl Shared {
    /// Seconds since the run began, across resumes.
    #[must_use]
    pub fn run_secs(&self) -> f64 {
        self.elapsed_before + self.started.elapsed().as_secs_f64()
    }

    /// Whether shutdown was requested.
    #[must_use]
    pub fn stopping(&self) -> bool {
        self.shutdown.load(Ordering::SeqCst)
    }

    /// The newest weights.
    #[must_use]
    pub fn current_weights(&self) -> PublishedWeights {
        self.weights.read().expect("weights lock").clone()
    }

    /// The current counters and training measurements as a `train.jsonl` record.
    #[must_use]
    pub fn train_record(&self) -> TrainRecord {
        let c = self.counters.lock().expect("counters lock").clone();
        let s = *self.stats.lock().expect("stats lock");
        let replay_size = self.replay.lock().expect("replay lock").len() as u64;
        let (episode_return_mean, completion_rate, collision_rate) = {
            let window = self.recent_episodes.lock().expect("episodes lock");
            let n = window.len() as f64;
            if window.is_empty() {
                (None, None, None)
            } else {
                (
                    Some(window.iter().map(|e| e.episode_return).sum::<f64>() / n),
                    Some(window.iter().filter(|e| e.arrived).count() as f64 / n),
                    Some(window.iter().filter(|e| e.collided).count() as f64 / n),
                )
            }
        };
        let weights_lag_mean = {
            let timeout = self.cfg.service.actor_timeout_secs as f64;
            let actors = self.actors.lock().expect("actors lock");
            let lags: Vec<f64> = actors
                .iter()
                .filter(|a| a.last_seen.elapsed().as_secs_f64() < timeout)
                .map(|a| c.weights_version.saturating_sub(a.weights_version) as f64)
                .collect();
            (!lags.is_empty()).then(|| lags.iter().sum::<f64>() / lags.len() as f64)
        };
        TrainRecord {
            time_secs: self.run_secs(),
            learner_step: c.learner_step,
            env_steps: c.env_steps,
            transitions_stored: c.transitions_stored,
            loss: s.loss,
            mean_q: s.mean_q,
            updates_per_sec: s.updates_per_sec,
            env_steps_per_sec: s.env_steps_per_sec,
            epsilon: s.epsilon,
            replay_size,
            weights_version: c.weights_version,
            episodes: c.episodes,
            episode_return_mean,
            completion_rate,
            collision_rate,
            weights_lag_mean,
        }
    }

    /// Records finished episodes in the rolling window.
    pub fn push_episodes(&self, outcomes: impl IntoIterator<Item = EpisodeOutcome>) {
        let mut q = self.recent_episodes.lock().expect("episodes lock");
        for o in outcomes {
            q.push_back(o);
            while q.len() > self.cfg.service.stats_window {
                q.pop_front();
            }
        }
    }
}
