//! `rust_loop`: the benchmark's baseline, the Python benchmark's loop (step, reset when an episode
//! ends) run in Rust on one environment, so that `python -m hybrid_drive.bench` can say how much of
//! a step's time the binding and Python add.

use std::time::Instant;

use numpy::PyReadonlyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::config::SimConfig;
use crate::errors::env_error;
use crate::slot::Slot;

/// Steps a new environment of `cfg` (reset with `seed`) under the action indices `actions`,
/// resetting it whenever an episode ends, with the GIL released. Returns `(steps, episodes,
/// seconds)`, the time covering steps and resets.
#[pyfunction]
pub fn rust_loop(py: Python<'_>, cfg: &SimConfig, actions: PyReadonlyArray1<'_, i64>, seed: u64) -> PyResult<(usize, usize, f64)> {
    let n = cfg.actions.len();
    let actions: Vec<usize> = actions
        .as_slice()?
        .iter()
        .map(|&a| usize::try_from(a).ok().filter(|&i| i < n).ok_or_else(|| PyValueError::new_err(format!("action {a} is not in 0..{n}"))))
        .collect::<PyResult<_>>()?;
    let mut slot = Slot::new(cfg, seed).map_err(env_error)?;
    py.detach(|| {
        let mut episodes = 0;
        let start = Instant::now();
        for &a in &actions {
            let r = slot.step(cfg.actions[a])?;
            if r.terminated || r.truncated {
                slot.reset(None)?;
                episodes += 1;
            }
        }
        Ok((actions.len(), episodes, start.elapsed().as_secs_f64()))
    })
    .map_err(env_error)
}
