//! The learner's shared state: what the gRPC handlers, the training thread and the status
//! reporting all see. Locks are held briefly and never across an update or an await.

use std::collections::{HashSet, VecDeque};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, RwLock};
use std::time::{Duration, Instant};

use crate::service::backpressure::Backpressure;
use crate::storage::replay::Replay;
use crate::storage::replay_log::ReplayLog;
use crate::storage::versions::VersionLease;
use crate::telemetry::metrics_log::MetricsLog;
use crate::telemetry::records::TrainRecord;
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

/// An actor the learner knows: one record per name (an actor that registers again under its
/// name, after a reconnection or a restart, reuses it), one per registration for unnamed ones.
#[derive(Debug, Clone)]
pub struct ActorRecord {
    /// The id of its current registration (sent back in every batch); an earlier registration's
    /// id is no longer accepted.
    pub id: String,
    pub name: String,
    /// The driver it demonstrates with (`RegisterRequest.demonstrator`); empty for a learning
    /// actor.
    pub demonstrator: String,
    pub index: u32,
    pub envs: u32,
    pub last_seen: Instant,
    pub weights_version: u64,
    pub transitions: u64,
    pub rejected_batches: u64,
    pub epsilon: f32,
    pub dropped_steps: u64,
    /// Seconds its experience streams were held for the replay ratio (counted as each hold ends).
    pub held_secs: f64,
    /// Experience streams of this actor open now.
    pub open_streams: u32,
    pub registrations: u64,
    /// The last batch `seq` accepted in the current registration.
    pub last_seq: Option<u64>,
    /// Per environment: (episode, t) of the last step accepted in the current registration.
    pub env_positions: Vec<Option<(u64, u32)>>,
    /// Refusal kinds already logged at WARN for this actor (later ones go to DEBUG).
    pub warned: HashSet<&'static str>,
}

impl ActorRecord {
    /// A record for a first registration.
    #[must_use]
    pub fn new(id: String, name: String, index: u32, envs: u32) -> Self {
        Self {
            id,
            name,
            demonstrator: String::new(),
            index,
            envs,
            last_seen: Instant::now(),
            weights_version: 0,
            transitions: 0,
            rejected_batches: 0,
            epsilon: 1.0,
            dropped_steps: 0,
            held_secs: 0.0,
            open_streams: 0,
            registrations: 1,
            last_seq: None,
            env_positions: vec![None; envs as usize],
            warned: HashSet::new(),
        }
    }

    /// Connected: an experience stream is open and the actor was heard from within `timeout`.
    #[must_use]
    pub fn connected(&self, timeout: Duration) -> bool {
        self.open_streams > 0 && self.last_seen.elapsed() < timeout
    }
}

/// Streams the learner ended because of what came over them (also counted in
/// `batches_rejected`).
#[derive(Debug, Default)]
pub struct RefusedStreams {
    pub too_large: AtomicU64,
    pub undecodable: AtomicU64,
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
    /// Seconds experience streams have waited for the training thread to catch up with the
    /// replay ratio (`service.update_lag_limit`), summed over streams: the actors held.
    pub held_secs: f64,
    /// DQfD's large-margin loss on the demonstrations of recent batches (smoothed); none before
    /// a batch held one.
    pub margin_loss: Option<f64>,
    /// The share of demonstrations in the last [`DEMO_SHARE_WINDOW`] batches.
    pub demo_batch_share: f64,
    /// Pre-training updates (`agent.demo_pretrain_updates`) still to do.
    pub pretrain_updates_left: u64,
}

/// Batches the reported share of demonstrations is measured over.
pub const DEMO_SHARE_WINDOW: usize = 100;

/// Where this session's replay ratio counts from: fixed when the replay first reaches its
/// minimum while a training thread runs ([`Shared::fix_ratio_baseline`]), cleared when the
/// thread ends (nothing is then owed, and no stream waits for a thread that is gone).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RatioBaseline {
    /// Transitions stored before the count began (a resumed learner's rebuilt replay was trained
    /// on by its predecessor).
    pub stored_at_fill: u64,
    /// Updates done before the count began.
    pub updates_at_start: u64,
}

/// Everything shared between the server's tasks and the training thread.
#[derive(Debug)]
pub struct Shared {
    pub cfg: RunConfig,
    /// The map file the run drives (`[env] map`), sent to actors at Register; none for the
    /// embedded towns.
    pub map: Option<crate::storage::run_map::RunMap>,
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
    /// The running training thread's start: transitions stored and updates done before it
    /// (none while no thread runs). Locked before `ratio_baseline` wherever both are.
    pub ratio_session: Mutex<Option<(u64, u64)>>,
    /// Where the replay ratio counts from, once training has started ([`Shared::updates_owed`]).
    pub ratio_baseline: Mutex<Option<RatioBaseline>>,
    /// Holds experience streams while the training thread owes more than
    /// `service.update_lag_limit` updates ([`Shared::may_store_a_batch`]).
    pub backpressure: Backpressure,
    /// Wakes the training thread when transitions arrive.
    pub data_arrived: (Mutex<()>, Condvar),
    pub shutdown: AtomicBool,
    /// Seconds of earlier sessions of this run (from the checkpoint), for `time_secs` in metrics.
    pub elapsed_before: f64,
    /// This process continues an earlier session of the run (`--resume`): its actors are not in
    /// their first life.
    pub resumed: bool,
    /// The replay log (`service.durability = "ack"`), or none.
    pub log: Option<ReplayLog>,
    /// Hands out weights versions that never go backwards, across restarts too.
    pub versions: Mutex<VersionLease>,
    /// Registrations so far (for unique actor ids).
    pub registrations: AtomicU64,
    pub refused: RefusedStreams,
    /// Refusals of clients that never registered, logged at WARN once per (peer, kind).
    pub warned_peers: Mutex<HashSet<String>>,
    /// Why training stopped, once it has (the learner then stops serving and exits non-zero).
    pub failure: tokio::sync::watch::Sender<Option<Arc<str>>>,
    /// The last failed checkpoint write, while checkpoints are retried.
    pub checkpoint_error: Mutex<Option<String>>,
    /// The most recent refusal of a batch and when it happened (Status's `recent_refusal`).
    pub last_refusal: Mutex<Option<(Instant, String)>>,
}

/// What a learner starts [`Shared`] from: what it loaded or opened; everything else starts empty
/// ([`Shared::new`]).
#[derive(Debug)]
pub struct SharedStart {
    pub cfg: RunConfig,
    pub map: Option<crate::storage::run_map::RunMap>,
    pub replay: Replay,
    /// The run's counters (its id and the seconds of earlier sessions come from them).
    pub counters: Counters,
    pub weights: PublishedWeights,
    pub metrics: MetricsLog,
    pub log: Option<ReplayLog>,
    pub versions: VersionLease,
    /// See [`Shared::ratio_session`].
    pub ratio_session: Option<(u64, u64)>,
    pub resumed: bool,
}

/// How long a refusal counts as recent in Status.
pub const RECENT_REFUSAL: Duration = Duration::from_secs(30);

impl Shared {
    /// The state of a learner that starts now from `start`: no actors, episodes, statistics,
    /// refusals or failure yet.
    #[must_use]
    pub fn new(start: SharedStart) -> Self {
        let SharedStart { cfg, map, replay, counters, weights, metrics, log, versions, ratio_session, resumed } = start;
        let shape = cfg.net_shape();
        let frame_bytes = cfg.frame_bytes();
        let backpressure = Backpressure::new(cfg.service.update_lag_limit > 0);
        let pretrain_updates_left = cfg.agent.demo_pretrain_updates.saturating_sub(counters.learner_step);
        Self {
            run_id: counters.run_id.clone(),
            elapsed_before: counters.elapsed_secs,
            cfg,
            map,
            started: Instant::now(),
            shape,
            frame_bytes,
            replay: Mutex::new(replay),
            counters: Mutex::new(counters),
            weights: RwLock::new(weights),
            actors: Mutex::new(Vec::new()),
            recent_episodes: Mutex::new(VecDeque::new()),
            stats: Mutex::new(TrainStats { pretrain_updates_left, ..TrainStats::default() }),
            metrics,
            ratio_session: Mutex::new(ratio_session),
            ratio_baseline: Mutex::new(None),
            backpressure,
            data_arrived: (Mutex::new(()), Condvar::new()),
            shutdown: AtomicBool::new(false),
            resumed,
            log,
            versions: Mutex::new(versions),
            registrations: AtomicU64::new(0),
            refused: RefusedStreams::default(),
            warned_peers: Mutex::new(HashSet::new()),
            failure: tokio::sync::watch::Sender::new(None),
            checkpoint_error: Mutex::new(None),
            last_refusal: Mutex::new(None),
        }
    }

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

    /// Why training stopped, if it has.
    #[must_use]
    pub fn failure(&self) -> Option<Arc<str>> {
        self.failure.borrow().clone()
    }

    /// Records that the learner cannot go on (training stopped, or the replay log failed): it is
    /// logged, Status shows it, health turns NOT_SERVING, nothing more is acknowledged, and
    /// `learner serve` exits non-zero. The first reason is kept.
    pub fn fail(&self, reason: impl Into<Arc<str>>) {
        let reason = reason.into();
        let first = self.failure.send_if_modified(|f| {
            if f.is_none() {
                *f = Some(reason.clone());
                true
            } else {
                false
            }
        });
        if first {
            tracing::error!(%reason, "the learner cannot go on: reporting NOT_SERVING and stopping");
            // Held streams are refused at once rather than left waiting for a learner that is gone.
            self.backpressure.wake();
        }
    }

    /// Records a refusal of a batch, for Status and the progress line.
    pub fn note_refusal(&self, reason: &str) {
        *self.last_refusal.lock().expect("refusal lock") = Some((Instant::now(), reason.to_owned()));
    }

    /// The most recent refusal, if within [`RECENT_REFUSAL`].
    #[must_use]
    pub fn recent_refusal(&self) -> Option<String> {
        self.last_refusal.lock().expect("refusal lock").as_ref().filter(|(t, _)| t.elapsed() < RECENT_REFUSAL).map(|(_, r)| r.clone())
    }

    /// Fixes the replay ratio's baseline if it is not yet fixed, a training thread runs and the
    /// replay (`len` transitions, `stored` stored in all) has reached its minimum. Both the
    /// training thread and the streams that store batches call it, so that a burst that fills
    /// the replay before the thread looks is held as well. Call it holding no other lock.
    pub fn fix_ratio_baseline(&self, len: usize, stored: u64) {
        if len < self.cfg.agent.min_replay {
            return;
        }
        let session = self.ratio_session.lock().expect("ratio session lock");
        let Some((stored_at_start, updates_at_start)) = *session else { return };
        self.ratio_baseline
            .lock()
            .expect("ratio baseline lock")
            .get_or_insert(RatioBaseline { stored_at_fill: stored.saturating_sub(len as u64).max(stored_at_start), updates_at_start });
    }

    /// Updates the replay ratio allows now and the training thread has not done: what the
    /// training thread works off, and what the experience streams wait on
    /// (`service.update_lag_limit`). 0 before training starts.
    #[must_use]
    pub fn updates_owed(&self) -> u64 {
        let Some(b) = *self.ratio_baseline.lock().expect("ratio baseline lock") else { return 0 };
        let a = &self.cfg.agent;
        let c = self.counters.lock().expect("counters lock");
        let arrived = c.transitions_stored.saturating_sub(b.stored_at_fill);
        let allowed = (arrived as f64 * f64::from(a.replay_ratio) / a.batch_size as f64).floor() as u64;
        allowed.saturating_sub(c.learner_step.saturating_sub(b.updates_at_start))
    }

    /// Whether an experience stream may store its next batch now: the training thread owes at
    /// most `service.update_lag_limit` updates, or the learner is stopping or has failed (the
    /// batch is then refused, not held).
    #[must_use]
    pub fn may_store_a_batch(&self) -> bool {
        self.updates_owed() <= self.cfg.service.update_lag_limit || self.stopping() || self.failure().is_some()
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
        let (replay_size, demos) = {
            let r = self.replay.lock().expect("replay lock");
            (r.len() as u64, r.demo_len() > 0)
        };
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
            margin_loss: s.margin_loss,
            demo_batch_share: demos.then_some(s.demo_batch_share),
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
