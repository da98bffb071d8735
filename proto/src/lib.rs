//! The wire of the actor–learner protocol (gRPC, package `hybriddrive.v1`): the types generated
//! from `proto/hybriddrive/v1/learner.proto` ([`v1`]), and what both ends share to speak it —
//! connection settings, the bearer token and connecting ([`client`]), plaintext or TLS to an
//! address ([`target`]), failures told apart ([`failure`]), raw bytes as messages for tests and probes ([`raw`]), the clients' shared flags ([`cli`]), how the programs start (logging and runtime,
//! [`program`]) and stopping on a signal ([`shutdown`]). No domain types: both ends convert to their own at the edge.

#[cfg(feature = "cli")]
pub mod cli;
pub mod client;
pub mod failure;
#[cfg(feature = "cli")]
pub mod program;
pub mod raw;
pub mod shutdown;
pub mod target;

/// Version 1 of the protocol.
#[allow(missing_debug_implementations, clippy::all, clippy::pedantic)]
pub mod v1 {
    tonic::include_proto!("hybriddrive.v1");

    /// The protocol revision an actor states in `Register`; the learner refuses any other.
    pub const PROTOCOL: u32 = 1;

    /// The values of `EpisodeSummary.outcome`: one definition for the actor that sends them and
    /// the learner that checks them.
    pub mod outcome {
        /// The episode reached its destination.
        pub const ARRIVED: &str = "arrived";
        /// The episode ended in a collision.
        pub const COLLISION: &str = "collision";
        /// The episode hit its time limit (truncated).
        pub const TIMEOUT: &str = "timeout";
    }

    /// The encoded file descriptor set, for gRPC server reflection.
    pub const FILE_DESCRIPTOR_SET: &[u8] = tonic::include_file_descriptor_set!("hybriddrive_v1_descriptor");
}
