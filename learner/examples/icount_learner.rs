//! The network's, the replay's and the service's instruction-count benchmarks, run under
//! callgrind by `scripts/bench-check.sh` (docs/PERFORMANCE.md, "Instruction counts"); the
//! simulator's are `sim-core/examples/icount_sim.rs`. `icount_learner list` names them; `icount_learner run NAME` sets
//! one up and runs its measured work inside [`icount_measured`], the only function callgrind
//! counts, then prints one JSON line (bench, iterations, the CPU features this process saw).
//!
//! Valgrind serialises threads and cannot count a syscall's kernel side, so each path is its
//! single-threaded variant: the network on one thread (as an actor runs it), the replay log's
//! record encoding and write to a file (the committer's fsync is not counted), and the Status
//! handler's work (`service::status` and the reply's encoding) called directly, without gRPC.
//!
//! The network's benches are small (a few images, no warm-up call: a count is the same at every
//! call, first or not, save the buffers' allocation): valgrind runs `gemm`'s FMA kernels through
//! helper calls, many times slower than other code, so a batch-32 update would take minutes.

use std::collections::VecDeque;
use std::hint::black_box;
use std::io::Write;
use std::sync::Mutex;

use agent::checkpoint::Counters;
use agent::config::RunConfig;
use agent::fastnet::{Inference, Params};
use learner::shared_state::{ActorRecord, EpisodeOutcome, PublishedWeights, Shared, SharedStart, TrainStats};
use learner::storage::replay::{Replay, ReplayConfig, StepRecord};
use learner::storage::replay_log::format;
use learner::storage::versions::VersionLease;
use learner::telemetry::metrics_log::MetricsLog;
use learner::training::dqn::{Batch, Dqn};
use prost::Message;
use sim_core::env::PATH_FEATURES;

#[path = "../../benches/icount.rs"]
mod icount;

/// The benches: name, what one iteration is.
const BENCHES: &[(&str, &str)] = &[
    ("forward_b1_48x48", "one forward pass, batch 1, hybrid-tuned network (48x48 gray), 1 thread"),
    ("forward_b4_48x48", "one forward pass, batch 4 (an actor's 4 environments), 1 thread"),
    ("update_b4_48x48", "one DQN update of the hybrid-tuned network (double DQN, Adam), batch 4, 1 thread"),
    ("replay_insert_sample", "insert 32 steps (4 envs x 8) into a 4,000-transition replay, sample 32, update priorities"),
    ("replay_log_append", "encode a 32-step batch as a replay-log record and write it to a file"),
    ("status", "the Status handler's work (2 actors, 100 episodes) and its reply's encoding"),
];

/// The counted region: callgrind collects only while this function runs.
#[inline(never)]
fn icount_measured(work: &mut dyn FnMut()) {
    work();
}

/// The preset `actor train` runs by default.
fn config() -> RunConfig {
    let mut cfg = RunConfig::preset("hybrid-tuned").expect("a known preset");
    // valgrind runs neither AMX nor AVX-512: the counts are the f32 path's, on every machine.
    cfg.agent.precision = agent::fastnet::Precision::F32;
    cfg
}

/// Deterministic pseudo-random bytes (a frame's worth of texture).
fn noise(n: usize, seed: u32) -> Vec<u8> {
    (0..n as u32).map(|i| ((i ^ seed).wrapping_mul(2_654_435_761) >> 11) as u8).collect()
}

fn forward(batch: usize, calls: u64) -> u64 {
    let cfg = config();
    let shape = cfg.net_shape();
    let frame = shape.height * shape.width * shape.channels;
    let mut net = Inference::with_params(Params::init(shape, 1), 1);
    let images = noise(batch * frame, 7);
    let scalars = vec![0.5f32; batch * shape.scalars];
    for _ in 0..calls {
        icount_measured(&mut || {
            black_box(net.q_values(images.chunks_exact(frame), &scalars));
        });
    }
    calls
}

fn update(n: usize, updates: u64) -> u64 {
    let cfg = config();
    let shape = cfg.net_shape();
    let frame = shape.height * shape.width * shape.channels;
    let batch = Batch {
        images: noise(n * frame, 1),
        scalars: (0..n * shape.scalars).map(|i| (i % 7) as f32 / 7.0).collect(),
        actions: (0..n as u32).map(|i| i % shape.actions as u32).collect(),
        rewards: (0..n).map(|i| (i % 5) as f32 / 5.0 - 0.4).collect(),
        next_images: noise(n * frame, 2),
        next_scalars: (0..n * shape.scalars).map(|i| (i % 5) as f32 / 5.0).collect(),
        discounts: (0..n).map(|i| if i % 9 == 0 { 0.0 } else { 0.97 }).collect(),
        weights: vec![1.0; n],
        demos: 0,
    };
    let mut dqn = Dqn::with_threads(shape, &cfg.agent, 1);
    for _ in 0..updates {
        icount_measured(&mut || {
            black_box(dqn.update(&batch));
        });
    }
    updates
}

/// A replay as `actor train` makes it, and a stream of steps for it.
struct Steps {
    frame: usize,
    images: Vec<Vec<u8>>,
    t: u32,
}

impl Steps {
    fn new(frame: usize) -> Self {
        Self { frame, images: (0..64).map(|i| noise(frame, i)).collect(), t: 0 }
    }

    /// The next `per_env` steps of 4 environments, episodes of 100 steps.
    fn batch(&mut self, per_env: u32) -> Vec<StepRecord<'_>> {
        let t0 = self.t;
        self.t += per_env;
        let images = &self.images;
        let frame = self.frame;
        (0..per_env)
            .flat_map(|k| {
                let t = t0 + k;
                (0..4u32).map(move |env| StepRecord {
                    env,
                    episode: u64::from(t / 100),
                    t: t % 100,
                    image: &images[((t * 4 + env) % 64) as usize][..frame],
                    speed: (t % 13) as f32,
                    d: 0.1,
                    path: [0.2; PATH_FEATURES],
                    vector: Default::default(),
                    action: t % 6,
                    reward: 0.5,
                    terminated: t % 100 == 99 && env == 0,
                    truncated: t % 100 == 99 && env != 0,
                })
            })
            .collect()
    }
}

fn replay_for(cfg: &RunConfig, frame: usize) -> Replay {
    let a = &cfg.agent;
    Replay::new(ReplayConfig {
        vector_len: 0,
        capacity: 4_000,
        max_bytes: a.replay_max_bytes,
        frame_bytes: frame,
        channels: cfg.net_shape().channels,
        stack: 1,
        gamma: a.gamma,
        n_step: a.n_step,
        prioritized: a.prioritized_replay,
        alpha: a.priority_alpha,
        beta: a.priority_beta,
        seed: a.seed,
    })
}

fn replay_insert_sample(rounds: u64) -> u64 {
    let cfg = config();
    let shape = cfg.net_shape();
    let frame = shape.height * shape.width * shape.channels;
    let mut replay = replay_for(&cfg, frame);
    let mut steps = Steps::new(frame);
    // Full, so that every insert also evicts.
    while replay.len() < replay.capacity() {
        replay.add_steps("actor-0", &steps.batch(8));
    }
    let n = cfg.agent.batch_size;
    let td: Vec<f32> = (0..n).map(|i| (i % 10) as f32 / 10.0).collect();
    for _ in 0..rounds {
        let batch = steps.batch(8);
        icount_measured(&mut || {
            black_box(replay.add_steps("actor-0", &batch));
            let sample = replay.sample(n).expect("a full replay");
            replay.update_priorities(&sample.slots, &td);
            black_box(&sample);
        });
    }
    rounds
}

fn replay_log_append(records: u64) -> anyhow::Result<u64> {
    let shape = config().net_shape();
    let frame = shape.height * shape.width * shape.channels;
    let dir = tempfile::tempdir()?;
    let mut file = std::fs::File::create(dir.path().join("0.seg"))?;
    file.write_all(&format::segment_header(format::StepShape::frames(frame)))?;
    let mut steps = Steps::new(frame);
    let mut position = 0u64;
    for _ in 0..records {
        let batch = steps.batch(8);
        let mut written = Ok(());
        icount_measured(&mut || {
            position += 1;
            let payload = format::encode("actor-0", 1, &batch);
            let header = format::record_header(position, &payload);
            written = file.write_all(&header).and_then(|()| file.write_all(&payload));
        });
        written?;
    }
    Ok(records)
}

fn status(calls: u64) -> anyhow::Result<u64> {
    let cfg = config();
    let shape = cfg.net_shape();
    let frame = shape.height * shape.width * shape.channels;
    let dir = tempfile::tempdir()?;
    let mut replay = replay_for(&cfg, frame);
    let mut steps = Steps::new(frame);
    for _ in 0..20 {
        replay.add_steps("actor-0", &steps.batch(8));
    }
    let actors = (0..2u32)
        .map(|i| {
            let mut a = ActorRecord::new(format!("id-{i}"), format!("actor-{i}"), i, 4);
            (a.open_streams, a.weights_version, a.transitions) = (1, 3, 1_000);
            a
        })
        .collect();
    let episodes: VecDeque<EpisodeOutcome> =
        (0..100).map(|i| EpisodeOutcome { episode_return: f64::from(i) / 10.0, arrived: i % 3 == 0, collided: i % 7 == 0 }).collect();
    let counters = Counters { run_id: "icount".into(), learner_step: 100, env_steps: 10_000, ..Counters::default() };
    let mut shared = Shared::new(SharedStart {
        cfg,
        map: None,
        replay,
        counters,
        weights: PublishedWeights { version: 4, bytes: Default::default() },
        metrics: MetricsLog::open(dir.path())?,
        log: None,
        versions: VersionLease::open(dir.path(), 0)?,
        ratio_session: None,
        resumed: false,
    });
    shared.actors = Mutex::new(actors);
    shared.recent_episodes = Mutex::new(episodes);
    shared.stats = Mutex::new(TrainStats { loss: Some(0.1), mean_q: Some(1.0), ..TrainStats::default() });
    for _ in 0..calls {
        icount_measured(&mut || {
            black_box(learner::service::status(&shared).encode_to_vec());
        });
    }
    Ok(calls)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.iter().map(String::as_str).collect::<Vec<_>>().as_slice() {
        ["list"] => icount::list(BENCHES),
        ["run", name] => {
            let iterations = match *name {
                "forward_b1_48x48" => forward(1, 2),
                "forward_b4_48x48" => forward(4, 1),
                "update_b4_48x48" => update(4, 1),
                "replay_insert_sample" => replay_insert_sample(50),
                "replay_log_append" => replay_log_append(50)?,
                "status" => status(200)?,
                other => {
                    let names: Vec<&str> = BENCHES.iter().map(|b| b.0).collect();
                    anyhow::bail!("unknown bench `{other}`: expected one of {}", names.join(", "));
                }
            };
            icount::report(name, iterations);
        }
        _ => anyhow::bail!("usage: icount_learner list | icount_learner run NAME"),
    }
    Ok(())
}
