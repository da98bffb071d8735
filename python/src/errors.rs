//! How simulator errors and bad arguments become Python exceptions: the simulator's message, the
//! bad value and what would be valid.

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use sim_core::env::EnvError;

/// A simulator error as the Python exception that fits it, with the simulator's message.
pub fn env_error(e: EnvError) -> PyErr {
    match e {
        EnvError::EpisodeOver => PyRuntimeError::new_err(e.to_string()),
        EnvError::Config(_) | EnvError::ScenarioNotOnMap(_) | EnvError::NoRandomRoute { .. } => PyValueError::new_err(e.to_string()),
    }
}

/// The action index in `action` (a Python or NumPy integer), checked against `n` actions.
pub fn action_index(action: &Bound<'_, PyAny>, n: usize) -> PyResult<usize> {
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
