//! The wire of the actor–learner protocol (gRPC, package `hybriddrive.v1`): the types generated
//! from `proto/hybriddrive/v1/learner.proto` ([`v1`]), and what both ends share to speak it —
//! connection settings, the bearer token and connecting ([`client`]), and stopping on a signal
//! ([`shutdown`]). No domain types: both ends convert to their own at the edge.

pub mod client;
pub mod shutdown;

/// Version 1 of the protocol.
#[allow(missing_debug_implementations, clippy::all, clippy::pedantic)]
pub mod v1 {
    tonic::include_proto!("hybriddrive.v1");

    /// The protocol revision an actor states in `Register`; the learner refuses any other.
    pub const PROTOCOL: u32 = 1;

    /// The encoded file descriptor set, for gRPC server reflection.
    pub const FILE_DESCRIPTOR_SET: &[u8] = tonic::include_file_descriptor_set!("hybriddrive_v1_descriptor");
}
