//! Experience replay. Frames are stored once, in a ring, and transitions refer to them by id: a
//! step's observation is the `next` of one transition and the `obs` of the following one.
//! Transitions are formed per (actor, environment) stream, with n-step returns when configured;
//! eviction is FIFO, bounded both in transitions and in bytes. Sampling is uniform, or
//! proportional to priority (Schaul et al. 2016) with importance weights.
//!
//! Streams interleave, so transitions are not in frame order: a slow stream's transition can sit
//! behind newer ones while its observation frame is the oldest in the ring. Each frame slot
//! therefore remembers the transition that observes it, and when the ring overwrites a frame that
//! transition is retired on the spot (a tombstone in the FIFO, priority 0); sampling also checks
//! every frame id it reads against the ring's live range (the generation check). A transition is
//! never sampled with another frame than its own.
//!
//! Frame stacks (`stack` N > 1): the network sees a transition's last N frames, but actors send,
//! and the ring stores, one frame per step. Each frame remembers its predecessor in its stream's
//! episode (none at the episode's first frame), and sampling walks those links back to assemble
//! the stack ([`interleave_frames`]'s layout, the episode's first frame standing in for frames
//! before it). Retirement widens with it: when the ring overwrites frame f, the transitions that
//! observe f or one of its next N − 1 successors in the stream are retired, since their stacks
//! hold f. That covers the `next` stacks too (see [`Replay::push_frame`]). A frame whose
//! predecessor never arrived (a break in the stream) has a stack that cannot be assembled: the
//! transitions that would need it are not formed.
//!
//! Demonstrations (`actor --demonstrate`, DQfD) live in a partition of their own: a second buffer
//! of the same kind with its own capacity and byte cap, FIFO among themselves and never evicted by
//! the agent's experience ([`Replay::add_demo_steps`]). [`Replay::sample_mixed`] draws each sample
//! from it with a given probability; without demonstrations it is [`Replay::sample`], draw for
//! draw. The replay log counts the frames of both partitions in one sequence
//! ([`Replay::log_frame_end`], [`Replay::log_first_live_frame`]), so that a segment is deleted only
//! once neither partition holds a frame of it.

use std::borrow::Cow;
use std::collections::{HashMap, VecDeque};

use agent::features::{RawScalars, raw_scalars};
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::env::PATH_FEATURES;

use crate::storage::sum_tree::SumTree;
use sim_core::camera::interleave_frames;

/// Sizes and options of a replay buffer.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayConfig {
    /// Transitions kept.
    pub capacity: usize,
    /// Bytes the frames and transitions may take.
    pub max_bytes: u64,
    /// Bytes of one camera frame (H·W·C, row-major, C channels interleaved per pixel).
    pub frame_bytes: usize,
    /// Channels of a frame (C): a stack interleaves its frames per pixel, C bytes at a time.
    pub channels: usize,
    /// Values of the vector sensor's reading stored with each frame (`[env.vector]`; 0 for none).
    pub vector_len: usize,
    /// Frames per observation (N ≥ 1): a sampled image holds the transition's frame and the N − 1
    /// before it in its episode, N·`frame_bytes` bytes. 1 is no stacking.
    pub stack: usize,
    pub gamma: f32,
    pub n_step: usize,
    pub prioritized: bool,
    pub alpha: f32,
    pub beta: f32,
    pub seed: u64,
}

/// One environment step as it arrives from an actor (the domain form of the wire `Step`).
#[derive(Debug, Clone, PartialEq)]
pub struct StepRecord<'a> {
    pub env: u32,
    pub episode: u64,
    pub t: u32,
    pub image: &'a [u8],
    pub speed: f32,
    pub d: f32,
    /// The planner's path features (zeros when the actor sent none).
    pub path: [f32; PATH_FEATURES],
    /// The vector sensor's reading (`ReplayConfig::vector_len` values; empty for none): borrowed
    /// from the wire, owned when read back from the log.
    pub vector: Cow<'a, [f32]>,
    pub action: u32,
    pub reward: f32,
    pub terminated: bool,
    pub truncated: bool,
}

/// A transition between two stored frames.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Transition {
    /// Retired because its observation frame was overwritten (a tombstone until it reaches the
    /// front of the FIFO).
    dead: bool,
    obs: u64,
    next: u64,
    action: u32,
    /// Discounted sum of the n rewards.
    reward: f32,
    /// γ^k for a bootstrapped transition of k steps, 0 for a terminal one.
    discount: f32,
}

/// What precedes a frame in its stream's episode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
enum Pred {
    /// Nothing: it is the episode's first frame, which stands in for the frames before it.
    #[default]
    Start,
    /// The frame with this id (which may have left the ring since).
    Frame(u64),
    /// A frame that never reached the replay (a break in the stream): no stack reaches past it.
    Missing,
}

/// Where a stream (one environment of one actor) stands.
#[derive(Debug, Clone, Default)]
struct Stream {
    episode: u64,
    t: u32,
    /// Frame of the latest observation, if the episode is running.
    last_frame: Option<u64>,
    /// Steps not yet turned into transitions: (observation frame, action, reward).
    pending: VecDeque<(u64, u32, f32)>,
}

/// Why a frame stack cannot be assembled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Gone {
    /// A frame of it left the ring.
    Overwritten,
    /// It reaches past a break in its stream, to a frame that never arrived.
    NeverStored,
}

/// Transitions sampled for an update.
#[derive(Debug, Clone, Default)]
pub struct Sample {
    /// Positions in the buffer, for priority updates.
    pub slots: Vec<usize>,
    /// Observations, concatenated, `stack`·`frame_bytes` each: the stacked frames interleaved
    /// per pixel, oldest first ([`interleave_frames`]).
    pub images: Vec<u8>,
    pub next_images: Vec<u8>,
    /// The raw scalars of each observation.
    pub scalars: Vec<RawScalars>,
    pub next_scalars: Vec<RawScalars>,
    /// The vector sensor's readings of each observation, concatenated (`vector_len` each; empty
    /// without the sensor). Not stacked: the reading holds velocities itself.
    pub vectors: Vec<f32>,
    pub next_vectors: Vec<f32>,
    pub actions: Vec<u32>,
    pub rewards: Vec<f32>,
    pub discounts: Vec<f32>,
    /// Importance-sampling weights (1 for uniform replay).
    pub weights: Vec<f32>,
    /// The last `demos` transitions are demonstrations (their slots are offset by the agent
    /// partition's capacity).
    pub demos: usize,
}

impl Sample {
    /// Appends `other`'s transitions after this sample's.
    fn append(&mut self, mut other: Sample) {
        self.slots.append(&mut other.slots);
        self.images.append(&mut other.images);
        self.next_images.append(&mut other.next_images);
        self.scalars.append(&mut other.scalars);
        self.next_scalars.append(&mut other.next_scalars);
        self.vectors.append(&mut other.vectors);
        self.next_vectors.append(&mut other.next_vectors);
        self.actions.append(&mut other.actions);
        self.rewards.append(&mut other.rewards);
        self.discounts.append(&mut other.discounts);
        self.weights.append(&mut other.weights);
        self.demos += other.demos;
    }
}

/// The demonstration partition: configured, and created at the first demonstration.
#[derive(Debug)]
struct Demos {
    cfg: ReplayConfig,
    replay: Option<Box<Replay>>,
    /// Draws which samples of a batch are demonstrations (its own stream: the agent
    /// partition's draws are those of a replay without demonstrations).
    mix_rng: ChaCha8Rng,
}

/// The replay buffer.
#[derive(Debug)]
pub struct Replay {
    cfg: ReplayConfig,
    /// Frame ring: `frame_slots` frames; frame id `i` lives in slot `i % frame_slots`.
    frames: Vec<u8>,
    frame_scalars: Vec<RawScalars>,
    /// Per frame slot: its vector sensor reading (`vector_len` values).
    frame_vectors: Vec<f32>,
    /// Per frame slot: 1 + the id of the transition whose observation it is, or 0.
    observed_by: Vec<u64>,
    /// Per frame slot, with stacks only (empty for `stack` 1): the frame's predecessor in its
    /// stream's episode, and 1 + the id of its successor, or 0.
    pred: Vec<Pred>,
    succ: Vec<u64>,
    frame_slots: usize,
    /// Ids of the oldest and next frame.
    first_frame: u64,
    next_frame: u64,
    /// Transition ring (FIFO).
    transitions: VecDeque<Transition>,
    /// Transition ids: the front of `transitions` has id `first_transition`.
    first_transition: u64,
    /// Tombstones in `transitions`.
    dead: usize,
    /// Transitions that left the buffer (capacity, byte cap, overwritten frames).
    evicted: u64,
    streams: HashMap<(String, u32), Stream>,
    priorities: Option<SumTree>,
    max_priority: f32,
    rng: ChaCha8Rng,
    /// Runs of this partition's frame ids in the replay log's count of frames (both
    /// partitions'): (first frame id of the run, its number in the count).
    log_runs: VecDeque<(u64, u64)>,
    /// Frames stored by both partitions: the replay log's frame count.
    log_frames: u64,
    demos: Option<Demos>,
}

/// Bytes a stored frame takes: the image, its raw scalars and its vector sensor reading
/// (counted against the byte cap).
fn frame_cost(frame_bytes: usize, vector_len: usize) -> u64 {
    (frame_bytes + std::mem::size_of::<RawScalars>() + vector_len * std::mem::size_of::<f32>()) as u64
}

/// Per-transition bookkeeping bytes (counted against the byte cap).
const TRANSITION_BYTES: u64 = std::mem::size_of::<Transition>() as u64 + 8;

/// Per-frame links kept with stacks (counted against the byte cap with the frame).
const LINK_BYTES: u64 = std::mem::size_of::<Pred>() as u64 + 8;

/// Bytes a stored frame takes under `cfg`: the frame itself, once, and its links if stacking.
fn stored_frame_cost(cfg: &ReplayConfig) -> u64 {
    frame_cost(cfg.frame_bytes, cfg.vector_len) + if cfg.stack > 1 { LINK_BYTES } else { 0 }
}

impl Replay {
    /// An empty buffer. Frame slots: enough for the capacity plus one per 8 transitions (episode
    /// starts), or fewer if the byte cap says so.
    #[must_use]
    ///
    /// # Panics
    /// If `stack` or `channels` is 0, or `frame_bytes` is not whole pixels of `channels`.
    pub fn new(cfg: ReplayConfig) -> Self {
        assert!(cfg.stack >= 1 && cfg.channels >= 1, "replay: stack {} and channels {} must be at least 1", cfg.stack, cfg.channels);
        assert!(
            cfg.frame_bytes.is_multiple_of(cfg.channels),
            "replay: frames of {} bytes are not whole pixels of {} channels",
            cfg.frame_bytes,
            cfg.channels
        );
        let per_frame = stored_frame_cost(&cfg);
        let by_bytes = (cfg.max_bytes.saturating_sub(cfg.capacity as u64 * TRANSITION_BYTES) / per_frame.max(1)) as usize;
        let frame_slots = (cfg.capacity + cfg.capacity / 8 + 64).min(by_bytes).max(2);
        let priorities = cfg.prioritized.then(|| SumTree::new(cfg.capacity));
        let rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        Self {
            frames: vec![0; frame_slots * cfg.frame_bytes],
            frame_scalars: vec![RawScalars::default(); frame_slots],
            frame_vectors: vec![0.0; frame_slots * cfg.vector_len],
            observed_by: vec![0; frame_slots],
            pred: vec![Pred::Start; if cfg.stack > 1 { frame_slots } else { 0 }],
            succ: vec![0; if cfg.stack > 1 { frame_slots } else { 0 }],
            frame_slots,
            first_frame: 0,
            next_frame: 0,
            transitions: VecDeque::with_capacity(cfg.capacity.min(1 << 20)),
            first_transition: 0,
            dead: 0,
            evicted: 0,
            streams: HashMap::new(),
            priorities,
            max_priority: 1.0,
            rng,
            log_runs: VecDeque::new(),
            log_frames: 0,
            demos: None,
            cfg,
        }
    }

    /// Keeps demonstrations ([`Self::add_demo_steps`]) in a partition of `capacity` transitions
    /// and `max_bytes` bytes, with this buffer's other settings; its memory is taken at the first
    /// demonstration.
    pub fn keep_demonstrations(&mut self, capacity: usize, max_bytes: u64) {
        let cfg = ReplayConfig { capacity, max_bytes, seed: self.cfg.seed ^ 0xd3e0_5eed_0000_0001, ..self.cfg.clone() };
        let mix_rng = ChaCha8Rng::seed_from_u64(self.cfg.seed ^ 0x0d3e_0317_0000_0002);
        self.demos = Some(Demos { cfg, replay: None, mix_rng });
    }

    /// Transitions in the demonstration partition.
    #[must_use]
    pub fn demo_len(&self) -> usize {
        self.demo_replay().map_or(0, Replay::len)
    }

    /// Capacity of the demonstration partition (0 when it keeps none).
    #[must_use]
    pub fn demo_capacity(&self) -> usize {
        self.demos.as_ref().map_or(0, |d| d.cfg.capacity)
    }

    /// Demonstrations that have left their partition (its capacity, its byte cap).
    #[must_use]
    pub fn demo_evicted(&self) -> u64 {
        self.demo_replay().map_or(0, Replay::evicted)
    }

    fn demo_replay(&self) -> Option<&Replay> {
        self.demos.as_ref().and_then(|d| d.replay.as_deref())
    }

    /// Adds the steps of one stream of demonstrator `actor` to the demonstration partition, as
    /// [`Self::add_steps`] does to the agent's; returns the transitions formed (0, and nothing
    /// kept, without [`Self::keep_demonstrations`]).
    pub fn add_demo_steps(&mut self, actor: &str, steps: &[StepRecord<'_>]) -> usize {
        let count = self.log_frames;
        let Some(d) = self.demos.as_mut() else { return 0 };
        let r = d.replay.get_or_insert_with(|| Box::new(Replay::new(d.cfg.clone())));
        let first = r.next_frame;
        let stored = r.add_steps_here(actor, steps);
        let added = r.next_frame - first;
        r.note_log_run(first, count);
        self.log_frames += added;
        stored
    }

    /// The replay log's frame count: frames stored by both partitions.
    #[must_use]
    pub fn log_frame_end(&self) -> u64 {
        self.log_frames
    }

    /// The oldest frame either partition holds, in the replay log's count (the count itself when
    /// neither holds one): every frame before it has left the replay.
    #[must_use]
    pub fn log_first_live_frame(&self) -> u64 {
        let oldest = |r: &Replay| (r.first_frame < r.next_frame).then(|| r.log_id(r.first_frame));
        [oldest(self), self.demo_replay().and_then(oldest)].into_iter().flatten().min().unwrap_or(self.log_frames)
    }

    /// Records that frames from `first` on are numbered from `count` in the log's count.
    fn note_log_run(&mut self, first: u64, count: u64) {
        if self.log_runs.back().is_none_or(|&(f, c)| c + (first - f) != count) {
            self.log_runs.push_back((first, count));
        }
        while self.log_runs.len() > 1 && self.log_runs[1].0 <= self.first_frame {
            self.log_runs.pop_front();
        }
    }

    /// Frame `id`'s number in the replay log's count.
    fn log_id(&self, id: u64) -> u64 {
        let &(f, c) = self.log_runs.iter().rev().find(|(f, _)| *f <= id).unwrap_or(&(0, 0));
        c + (id - f)
    }

    /// Transitions stored (and sampleable).
    #[must_use]
    pub fn len(&self) -> usize {
        self.transitions.len() - self.dead
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Transitions that have left the buffer since it was created: pushed out by the capacity,
    /// or retired because the byte cap's frame ring overwrote their observation.
    #[must_use]
    pub fn evicted(&self) -> u64 {
        self.evicted
    }

    /// Id of the next frame to be stored (ids count every frame ever stored).
    #[must_use]
    pub fn next_frame_id(&self) -> u64 {
        self.next_frame
    }

    /// Id of the oldest frame still held; every older frame, and every transition that observed
    /// it, is gone.
    #[must_use]
    pub fn first_frame_id(&self) -> u64 {
        self.first_frame
    }

    /// Forgets where every stream stood.
    pub fn end_all_streams(&mut self) {
        self.streams.clear();
        if let Some(r) = self.demos.as_mut().and_then(|d| d.replay.as_mut()) {
            r.streams.clear();
        }
    }

    /// Forgets where the streams of `actor` stood (its session ended): its next steps start
    /// afresh.
    pub fn end_streams_of(&mut self, actor: &str) {
        self.streams.retain(|(a, _), _| a != actor);
        if let Some(r) = self.demos.as_mut().and_then(|d| d.replay.as_mut()) {
            r.streams.retain(|(a, _), _| a != actor);
        }
    }

    /// Capacity in transitions.
    #[must_use]
    pub fn capacity(&self) -> usize {
        self.cfg.capacity
    }

    /// Bytes in use (frames held and transitions, of both partitions).
    #[must_use]
    pub fn bytes(&self) -> u64 {
        let frames = (self.next_frame - self.first_frame) * stored_frame_cost(&self.cfg);
        frames + self.transitions.len() as u64 * TRANSITION_BYTES + self.demo_replay().map_or(0, Replay::bytes)
    }

    /// Frames held.
    #[must_use]
    pub fn frames_held(&self) -> u64 {
        self.next_frame - self.first_frame
    }

    /// Adds the steps of one stream of `actor`, in order, and returns the transitions formed.
    /// Steps must already be validated (image size, finite numbers, action range).
    pub fn add_steps(&mut self, actor: &str, steps: &[StepRecord<'_>]) -> usize {
        let (first, count) = (self.next_frame, self.log_frames);
        let stored = self.add_steps_here(actor, steps);
        self.log_frames += self.next_frame - first;
        self.note_log_run(first, count);
        stored
    }

    /// [`Self::add_steps`] to this partition's own ring and FIFO.
    fn add_steps_here(&mut self, actor: &str, steps: &[StepRecord<'_>]) -> usize {
        let mut stored = 0;
        for s in steps {
            let key = (actor.to_owned(), s.env);
            let mut stream = self.streams.remove(&key).unwrap_or_default();
            let continues = s.t > 0 && stream.last_frame.is_some() && stream.episode == s.episode && stream.t + 1 == s.t;
            let pred = match stream.last_frame {
                Some(prev) if continues => Pred::Frame(prev),
                _ if s.t == 0 => Pred::Start,
                _ => Pred::Missing,
            };
            let frame = self.push_frame(s.image, raw_scalars(s.speed, s.d, s.path), &s.vector, pred);
            if continues {
                let prev = stream.last_frame.expect("checked above");
                stream.pending.push_back((prev, s.action, s.reward));
                if s.terminated || s.truncated {
                    // Every pending step ends here: terminal ones without bootstrap.
                    while !stream.pending.is_empty() {
                        stored += self.emit(&mut stream, frame, s.terminated);
                    }
                } else if stream.pending.len() >= self.cfg.n_step {
                    stored += self.emit(&mut stream, frame, false);
                }
            } else {
                // A new episode, or a break in the stream (lost batches): start afresh here.
                stream.pending.clear();
            }
            stream.episode = s.episode;
            stream.t = s.t;
            stream.last_frame = (!(s.terminated || s.truncated)).then_some(frame);
            self.streams.insert(key, stream);
        }
        stored
    }

    /// Turns the oldest pending step of `stream` into a transition ending at frame `next`.
    fn emit(&mut self, stream: &mut Stream, next: u64, terminal: bool) -> usize {
        let (obs, action, _) = *stream.pending.front().expect("pending is not empty");
        let mut reward = 0.0f32;
        let mut g = 1.0f32;
        for &(_, _, r) in &stream.pending {
            reward += g * r;
            g *= self.cfg.gamma;
        }
        stream.pending.pop_front();
        match self.walk_stack(obs, |_| {}) {
            Ok(()) => {}
            Err(Gone::Overwritten) => {
                self.evicted += 1;
                return 0; // a frame of its stack was overwritten already
            }
            Err(Gone::NeverStored) => return 0, // its stack reaches into a break in the stream
        }
        self.push_transition(Transition { dead: false, obs, next, action, reward, discount: if terminal { 0.0 } else { g } });
        1
    }

    /// Stores a frame whose predecessor in its stream is `pred`, overwriting the oldest if the
    /// ring is full.
    ///
    /// Overwriting frame f retires every transition whose observation stack holds f: the
    /// observers of f and of its next `stack` − 1 successors in the stream (a stack is a frame and
    /// the `stack` − 1 before it). The `next` stacks need nothing more. A transition's `next`
    /// frame comes after its `obs` frame in the same episode, so every frame of the `next` stack
    /// is at least as new as the oldest frame o of the `obs` stack. The ring overwrites frames in
    /// id order, so f is the oldest frame held, and a live transition's o is held: if f is in its
    /// `next` stack then o ≤ f, so o = f and the `obs` stack holds f too.
    fn push_frame(&mut self, image: &[u8], scalars: RawScalars, vector: &[f32], pred: Pred) -> u64 {
        let id = self.next_frame;
        let slot = (id % self.frame_slots as u64) as usize;
        let fb = self.cfg.frame_bytes;
        self.frames[slot * fb..(slot + 1) * fb].copy_from_slice(image);
        self.frame_scalars[slot] = scalars;
        let vl = self.cfg.vector_len;
        if vl > 0 {
            self.frame_vectors[slot * vl..(slot + 1) * vl].copy_from_slice(vector);
        }
        // The frame that lived in this slot is gone: so is the transition that observed it,
        // wherever it sits in the FIFO (streams interleave, so not necessarily at the front).
        let observer = std::mem::take(&mut self.observed_by[slot]);
        let successor = if self.cfg.stack > 1 { std::mem::take(&mut self.succ[slot]) } else { 0 };
        if self.next_frame - self.first_frame >= self.frame_slots as u64 {
            let gone = self.first_frame;
            self.first_frame += 1;
            if let Some(tid) = observer.checked_sub(1) {
                self.retire(tid, gone);
            }
            // With stacks, so are the observers of its successors whose stacks reach back to it.
            let mut next = successor;
            for _ in 1..self.cfg.stack {
                let Some(f) = next.checked_sub(1) else { break };
                // Successors are newer than the frame just overwritten, hence still held.
                debug_assert!(self.holds_frame(f));
                let s = self.slot(f);
                if let Some(tid) = self.observed_by[s].checked_sub(1) {
                    self.retire(tid, f);
                }
                next = self.succ[s];
            }
        }
        if self.cfg.stack > 1 {
            self.pred[slot] = pred;
            if let Pred::Frame(p) = pred
                && self.holds_frame(p)
            {
                let s = self.slot(p);
                self.succ[s] = id + 1;
            }
        }
        self.next_frame += 1;
        while self.transitions.front().is_some_and(|t| t.dead || t.obs < self.first_frame) {
            self.pop_transition();
        }
        id
    }

    /// Retires transition `tid` if it is still held and observes frame `frame`.
    fn retire(&mut self, tid: u64, frame: u64) {
        let Some(k) = tid.checked_sub(self.first_transition).map(|k| k as usize) else { return };
        let Some(t) = self.transitions.get_mut(k) else { return };
        if t.dead || t.obs != frame {
            return;
        }
        t.dead = true;
        self.dead += 1;
        self.evicted += 1;
        if let Some(tree) = self.priorities.as_mut() {
            tree.set((tid % self.cfg.capacity as u64) as usize, 0.0);
        }
    }

    fn push_transition(&mut self, t: Transition) {
        if self.transitions.len() == self.cfg.capacity {
            self.pop_transition();
        }
        let id = self.first_transition + self.transitions.len() as u64;
        self.observed_by[(t.obs % self.frame_slots as u64) as usize] = id + 1;
        self.transitions.push_back(t);
        if let Some(tree) = self.priorities.as_mut() {
            tree.set((id % self.cfg.capacity as u64) as usize, self.max_priority.powf(self.cfg.alpha));
        }
    }

    fn pop_transition(&mut self) {
        if let Some(t) = self.transitions.pop_front() {
            if t.dead {
                self.dead -= 1;
            } else {
                self.evicted += 1;
            }
            if let Some(tree) = self.priorities.as_mut() {
                tree.set((self.first_transition % self.cfg.capacity as u64) as usize, 0.0);
            }
            self.first_transition += 1;
        }
    }

    /// The ring slot of frame `id`.
    fn slot(&self, id: u64) -> usize {
        (id % self.frame_slots as u64) as usize
    }

    /// Visits the ids of the stack whose newest frame is `newest`, newest first: `newest` and the
    /// `stack` − 1 frames before it in its episode, the episode's first frame repeated where the
    /// episode is shorter. Every id is checked against the ring before its slot is read.
    fn walk_stack(&self, newest: u64, mut visit: impl FnMut(u64)) -> Result<(), Gone> {
        let mut cur = newest;
        for k in 0..self.cfg.stack {
            if !self.holds_frame(cur) {
                return Err(Gone::Overwritten);
            }
            visit(cur);
            if k + 1 == self.cfg.stack {
                break;
            }
            match self.pred[self.slot(cur)] {
                Pred::Start => {}
                Pred::Frame(p) => cur = p,
                Pred::Missing => return Err(Gone::NeverStored),
            }
        }
        Ok(())
    }

    /// The ids of the stack whose newest frame is `newest`, oldest first, into `ids` (cleared
    /// first); see [`Self::walk_stack`].
    fn stack_of(&self, newest: u64, ids: &mut Vec<u64>) -> Result<(), Gone> {
        ids.clear();
        self.walk_stack(newest, |id| ids.push(id))?;
        ids.reverse();
        Ok(())
    }

    /// Appends the stack of `ids` (oldest first) to `out`, in [`interleave_frames`]'s layout.
    fn put_stack(&self, ids: &[u64], out: &mut Vec<u8>) {
        if let &[id] = ids {
            out.extend_from_slice(self.frame(id).0);
            return;
        }
        let frames: Vec<&[u8]> = ids.iter().map(|&id| self.frame(id).0).collect();
        interleave_frames(&frames, self.cfg.channels, out);
    }

    fn frame(&self, id: u64) -> (&[u8], RawScalars) {
        let slot = self.slot(id);
        let fb = self.cfg.frame_bytes;
        (&self.frames[slot * fb..(slot + 1) * fb], self.frame_scalars[slot])
    }

    /// The vector sensor reading stored with frame `id`.
    fn vector_of(&self, id: u64) -> &[f32] {
        let (slot, vl) = (self.slot(id), self.cfg.vector_len);
        &self.frame_vectors[slot * vl..(slot + 1) * vl]
    }

    /// Whether frame `id` is still in the ring (its slot has not been reused): the generation
    /// check every sampled frame passes.
    fn holds_frame(&self, id: u64) -> bool {
        id >= self.first_frame && id < self.next_frame
    }

    /// Position in the FIFO of a live transition, drawn uniformly or by priority, with its
    /// sampling probability.
    fn draw(&mut self) -> (usize, f64) {
        let len = self.transitions.len();
        let live = self.len();
        let cap = self.cfg.capacity as u64;
        // Tombstones are few (only transitions overtaken by other streams'), so redrawing ends
        // quickly; a scan bounds it.
        for _ in 0..64 {
            let (k, p) = match self.priorities.as_ref() {
                Some(tree) => {
                    let total = tree.total();
                    let u = (self.rng.next_u32() as f64 / (u32::MAX as f64 + 1.0)) * total;
                    let slot = tree.find(u);
                    let k = (slot as u64 + cap - self.first_transition % cap) % cap;
                    ((k as usize).min(len - 1), tree.get(slot) as f64 / total)
                }
                None => ((self.rng.next_u64() % len as u64) as usize, 1.0 / live as f64),
            };
            if !self.transitions[k].dead {
                return (k, p);
            }
        }
        let k = self.transitions.iter().position(|t| !t.dead).expect("a live transition exists");
        (k, 1.0 / live as f64)
    }

    /// Samples `n` transitions (with replacement). `None` when the buffer is empty.
    pub fn sample(&mut self, n: usize) -> Option<Sample> {
        if self.is_empty() {
            return None;
        }
        let len = self.len();
        let mut out = Sample::default();
        let mut probs = Vec::with_capacity(n);
        let (mut obs_ids, mut next_ids) = (Vec::with_capacity(self.cfg.stack), Vec::with_capacity(self.cfg.stack));
        for _ in 0..n {
            let (k, p) = self.draw();
            let t = self.transitions[k];
            if self.cfg.stack == 1 {
                // One frame each: copied straight, without walking stacks (the common case).
                assert!(
                    self.holds_frame(t.obs) && self.holds_frame(t.next),
                    "replay: transition {k} refers to frames {}→{} outside the ring [{}, {})",
                    t.obs,
                    t.next,
                    self.first_frame,
                    self.next_frame
                );
                out.images.extend_from_slice(self.frame(t.obs).0);
                out.next_images.extend_from_slice(self.frame(t.next).0);
            } else {
                let held = self.stack_of(t.obs, &mut obs_ids).and_then(|()| self.stack_of(t.next, &mut next_ids));
                assert!(
                    held.is_ok(),
                    "replay: transition {k} refers to frames {}→{} whose stacks leave the ring [{}, {}): {held:?}",
                    t.obs,
                    t.next,
                    self.first_frame,
                    self.next_frame
                );
                self.put_stack(&obs_ids, &mut out.images);
                self.put_stack(&next_ids, &mut out.next_images);
            }
            out.scalars.push(self.frame(t.obs).1);
            out.next_scalars.push(self.frame(t.next).1);
            if self.cfg.vector_len > 0 {
                // Without the sensor there is nothing to copy (and the camera path's sampling
                // costs what it did before the sensor: scripts/bench-check.sh).
                out.vectors.extend_from_slice(self.vector_of(t.obs));
                out.next_vectors.extend_from_slice(self.vector_of(t.next));
            }
            out.actions.push(t.action);
            out.rewards.push(t.reward);
            out.discounts.push(t.discount);
            out.slots.push(((self.first_transition + k as u64) % self.cfg.capacity as u64) as usize);
            probs.push(p);
        }
        out.weights = if self.priorities.is_some() {
            let w: Vec<f64> = probs.iter().map(|p| (len as f64 * p.max(1e-12)).powf(-f64::from(self.cfg.beta))).collect();
            let max = w.iter().copied().fold(f64::MIN, f64::max);
            w.iter().map(|x| (x / max) as f32).collect()
        } else {
            vec![1.0; n]
        };
        Some(out)
    }

    /// Samples `n` transitions, each from the demonstrations with probability `demo_share`
    /// while there are any (the demonstrations last in the sample, [`Sample::demos`]), else from
    /// the agent's experience. With no demonstrations or a share of 0 it is [`Self::sample`].
    /// `None` when the agent partition is empty.
    pub fn sample_mixed(&mut self, n: usize, demo_share: f32) -> Option<Sample> {
        let capacity = self.cfg.capacity;
        let Some(d) = self.demos.as_mut().filter(|d| demo_share > 0.0 && d.replay.as_ref().is_some_and(|r| !r.is_empty())) else {
            return self.sample(n);
        };
        if self.transitions.len() == self.dead {
            return None;
        }
        let k = (0..n).filter(|_| d.mix_rng.random::<f32>() < demo_share).count();
        let demos = Self::sample_partition(d, k, capacity);
        let mut s = self.sample(n - k)?;
        s.append(demos);
        Some(s)
    }

    /// Samples `n` demonstrations alone (pre-training); `None` when there are none.
    pub fn sample_demos(&mut self, n: usize) -> Option<Sample> {
        let capacity = self.cfg.capacity;
        let d = self.demos.as_mut().filter(|d| d.replay.as_ref().is_some_and(|r| !r.is_empty()))?;
        Some(Self::sample_partition(d, n, capacity))
    }

    /// `n` samples of a non-empty demonstration partition, their slots offset by `offset`.
    fn sample_partition(d: &mut Demos, n: usize, offset: usize) -> Sample {
        let r = d.replay.as_mut().expect("a demonstration partition");
        let mut s = r.sample(n).expect("a non-empty demonstration partition");
        s.slots.iter_mut().for_each(|slot| *slot += offset);
        s.demos = n;
        s
    }

    /// Sets the priorities of sampled slots from their |TD errors| (prioritized replay only);
    /// slots from the demonstration partition are its own.
    pub fn update_priorities(&mut self, slots: &[usize], td_abs: &[f32]) {
        let capacity = self.cfg.capacity;
        if let Some(r) = self.demos.as_mut().and_then(|d| d.replay.as_mut())
            && slots.iter().any(|&s| s >= capacity)
        {
            let (mut ds, mut dt, mut os, mut ot) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            for (&slot, &e) in slots.iter().zip(td_abs) {
                if slot >= capacity {
                    ds.push(slot - capacity);
                    dt.push(e);
                } else {
                    os.push(slot);
                    ot.push(e);
                }
            }
            r.update_priorities(&ds, &dt);
            return self.update_priorities(&os, &ot);
        }
        let Some(tree) = self.priorities.as_mut() else { return };
        for (&slot, &e) in slots.iter().zip(td_abs) {
            let p = e.abs() + 1e-3;
            self.max_priority = self.max_priority.max(p);
            if tree.get(slot) > 0.0 {
                tree.set(slot, p.powf(self.cfg.alpha));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    fn cfg(capacity: usize) -> ReplayConfig {
        ReplayConfig {
            vector_len: 0,
            capacity,
            max_bytes: 1 << 30,
            frame_bytes: 4,
            channels: 1,
            stack: 1,
            gamma: 0.5,
            n_step: 1,
            prioritized: false,
            alpha: 0.6,
            beta: 0.4,
            seed: 1,
        }
    }

    /// An episode of `len` steps whose frames are filled with the step index.
    fn episode(episode: u64, len: u32, terminal: bool) -> Vec<(Vec<u8>, StepRecord<'static>)> {
        (0..=len)
            .map(|t| {
                let rec = StepRecord {
                    env: 0,
                    episode,
                    t,
                    image: &[],
                    speed: t as f32,
                    d: 0.0,
                    path: [0.0; PATH_FEATURES],
                    vector: Default::default(),
                    action: t % 3,
                    reward: t as f32,
                    terminated: terminal && t == len,
                    truncated: !terminal && t == len,
                };
                (vec![t as u8; 4], rec)
            })
            .collect()
    }

    /// The steps as records borrowing their frames.
    fn records<'a>(steps: &'a [(Vec<u8>, StepRecord<'static>)]) -> Vec<StepRecord<'a>> {
        steps.iter().map(|(img, s)| StepRecord { image: img, ..s.clone() }).collect()
    }

    fn add(r: &mut Replay, steps: &[(Vec<u8>, StepRecord<'static>)]) -> usize {
        r.add_steps("a", &records(steps))
    }

    #[test]
    fn frames_are_stored_once_and_transitions_link_them() {
        let mut r = Replay::new(cfg(100));
        assert_eq!(add(&mut r, &episode(0, 5, true)), 5);
        // 6 observations (t = 0..5), 5 transitions: one frame per step, not two per transition.
        assert_eq!((r.len(), r.frames_held()), (5, 6));
        let s = r.sample(200).unwrap();
        for i in 0..200 {
            // Frame bytes carry t: next = obs + 1; reward of the step that led to next.
            assert_eq!(s.next_images[i * 4], s.images[i * 4] + 1);
            assert_eq!(s.rewards[i], f32::from(s.next_images[i * 4]));
            let terminal = s.next_images[i * 4] == 5;
            assert_eq!(s.discounts[i], if terminal { 0.0 } else { 0.5 }, "terminal transitions do not bootstrap");
        }
    }

    #[test]
    fn vector_readings_are_stored_without_frames_and_sampled_with_their_transition() {
        // A vector run: no camera (frames of 0 bytes), readings of 3 values that carry t.
        let mut r = Replay::new(ReplayConfig { frame_bytes: 0, vector_len: 3, n_step: 2, ..cfg(100) });
        let reading = |t: u32| vec![t as f32 / 10.0, -(t as f32) / 10.0, 0.5];
        let steps: Vec<StepRecord<'static>> =
            episode(0, 6, true).into_iter().map(|(_, s)| StepRecord { vector: Cow::Owned(reading(s.t)), ..s }).collect();
        assert_eq!(r.add_steps("a", &steps), 6);
        let s = r.sample(300).unwrap();
        assert!(s.images.is_empty() && s.next_images.is_empty(), "no frames stored or sampled");
        assert_eq!((s.vectors.len(), s.next_vectors.len()), (300 * 3, 300 * 3));
        for i in 0..300 {
            // Each reading is its own frame's (the raw speed carries t too).
            let (t, t2) = (s.scalars[i][0] as u32, s.next_scalars[i][0] as u32);
            assert_eq!(&s.vectors[i * 3..i * 3 + 3], reading(t).as_slice());
            assert_eq!(&s.next_vectors[i * 3..i * 3 + 3], reading(t2).as_slice());
            assert!(t2 == t + 2 || t2 == 6, "two-step transitions: {t} -> {t2}");
        }
        // The byte count is the readings' and the bookkeeping's, not a frame's.
        assert_eq!(stored_frame_cost(&r.cfg), 3 * 4 + std::mem::size_of::<RawScalars>() as u64);
    }

    #[test]
    fn truncated_episodes_bootstrap() {
        let mut r = Replay::new(cfg(100));
        add(&mut r, &episode(0, 3, false));
        let s = r.sample(100).unwrap();
        assert!(s.discounts.iter().all(|&d| d == 0.5), "{:?}", s.discounts);
    }

    #[test]
    fn n_step_returns_sum_discounted_rewards() {
        let mut r = Replay::new(ReplayConfig { n_step: 3, ..cfg(100) });
        // Rewards 1..=5 arrive with t = 1..=5; episode terminal at t = 5.
        assert_eq!(add(&mut r, &episode(0, 5, true)), 5);
        let s = r.sample(300).unwrap();
        for i in 0..300 {
            let obs = s.images[i * 4];
            let next = s.next_images[i * 4];
            // From t = obs: rewards obs+1, obs+2, … up to 3 of them or the end.
            let k = (next - obs) as i32;
            let expected: f32 = (0..k).map(|j| 0.5f32.powi(j) * f32::from(obs + 1 + j as u8)).sum();
            assert!((s.rewards[i] - expected).abs() < 1e-6, "obs {obs} next {next}: {} vs {expected}", s.rewards[i]);
            assert!(k == 3 || next == 5, "3-step except at the end");
            assert_eq!(s.discounts[i], if next == 5 { 0.0 } else { 0.125 });
        }
    }

    #[test]
    fn eviction_is_fifo_and_bounded() {
        let mut r = Replay::new(cfg(10));
        for e in 0..10 {
            add(&mut r, &episode(e, 5, true));
        }
        assert_eq!(r.len(), 10);
        // Byte cap: 20 frames of 1000 bytes at most.
        let mut small = Replay::new(ReplayConfig { frame_bytes: 1000, max_bytes: 20 * 1020 + 1000 * TRANSITION_BYTES, ..cfg(1000) });
        let img = vec![7u8; 1000];
        for t in 0..100u32 {
            let rec = StepRecord {
                env: 0,
                episode: 0,
                t,
                image: &img,
                speed: 0.0,
                d: 0.0,
                path: [0.0; PATH_FEATURES],
                vector: Default::default(),
                action: 0,
                reward: 0.0,
                terminated: false,
                truncated: false,
            };
            small.add_steps("a", &[rec]);
        }
        assert!(small.frames_held() <= 20, "{}", small.frames_held());
        assert!(small.bytes() <= 20 * 1020 + 1000 * TRANSITION_BYTES);
        assert!(small.len() <= 19 && !small.is_empty());
    }

    #[test]
    fn a_broken_stream_forms_no_transition_across_the_gap() {
        let mut r = Replay::new(cfg(100));
        let steps = episode(0, 6, true);
        // Steps 0–2, then 4–6 (3 lost): transitions 0→1, 1→2, 4→5, 5→6 only.
        let kept: Vec<_> = steps.iter().filter(|(_, s)| s.t != 3).cloned().collect();
        assert_eq!(add(&mut r, &kept), 4);
        let s = r.sample(100).unwrap();
        assert!((0..100).all(|i| s.next_images[i * 4] == s.images[i * 4] + 1));
    }

    /// Several streams interleaved at the byte cap, one of them slow: its transitions sit behind
    /// newer ones while their frames are the oldest in the ring. No sample may pair a transition
    /// with a frame that is not its own. Frames carry (stream, t); the transition from t observes
    /// (s, t) and leads to (s, t + 1).
    #[test]
    fn interleaved_streams_at_the_byte_cap_never_sample_an_overwritten_frame() {
        for prioritized in [false, true] {
            // 24 frame slots of 4 bytes: the byte cap, not the capacity, binds.
            let per_frame = frame_cost(4, 0);
            let cfg = ReplayConfig { frame_bytes: 4, max_bytes: 24 * per_frame + 1000 * TRANSITION_BYTES, prioritized, ..cfg(1000) };
            let mut r = Replay::new(cfg);
            assert_eq!(r.frame_slots, 24);
            let mut t = [0u32; 5];
            let mut rng = ChaCha8Rng::seed_from_u64(7);
            let check = |r: &mut Replay| {
                let Some(s) = r.sample(64) else { return };
                for i in 0..64 {
                    let (obs, next) = (&s.images[i * 4..i * 4 + 4], &s.next_images[i * 4..i * 4 + 4]);
                    assert_eq!(obs[0], next[0], "a transition of stream {} was sampled with stream {}'s frame", next[0], obs[0]);
                    let (t0, t1) = (u16::from_le_bytes([obs[1], obs[2]]), u16::from_le_bytes([next[1], next[2]]));
                    assert_eq!(t0 + 1, t1, "stream {}: frames {t0} → {t1}", obs[0]);
                }
                if prioritized {
                    r.update_priorities(&s.slots, &vec![0.5; 64]);
                }
            };
            for round in 0..400 {
                // Stream 0 is slow (one step in 12 rounds); the others send 1–6 steps at a time.
                let stream = if round % 12 == 0 { 0 } else { 1 + rng.random_range(0..4usize) };
                let n = if stream == 0 { 1 } else { rng.random_range(1..=6) };
                let actor = format!("actor-{stream}");
                let imgs: Vec<[u8; 4]> = (0..n)
                    .map(|k| {
                        let [lo, hi] = ((t[stream] + k) as u16).to_le_bytes();
                        [stream as u8, lo, hi, 0]
                    })
                    .collect();
                let recs: Vec<StepRecord<'_>> = imgs
                    .iter()
                    .enumerate()
                    .map(|(k, img)| StepRecord {
                        env: 0,
                        episode: 0,
                        t: t[stream] + k as u32,
                        image: img,
                        speed: 0.0,
                        d: 0.0,
                        path: [0.0; PATH_FEATURES],
                        vector: Default::default(),
                        action: 0,
                        reward: 0.0,
                        terminated: false,
                        truncated: false,
                    })
                    .collect();
                r.add_steps(&actor, &recs);
                t[stream] += n;
                assert!(r.bytes() <= 24 * per_frame + 1000 * TRANSITION_BYTES);
                check(&mut r);
            }
            // Stream 0's transitions were overtaken and retired, and counted as evicted.
            assert!(r.evicted() > 0);
            assert!(r.len() <= 23, "{} live transitions over 24 frames", r.len());
        }
    }

    #[test]
    fn prioritized_sampling_prefers_high_priorities_and_weights_correct_for_it() {
        let mut r = Replay::new(ReplayConfig { prioritized: true, alpha: 1.0, beta: 1.0, ..cfg(8) });
        add(&mut r, &episode(0, 4, true));
        let s = r.sample(4).unwrap();
        // Make transition of slot s.slots[0] 100× likelier than the others.
        let all: Vec<usize> = (0..4).collect();
        r.update_priorities(&all, &[0.001; 4]);
        r.update_priorities(&[s.slots[0]], &[1.0]);
        let s2 = r.sample(1000).unwrap();
        let hits = s2.slots.iter().filter(|&&x| x == s.slots[0]).count();
        assert!(hits > 900, "{hits} of 1000");
        // The favoured transition has the smallest importance weight.
        let w_fav = s2.weights[s2.slots.iter().position(|&x| x == s.slots[0]).unwrap()];
        assert!(s2.weights.iter().all(|&w| w >= w_fav - 1e-6));
    }

    /// A frame that says where it comes from, in two pixels of two channels: pixel 0 is (stream,
    /// episode), pixel 1 is t (little-endian).
    fn tagged(stream: u8, episode: u8, t: u16) -> [u8; 4] {
        let [lo, hi] = t.to_le_bytes();
        [stream, episode, lo, hi]
    }

    /// The (stream, episode, t) of each frame of a stacked image of tagged frames, oldest first.
    fn untag(image: &[u8], stack: usize) -> Vec<(u8, u8, u16)> {
        (0..stack)
            .map(|k| {
                let pixel = |p: usize| &image[p * 2 * stack + 2 * k..p * 2 * stack + 2 * k + 2];
                (pixel(0)[0], pixel(0)[1], u16::from_le_bytes([pixel(1)[0], pixel(1)[1]]))
            })
            .collect()
    }

    /// The stack that ends at step `t` of an episode: the `stack` steps up to t, step 0 repeated
    /// where the episode is shorter.
    fn expected_stack(stream: u8, episode: u8, t: u16, stack: usize) -> Vec<(u8, u8, u16)> {
        (0..stack).map(|k| (stream, episode, t.saturating_sub((stack - 1 - k) as u16))).collect()
    }

    /// A step of stream `env` carrying `image`, its speed the step index.
    fn tagged_step(env: u32, episode: u64, t: u32, image: &[u8], end: Option<bool>) -> StepRecord<'_> {
        StepRecord {
            env,
            episode,
            t,
            image,
            speed: t as f32,
            d: env as f32,
            path: [0.0; PATH_FEATURES],
            vector: Default::default(),
            action: t % 3,
            reward: 1.0,
            terminated: end == Some(true),
            truncated: end == Some(false),
        }
    }

    /// Checks every transition of a sample of tagged frames: its observation is the stack that
    /// ends at its frame, its next observation the stack that ends 1 to `n_step` steps later in
    /// the same stream and episode, and its scalars are its own frame's. Returns the (stream,
    /// episode, t) of each observation.
    fn check_stacks(s: &Sample, stack: usize, n_step: u16) -> Vec<(u8, u8, u16)> {
        let size = 4 * stack;
        assert_eq!((s.images.len(), s.next_images.len()), (s.actions.len() * size, s.actions.len() * size));
        (0..s.actions.len())
            .map(|i| {
                let obs = untag(&s.images[i * size..(i + 1) * size], stack);
                let next = untag(&s.next_images[i * size..(i + 1) * size], stack);
                let (stream, episode, t) = obs[stack - 1];
                assert_eq!(obs, expected_stack(stream, episode, t, stack), "the observation stack of {:?}", obs[stack - 1]);
                let (s2, e2, t2) = next[stack - 1];
                assert!((s2, e2) == (stream, episode) && t2 > t && t2 - t <= n_step, "{:?} leads to {:?}", obs[stack - 1], next[stack - 1]);
                assert_eq!(next, expected_stack(stream, episode, t2, stack), "the next stack of {:?}", obs[stack - 1]);
                assert_eq!((s.scalars[i][0], s.next_scalars[i][0]), (f32::from(t), f32::from(t2)), "scalars of the newest frames");
                (stream, episode, t)
            })
            .collect()
    }

    /// Every live transition's observation and next stacks are whole in the ring: what the
    /// retirement rule promises (retiring the observers of an overwritten frame's stack covers
    /// the next stacks).
    fn check_live_stacks(r: &Replay) {
        let mut ids = Vec::new();
        for (k, t) in r.transitions.iter().enumerate().filter(|(_, t)| !t.dead) {
            assert_eq!(r.stack_of(t.obs, &mut ids), Ok(()), "transition {k}'s observation stack");
            assert_eq!(r.stack_of(t.next, &mut ids), Ok(()), "transition {k}'s next stack");
        }
    }

    #[test]
    fn stacks_hold_the_last_frames_of_the_episode_oldest_first() {
        let mut r = Replay::new(ReplayConfig { channels: 2, stack: 3, ..cfg(100) });
        // Episode 0: steps 0..=5, terminal; episode 1: steps 0..=4, truncated.
        let images: Vec<(u64, u32, [u8; 4])> =
            (0..=5).map(|t| (0, t, tagged(0, 0, t as u16))).chain((0..=4).map(|t| (1, t, tagged(0, 1, t as u16)))).collect();
        let recs: Vec<StepRecord<'_>> = images
            .iter()
            .map(|(e, t, img)| {
                let end = match (e, t) {
                    (0, 5) => Some(true),
                    (1, 4) => Some(false),
                    _ => None,
                };
                tagged_step(0, *e, *t, img, end)
            })
            .collect();
        assert_eq!(r.add_steps("a", &recs), 9);
        assert_eq!(r.frames_held(), 11, "one frame per step, stacks or not");
        let s = r.sample(500).unwrap();
        let seen = check_stacks(&s, 3, 1);
        for (i, &(_, episode, t)) in seen.iter().enumerate() {
            // The image is exactly the interleave of the three frames, the first repeated.
            let stack = |t: u16| -> Vec<u8> {
                let frames: Vec<[u8; 4]> = expected_stack(0, episode, t, 3).into_iter().map(|(s, e, t)| tagged(s, e, t)).collect();
                let refs: Vec<&[u8]> = frames.iter().map(|f| f.as_slice()).collect();
                let mut out = Vec::new();
                interleave_frames(&refs, 2, &mut out);
                out
            };
            assert_eq!(s.images[i * 12..(i + 1) * 12], stack(t));
            assert_eq!(s.next_images[i * 12..(i + 1) * 12], stack(t + 1));
        }
        let mut all: Vec<(u8, u16)> = seen.iter().map(|&(_, e, t)| (e, t)).collect();
        all.sort_unstable();
        all.dedup();
        let expected: Vec<(u8, u16)> = (0..5).map(|t| (0, t)).chain((0..4).map(|t| (1, t))).collect();
        assert_eq!(all, expected, "every transition sampled, episode 1's from its own first frame");
    }

    #[test]
    fn interleaved_streams_do_not_mix_their_frames() {
        let mut r = Replay::new(ReplayConfig { channels: 2, stack: 4, ..cfg(1000) });
        // Two environments of one actor and one of another, in chunks of different sizes.
        let streams = [("a", 0u32, 0u8), ("a", 1, 1), ("b", 0, 2)];
        let mut t = [0u32; 3];
        for round in 0..30 {
            let i = round % 3;
            let (actor, env, tag) = streams[i];
            let imgs: Vec<[u8; 4]> = (0..=i as u32).map(|k| tagged(tag, 0, (t[i] + k) as u16)).collect();
            let recs: Vec<StepRecord<'_>> =
                imgs.iter().enumerate().map(|(k, img)| tagged_step(env, 0, t[i] + k as u32, img, None)).collect();
            r.add_steps(actor, &recs);
            t[i] += imgs.len() as u32;
        }
        check_live_stacks(&r);
        let s = r.sample(1000).unwrap();
        let seen = check_stacks(&s, 4, 1);
        for tag in 0..3 {
            assert!(seen.iter().any(|&(s, _, _)| s == tag), "stream {tag} sampled");
        }
    }

    #[test]
    fn no_stack_reaches_across_a_break_in_the_stream() {
        let mut r = Replay::new(ReplayConfig { channels: 2, stack: 3, ..cfg(100) });
        // Steps 0–2, then 4–8 (3 lost): 0→1 and 1→2 are formed; 4→5 and 5→6 would need the lost
        // frame 3 in their stacks, so only 6→7 and 7→8 follow.
        let imgs: Vec<(u32, [u8; 4])> = (0..=8).filter(|&t| t != 3).map(|t| (t, tagged(0, 0, t as u16))).collect();
        let recs: Vec<StepRecord<'_>> = imgs.iter().map(|(t, img)| tagged_step(0, 0, *t, img, None)).collect();
        assert_eq!(r.add_steps("a", &recs), 4);
        let s = r.sample(200).unwrap();
        let mut seen: Vec<u16> = check_stacks(&s, 3, 1).into_iter().map(|(_, _, t)| t).collect();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen, [0, 1, 6, 7]);
        assert_eq!(r.evicted(), 0, "never stored is not evicted");
    }

    /// Several streams interleaved at the byte cap, one of them slow, episodes of random lengths,
    /// stacks of 3, with 1- and 3-step returns: the ring overwrites frames that the stacks of live
    /// transitions reach back to. No sample may hold a frame other than the stack's own, and no
    /// live transition may keep a stack (observation or next) with a frame gone from the ring.
    #[test]
    fn stacks_at_the_byte_cap_never_hold_an_overwritten_frame() {
        for (n_step, prioritized) in [(1, false), (3, false), (3, true)] {
            let base = ReplayConfig { channels: 2, stack: 3, n_step, prioritized, ..cfg(1000) };
            let per_frame = stored_frame_cost(&base);
            let max_bytes = 24 * per_frame + 1000 * TRANSITION_BYTES;
            let mut r = Replay::new(ReplayConfig { max_bytes, ..base });
            assert_eq!(r.frame_slots, 24);
            let mut rng = ChaCha8Rng::seed_from_u64(5);
            let (mut t, mut episode) = ([0u32; 4], [0u8; 4]);
            let mut length: [u32; 4] = std::array::from_fn(|_| rng.random_range(2..12));
            let mut sampled = 0;
            for round in 0..600 {
                // Stream 0 is slow (one step in 10 rounds); the others send 1–5 steps at a time.
                let stream = if round % 10 == 0 { 0 } else { 1 + rng.random_range(0..3usize) };
                let n = (if stream == 0 { 1 } else { rng.random_range(1..=5u32) }).min(length[stream] + 1 - t[stream]);
                let imgs: Vec<[u8; 4]> = (0..n).map(|k| tagged(stream as u8, episode[stream], (t[stream] + k) as u16)).collect();
                let recs: Vec<StepRecord<'_>> = imgs
                    .iter()
                    .enumerate()
                    .map(|(k, img)| {
                        let step = t[stream] + k as u32;
                        let end = (step == length[stream]).then(|| rng.random_bool(0.5));
                        tagged_step(0, u64::from(episode[stream]), step, img, end)
                    })
                    .collect();
                r.add_steps(&format!("actor-{stream}"), &recs);
                t[stream] += n;
                if t[stream] > length[stream] {
                    (t[stream], episode[stream], length[stream]) = (0, episode[stream].wrapping_add(1), rng.random_range(2..12));
                }
                assert!(r.bytes() <= max_bytes);
                check_live_stacks(&r);
                if let Some(s) = r.sample(64) {
                    sampled += check_stacks(&s, 3, n_step as u16).len();
                    if prioritized {
                        r.update_priorities(&s.slots, &vec![0.5; 64]);
                    }
                }
            }
            assert!(sampled > 0 && r.evicted() > 0, "n_step {n_step}: {sampled} sampled, {} evicted", r.evicted());
        }
    }

    /// Episodes of `len` steps on stream `env`, frames tagged with the stream (byte 0), so that
    /// a sample says where it came from.
    fn tagged_episode(env: u32, e: u64, len: u32, tag: u8) -> Vec<(Vec<u8>, StepRecord<'static>)> {
        episode(e, len, true)
            .into_iter()
            .map(|(mut img, s)| {
                img[0] = tag;
                (img, StepRecord { env, ..s })
            })
            .collect()
    }

    fn add_demo(r: &mut Replay, steps: &[(Vec<u8>, StepRecord<'static>)]) -> usize {
        r.add_demo_steps("teacher", &records(steps))
    }

    /// The agent's experience overfills its partition (capacity 50) twenty times over and its
    /// frame ring many times more, interleaved with demonstrations: every demonstration stays,
    /// sampled with its own frames; the demonstration partition evicts FIFO among its own once
    /// it is full itself, whatever the agent's partition does.
    #[test]
    fn demonstrations_are_never_evicted_by_the_agents_experience() {
        for prioritized in [false, true] {
            let mut r = Replay::new(ReplayConfig { prioritized, ..cfg(50) });
            r.keep_demonstrations(40, 1 << 30);
            assert_eq!(add_demo(&mut r, &tagged_episode(0, 0, 10, 200)), 10);
            for e in 0..100 {
                add(&mut r, &tagged_episode(0, e, 10, 1));
                if e == 50 {
                    assert_eq!(add_demo(&mut r, &tagged_episode(1, 0, 10, 201)), 10);
                }
            }
            assert!(r.evicted() > 900, "the agent's partition overflowed: {}", r.evicted());
            assert_eq!((r.len(), r.demo_len(), r.demo_evicted()), (50, 20, 0));
            let s = r.sample_demos(400).unwrap();
            assert_eq!(s.demos, 400);
            assert!(s.images.chunks(4).all(|f| f[0] == 200 || f[0] == 201), "demonstrations keep their own frames");
            assert!(s.slots.iter().all(|&k| k >= 50), "demonstration slots follow the agent's");
            if prioritized {
                r.update_priorities(&s.slots, &vec![0.5; 400]);
            }
            // Full, they leave FIFO among themselves: the first episode goes first.
            for e in 1..4 {
                add_demo(&mut r, &tagged_episode(1, e, 10, 201));
            }
            assert_eq!((r.demo_len(), r.demo_evicted()), (40, 10));
            let s = r.sample_demos(400).unwrap();
            assert!(s.images.chunks(4).all(|f| f[0] == 201), "the oldest demonstrations left first");
        }
    }

    /// Each sample is a demonstration with probability `demo_share`: over 200 batches of 64 the
    /// share is within 4 standard deviations (√(p(1−p)/12800) ≈ 0.004 at p = 0.25) of it; the
    /// demonstrations come last in the batch and are the demonstration partition's.
    #[test]
    fn the_share_of_demonstrations_in_batches_is_the_configured_one() {
        let mut r = Replay::new(cfg(1000));
        r.keep_demonstrations(1000, 1 << 30);
        add(&mut r, &tagged_episode(0, 0, 100, 1));
        add_demo(&mut r, &tagged_episode(0, 0, 100, 200));
        for p in [0.25f32, 0.5, 0.9] {
            let (mut demos, mut all) = (0, 0);
            for _ in 0..200 {
                let s = r.sample_mixed(64, p).unwrap();
                assert_eq!(s.actions.len(), 64);
                for (k, f) in s.images.chunks(4).enumerate() {
                    assert_eq!(f[0] == 200, k >= 64 - s.demos, "demonstrations last");
                }
                (demos, all) = (demos + s.demos, all + 64);
            }
            let share = demos as f64 / all as f64;
            let sd = (f64::from(p) * (1.0 - f64::from(p)) / all as f64).sqrt();
            assert!((share - f64::from(p)).abs() < 4.0 * sd, "share {share} for {p} (sd {sd})");
        }
        assert_eq!(r.sample_mixed(64, 0.0).unwrap().demos, 0);
    }

    /// Without demonstrations (none configured, or configured and none arrived), mixed sampling
    /// is plain sampling draw for draw, and the log's frame count is the ring's.
    #[test]
    fn without_demonstrations_mixed_sampling_is_plain_sampling() {
        let mut plain = Replay::new(cfg(100));
        let mut mixed = Replay::new(cfg(100));
        mixed.keep_demonstrations(100, 1 << 30);
        let mut h = (0xcbf2_9ce4_8422_2325u64, 0xcbf2_9ce4_8422_2325u64);
        for e in 0..40 {
            add(&mut plain, &episode(e, 7, e % 2 == 0));
            add(&mut mixed, &episode(e, 7, e % 2 == 0));
            fingerprint(&mut h.0, &plain.sample(16).unwrap());
            fingerprint(&mut h.1, &mixed.sample_mixed(16, 0.5).unwrap());
            assert_eq!((mixed.log_frame_end(), mixed.log_first_live_frame()), (mixed.next_frame_id(), mixed.first_frame_id()));
        }
        assert_eq!(h.0, h.1);
    }

    /// The replay log's frame count runs over both partitions: the oldest live frame is the
    /// older partition's oldest, counted where it was stored.
    #[test]
    fn the_log_counts_the_frames_of_both_partitions_in_order() {
        let mut r = Replay::new(cfg(20));
        r.keep_demonstrations(20, 1 << 30);
        add(&mut r, &episode(0, 4, true)); // log frames 0..5
        add_demo(&mut r, &episode(0, 4, true)); // 5..10
        add(&mut r, &episode(1, 4, true)); // 10..15
        assert_eq!((r.log_frame_end(), r.log_first_live_frame()), (15, 0));
        // The agent's ring (20 + 2 + 64 frame slots) overwrites its first frames; the
        // demonstrations' first frame, log frame 5, is then the oldest held.
        for e in 2..40 {
            add(&mut r, &episode(e, 4, true));
        }
        assert!(r.first_frame_id() > 0);
        assert_eq!(r.log_first_live_frame(), 5);
        assert_eq!(r.log_frame_end(), 15 + 38 * 5);
    }

    /// FNV-1a over everything a sample hands out, for comparing whole sampling runs.
    fn fingerprint(h: &mut u64, s: &Sample) {
        let mut eat = |bytes: &[u8]| {
            for &b in bytes {
                *h = (*h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
            }
        };
        eat(&s.images);
        eat(&s.next_images);
        for sc in s.scalars.iter().chain(&s.next_scalars) {
            sc.iter().for_each(|x| eat(&x.to_bits().to_le_bytes()));
        }
        s.actions.iter().for_each(|x| eat(&x.to_le_bytes()));
        for x in s.rewards.iter().chain(&s.discounts).chain(&s.weights) {
            eat(&x.to_bits().to_le_bytes());
        }
        s.slots.iter().for_each(|&x| eat(&(x as u64).to_le_bytes()));
    }

    /// Stack 1 is the replay as it was before frame stacks: interleaved streams, episode ends,
    /// n-step returns and prioritized sampling under a byte cap that overwrites frames hand out
    /// exactly the samples, retirements and sizes that the replay without stacks handed out
    /// (the fingerprints were taken from it).
    #[test]
    fn stack_1_samples_exactly_what_the_replay_without_stacks_sampled() {
        let mut got = Vec::new();
        for (n_step, prioritized) in [(1, false), (3, true)] {
            let cfg = ReplayConfig { max_bytes: 40 * frame_cost(4, 0) + 200 * TRANSITION_BYTES, n_step, prioritized, ..cfg(200) };
            let mut r = Replay::new(cfg);
            let mut rng = ChaCha8Rng::seed_from_u64(11);
            let mut t = [0u32; 3];
            let mut ep = [0u64; 3];
            let mut h = 0xcbf2_9ce4_8422_2325u64;
            for _ in 0..300 {
                let stream = rng.random_range(0..3usize);
                let n = rng.random_range(1..=4u32).min(10 - t[stream]);
                let imgs: Vec<[u8; 4]> = (0..n).map(|k| [stream as u8, ep[stream] as u8, (t[stream] + k) as u8, rng.random()]).collect();
                let recs: Vec<StepRecord<'_>> = imgs
                    .iter()
                    .enumerate()
                    .map(|(k, img)| {
                        let tt = t[stream] + k as u32;
                        StepRecord {
                            env: stream as u32,
                            episode: ep[stream],
                            t: tt,
                            image: img,
                            speed: tt as f32,
                            d: stream as f32,
                            path: [0.0; PATH_FEATURES],
                            vector: Default::default(),
                            action: tt % 3,
                            reward: tt as f32 * 0.25,
                            terminated: tt == 9,
                            truncated: false,
                        }
                    })
                    .collect();
                r.add_steps("a", &recs);
                t[stream] += n;
                if t[stream] == 10 {
                    t[stream] = 0;
                    ep[stream] += 1;
                }
                if let Some(s) = r.sample(16) {
                    fingerprint(&mut h, &s);
                    if prioritized {
                        let td: Vec<f32> = (0..16).map(|_| rng.random_range(0.0..2.0)).collect();
                        r.update_priorities(&s.slots, &td);
                    }
                }
                h ^= r.len() as u64 ^ (r.evicted() << 20) ^ (r.frames_held() << 40);
            }
            assert!(r.evicted() > 0, "the ring overwrote frames");
            got.push(h);
        }
        assert_eq!(got, [4002351331951892827, 17818935059842010881]);
    }
}
