//! Wire types of the actor–learner protocol (gRPC, package `hybriddrive.v1`), generated from
//! `proto/hybriddrive/v1/learner.proto`. Nothing else belongs here: both ends convert to their
//! own domain types at the edge.

#![allow(missing_debug_implementations, clippy::all, clippy::pedantic)]

/// Version 1 of the protocol.
pub mod v1 {
    tonic::include_proto!("hybriddrive.v1");

    /// The encoded file descriptor set, for gRPC server reflection.
    pub const FILE_DESCRIPTOR_SET: &[u8] = tonic::include_file_descriptor_set!("hybriddrive_v1_descriptor");
}
