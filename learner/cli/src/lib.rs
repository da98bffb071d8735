//! The `learner` program's tools beside the service: plots of runs, benchmarks, `learner status`,
//! `learner health` and certificates for TLS. They use the service library (`learner`) as any
//! client would; none of this is linked into actors.

pub mod bench;
pub mod certs;
pub mod health;
pub mod plot;
pub mod reflection;
pub mod status;
