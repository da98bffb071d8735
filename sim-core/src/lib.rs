//! `sim-core`: a deterministic, synchronous driving simulator for training and evaluating driving
//! agents (the world of the hybrid DRL + A* planner method).
//!
//! It knows nothing of async runtimes, networking or neural networks: an [`env::Env`] is plain data
//! with `reset` and `step`. Same seed and actions give bit-identical trajectories.

pub mod actions;
pub mod astar;
pub mod camera;
pub mod collision;
pub mod config;
pub mod env;
pub mod expert;
pub mod hash;
pub mod hazards;
pub mod map;
pub mod math;
pub mod path_features;
pub mod planner;
pub mod polyline;
pub mod reward;
pub mod reward_ordering;
pub mod route;
pub mod route_types;
pub mod scenario;
pub mod sensor;
pub mod topology;
pub mod town;
pub mod traffic;
pub mod vehicle;
