//! Learning: the DQN (online and target networks, Adam) and the loop that trains it from replay.

pub mod dqn;
pub mod trainer;
