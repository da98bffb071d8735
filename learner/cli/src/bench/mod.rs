//! `learner bench`: the cost of a full DQN update, ingestion throughput over gRPC on loopback, and
//! the whole loop (a learner and actor processes), each printed as JSON beside the machine.

pub mod candle;
pub mod ingest;
pub mod input;
pub mod machine;
pub mod many_actors;
pub mod synthetic_actor;
pub mod update;
pub mod whole_loop;

pub use ingest::ingest;
pub use input::{Input, parse_input};
pub use many_actors::many_actors;
pub use update::train;
pub use whole_loop::{loop_config, whole_loop};
