//! `Sim`: one environment for `hybrid_drive.HybridDriveEnv`. Steps run with the GIL released.

use std::time::{Duration, Instant};

use numpy::PyArray3;
use pyo3::IntoPyObjectExt;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use sim_core::vehicle::Action;

use crate::config::SimConfig;
use crate::convert::{self, image_array};
use crate::errors::{action_index, env_error};
use crate::slot::Slot;

#[pyclass(module = "hybrid_drive._core")]
#[derive(Debug)]
pub struct Sim {
    cfg: Py<SimConfig>,
    slot: Slot,
    /// Time spent in `reset` and `step` calls, and in the simulator within them (for the
    /// benchmark's profile).
    time_in_calls: Duration,
    time_in_sim: Duration,
}

#[pymethods]
impl Sim {
    #[new]
    #[pyo3(signature = (cfg, seed=0))]
    fn new(py: Python<'_>, cfg: Py<SimConfig>, seed: u64) -> PyResult<Self> {
        let c = cfg.get();
        let slot = py.detach(|| Slot::new(c, seed)).map_err(env_error)?;
        Ok(Self { cfg, slot, time_in_calls: Duration::ZERO, time_in_sim: Duration::ZERO })
    }

    /// Starts an episode (with `seed`, or the next seed of the stream the last seed started) on
    /// the current route, or on `route` from now on. Returns `(observation, info)`.
    #[pyo3(signature = (seed=None, route=None))]
    fn reset<'py>(&mut self, py: Python<'py>, seed: Option<u64>, route: Option<&str>) -> PyResult<Bound<'py, PyTuple>> {
        let start = Instant::now();
        let cfg = self.cfg.get();
        if let Some(name) = route {
            (self.slot.route, self.slot.scenario) = cfg.scenario_named(name)?;
        }
        let slot = &mut self.slot;
        let sim = Instant::now();
        let obs = py.detach(|| slot.reset(seed)).map_err(env_error)?;
        self.time_in_sim += sim.elapsed();
        let obs = convert::observation(py, cfg, obs)?;
        let info = convert::info(py, self.slot.env.info(), self.slot.route, self.slot.episode_seed())?;
        self.time_in_calls += start.elapsed();
        PyTuple::new(py, [obs.into_any(), info.into_any()])
    }

    /// One step under the action with index `action`: `(observation, reward, terminated,
    /// truncated, info)`.
    fn step<'py>(&mut self, py: Python<'py>, action: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyTuple>> {
        let start = Instant::now();
        let cfg = self.cfg.get();
        let a: Action = cfg.actions[action_index(action, cfg.actions.len())?];
        let slot = &mut self.slot;
        let sim = Instant::now();
        let r = py.detach(|| slot.step(a)).map_err(env_error)?;
        self.time_in_sim += sim.elapsed();
        let info = convert::info(py, &r.info, self.slot.route, self.slot.episode_seed())?;
        let obs = convert::observation(py, cfg, r.observation)?;
        self.time_in_calls += start.elapsed();
        PyTuple::new(
            py,
            [
                obs.into_any(),
                f64::from(r.reward).into_bound_py_any(py)?,
                r.terminated.into_bound_py_any(py)?,
                r.truncated.into_bound_py_any(py)?,
                info.into_any(),
            ],
        )
    }

    /// The bird's-eye view around the ego vehicle: RGB, (size, size, 3).
    fn render<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray3<u8>> {
        let view = &self.cfg.get().birdseye;
        let env = &mut self.slot.env;
        image_array(py, py.detach(|| env.birdseye(view)))
    }

    /// Seconds spent inside `reset` and `step` so far, and in the simulator within them:
    /// `(in_calls, in_sim)`.
    fn timings(&self) -> (f64, f64) {
        (self.time_in_calls.as_secs_f64(), self.time_in_sim.as_secs_f64())
    }

    /// A hash of the whole dynamic state (ego, traffic, route progress): equal after the same seed
    /// and actions.
    fn state_hash(&self) -> u64 {
        self.slot.env.state_hash()
    }

    /// Diagnostics of the last step, as `step` returns them in `info`.
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        convert::info(py, self.slot.env.info(), self.slot.route, self.slot.episode_seed())
    }

    /// Whether the episode has ended (`step` then raises until `reset`).
    #[getter]
    fn done(&self) -> bool {
        self.slot.env.is_done()
    }

    #[getter]
    fn route(&self) -> &'static str {
        self.slot.route
    }

    fn __repr__(&self) -> String {
        format!("Sim(route={:?}, episode_seed={}, steps={})", self.slot.route, self.slot.episode_seed(), self.slot.env.steps())
    }
}
