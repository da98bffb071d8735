//! The learner: the training service. It holds the replay buffer, trains the DQN (on the agent's
//! `fastnet`), writes checkpoints, publishes weights to actors and reports status and metrics.
//! What the agent is (network, weights files, configuration, inputs) lives in the `agent` crate;
//! the `learner` program and its offline tools (plots, benchmarks, `status`, certificates) live in
//! `learner/cli/`, so that this library has no plotting or benchmark code.
//!
//! - [`service`]: the gRPC service actors talk to, what it accepts, authentication, TLS.
//! - [`storage`]: the replay buffer, the replay log, checkpoints, the run directory's files.
//! - [`training`]: the DQN and the training loop.
//! - [`telemetry`]: Prometheus, TensorBoard events, metrics files, the progress line.
//! - [`serve`]: a learner assembled from the above and supervised; [`state`]: what they share.

pub mod serve;
pub mod service;
pub mod shared_state;
pub mod storage;
pub mod telemetry;
pub mod training;
