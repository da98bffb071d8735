//! Wire types of the actor–learner protocol (gRPC). The `.proto` files and their generated code
//! arrive with the learner service; nothing else belongs in this crate.
