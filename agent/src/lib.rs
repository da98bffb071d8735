//! `agent`: what the driving agent is, shared by the learner (which trains it) and the actor
//! (which drives with it): its Q-network ([`shape`], computed by [`fastnet`]), its weights file
//! ([`weights`]), its run configuration ([`config`], [`presets`]), how observations become network
//! inputs ([`features`]), how checkpoints are found and verified ([`checkpoint`]) and how a file is
//! replaced atomically ([`atomic_write`]), and the retry waits of both ([`backoff`]).
//!
//! No async runtime, network, plotting or tensor library: candle's version of the network
//! ([`candle_net`]) is behind the `candle` feature, for tests and benchmarks.

pub mod atomic_write;
pub mod backoff;
#[cfg(feature = "candle")]
pub mod candle_net;
pub mod checkpoint;
pub mod config;
pub mod config_docs;
pub mod fastnet;
pub mod features;
pub mod presets;
pub mod shape;
pub mod weights;

pub use config::RunConfig;
pub use shape::NetShape;
