//! The learner: replay buffer, DQN training on the fast CPU network (`fastnet`), checkpoints,
//! weight broadcast, status and metrics. The Q-network's definition (`net`) and its fast
//! implementation (`fastnet`) are shared with the actor, which links this library for inference.

pub mod bench;
pub mod checkpoint;
pub mod config;
pub mod dqn;
pub mod fastnet;
pub mod metrics;
pub mod net;
pub mod plot;
pub mod replay;
pub mod serve;
pub mod service;
pub mod state;
pub mod status;
pub mod train;
