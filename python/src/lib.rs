//! `hybrid_drive._core`: the Python binding of `sim-core`, a thin layer that the Python package
//! `hybrid_drive` (python/hybrid_drive/) wraps as a Gymnasium environment and vector environment.
//!
//! `SimConfig` checks what the user asked for once; `Sim` is one environment; `VecSim` steps N on a
//! thread pool with the GIL released and returns batched NumPy arrays. No simulator logic lives
//! here or in Python: episodes, rewards, rendering and routes are `sim_core::env::Env`'s.

mod bench;
mod config;
mod convert;
mod reference;
mod single;
mod slot;
mod vector;

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use sim_core::env::EnvError;

/// A simulator error as the Python exception that fits it, with the simulator's message.
fn env_error(e: EnvError) -> PyErr {
    match e {
        EnvError::EpisodeOver => PyRuntimeError::new_err(e.to_string()),
        EnvError::Config(_) | EnvError::ScenarioNotOnMap(_) | EnvError::NoRandomRoute { .. } => PyValueError::new_err(e.to_string()),
    }
}

/// The action index in `action` (a Python or NumPy integer), checked against `n` actions.
fn action_index(action: &Bound<'_, PyAny>, n: usize) -> PyResult<usize> {
    let a: i64 = action.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "action {} is not an integer: expected an index in 0..={}",
            action.repr().map_or_else(|_| "?".into(), |r| r.to_string()),
            n - 1
        ))
    })?;
    usize::try_from(a)
        .ok()
        .filter(|&i| i < n)
        .ok_or_else(|| PyValueError::new_err(format!("action {a} is not an action: expected 0..={}", n - 1)))
}

#[pymodule]
#[pyo3(name = "_core")]
fn core_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<config::SimConfig>()?;
    m.add_class::<single::Sim>()?;
    m.add_class::<vector::VecSim>()?;
    m.add_function(wrap_pyfunction!(reference::reference_rollout, m)?)?;
    m.add_function(wrap_pyfunction!(bench::rust_loop, m)?)?;
    m.add("ROUTES", config::route_names())?;
    m.add("COLLISION_KINDS", convert::COLLISION_KINDS.to_vec())?;
    Ok(())
}
