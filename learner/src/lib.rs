//! The learner: the training service. It holds the replay buffer, trains the DQN (on the agent's
//! `fastnet`), writes checkpoints, publishes weights to actors and reports status and metrics.
//! What the agent is (network, weights files, configuration, inputs) lives in the `agent` crate.

pub mod auth;
pub mod bench;
pub mod bounds;
pub mod certs;
pub mod checkpoint;
pub mod dqn;
pub mod metrics_log;
#[cfg(feature = "plot")]
pub mod plot;
pub mod progress;
pub mod prometheus;
pub mod records;
pub mod replay;
pub mod run_lock;
pub mod run_map;
pub mod serve;
pub mod service;
pub mod state;
pub mod status;
pub mod sum_tree;
pub mod tfevents;
pub mod tls;
pub mod train;
pub mod validate;
pub mod versions;
pub mod wal;
