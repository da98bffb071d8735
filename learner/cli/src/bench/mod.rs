//! `learner bench`: the cost of a full DQN update, ingestion throughput over gRPC on loopback, and
//! the whole loop (a learner and actor processes), each printed as JSON beside the machine.

pub mod candle;
pub mod ingest;
pub mod machine;
pub mod many_actors;
pub mod synthetic_actor;
pub mod update;
pub mod whole_loop;

pub use ingest::ingest;
pub use many_actors::many_actors;
pub use update::train;
pub use whole_loop::{loop_config, whole_loop};

/// Parses `WxHxC`, e.g. `84x84x3`.
pub fn parse_input(s: &str) -> Result<(usize, usize, usize), String> {
    let parts: Vec<&str> = s.split('x').collect();
    let [w, h, c] = parts.as_slice() else { return Err(format!("`{s}` is not WIDTHxHEIGHTxCHANNELS, e.g. 84x84x3")) };
    let num = |v: &str| v.parse::<usize>().map_err(|_| format!("`{v}` in `{s}` is not a whole number"));
    let (w, h, c) = (num(w)?, num(h)?, num(c)?);
    if !(8..=1024).contains(&w) || !(8..=1024).contains(&h) || !(c == 1 || c == 3) {
        return Err(format!("`{s}`: width and height must be 8..=1024 and channels 1 or 3"));
    }
    Ok((w, h, c))
}
