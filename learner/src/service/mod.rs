//! What actors talk to: the gRPC service and what it accepts from whom.

pub mod auth;
pub mod backpressure;
pub mod bounds;
pub mod rpc;
pub mod tls;
pub mod validate;

pub use rpc::{LearnerService, status};
