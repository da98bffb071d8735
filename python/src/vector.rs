//! `VecSim`: N environments stepped together on threads (`pool::Stepper`) with the GIL released,
//! for `hybrid_drive.HybridDriveVectorEnv`. Each call returns batched NumPy arrays: the cameras
//! (or, with `observation="vector"`, the vector sensor's readings) are copied once into one
//! (N, H, W, C) (or (N, len)) buffer that NumPy then owns, with no per-environment Python object.
//!
//! Auto-reset follows Gymnasium's `NEXT_STEP` mode: the step that ends an episode returns its last
//! observation; the next `step` resets that environment (its action is ignored) and returns the new
//! episode's first observation with reward 0 and neither terminated nor truncated.

use std::time::{Duration, Instant};

use numpy::ndarray::{Array2, Array4};
use numpy::{Element, PyArray, PyArray1, PyReadonlyArray1};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use sim_core::config::Variant;
use sim_core::env::PATH_FEATURES;

use crate::config::SimConfig;
use crate::convert::{collision_code, image_array};
use crate::errors::env_error;
use crate::pool::{Job, Outcome, RunError, Stepper};
use crate::slot::Slot;

#[pyclass(module = "hybrid_drive._core")]
#[derive(Debug)]
pub struct VecSim {
    cfg: Py<SimConfig>,
    stepper: Stepper,
    /// Time spent in `reset` and `step` calls, and in their parallel part (for the benchmark's
    /// profile).
    time_in_calls: Duration,
    time_in_threads: Duration,
}

#[pymethods]
impl VecSim {
    /// `num_envs` environments of `cfg`, environment i reset with seed `seed + i`, stepped by
    /// `num_threads` threads, the caller's included (default: the machine's cores, at most one
    /// per environment).
    #[new]
    #[pyo3(signature = (cfg, num_envs, num_threads=None, seed=0))]
    fn new(py: Python<'_>, cfg: Py<SimConfig>, num_envs: usize, num_threads: Option<usize>, seed: u64) -> PyResult<Self> {
        if num_envs == 0 {
            return Err(PyValueError::new_err("num_envs must be at least 1"));
        }
        let cores = std::thread::available_parallelism().map_or(1, usize::from);
        let threads = match num_threads {
            Some(0) => return Err(PyValueError::new_err("num_threads must be at least 1")),
            Some(t) => t.min(num_envs),
            None => cores.min(num_envs),
        };
        let c = cfg.get();
        let slots = py
            .detach(|| (0..num_envs).map(|i| Slot::new(c, seed.wrapping_add(i as u64))).collect::<Result<Vec<_>, _>>())
            .map_err(env_error)?;
        let stepper = Stepper::new(slots, threads).map_err(|e| PyOSError::new_err(format!("starting {threads} stepping threads: {e}")))?;
        Ok(Self { cfg, stepper, time_in_calls: Duration::ZERO, time_in_threads: Duration::ZERO })
    }

    #[getter]
    fn num_envs(&self) -> usize {
        self.stepper.len()
    }

    #[getter]
    fn num_threads(&self) -> usize {
        self.stepper.threads()
    }

    /// Resets every environment: environment i with `seeds[i]`, or without seeds with the next
    /// seed of its stream; on `route` from now on if given. Returns `(observations, infos)`.
    #[pyo3(signature = (seeds=None, route=None))]
    fn reset<'py>(&mut self, py: Python<'py>, seeds: Option<Vec<u64>>, route: Option<&str>) -> PyResult<Bound<'py, PyTuple>> {
        let start = Instant::now();
        let n = self.stepper.len();
        if let Some(s) = &seeds
            && s.len() != n
        {
            return Err(PyValueError::new_err(format!("{} seeds for {n} environments: give one per environment", s.len())));
        }
        if let Some(name) = route {
            let (route, scenario) = self.cfg.get().scenario_named(name)?;
            for i in 0..n {
                let mut slot = self.stepper.slot(i);
                (slot.route, slot.scenario) = (route, scenario);
            }
        }
        let rows = self.run(py, Job::Reset { seeds })?;
        let obs = self.observations(py, &rows)?;
        let info = infos(py, &rows)?;
        self.time_in_calls += start.elapsed();
        PyTuple::new(py, [obs.into_any(), info.into_any()])
    }

    /// Steps environment i under action `actions[i]` (an index into the action set), or resets it
    /// if its episode ended at the previous step. Returns `(observations, rewards, terminated,
    /// truncated, infos)`.
    fn step<'py>(&mut self, py: Python<'py>, actions: PyReadonlyArray1<'py, i64>) -> PyResult<Bound<'py, PyTuple>> {
        let start = Instant::now();
        let set = self.cfg.get().actions;
        let actions = actions.as_slice()?;
        let n = self.stepper.len();
        if actions.len() != n {
            return Err(PyValueError::new_err(format!("{} actions for {n} environments: give one per environment", actions.len())));
        }
        if let Some((i, a)) = actions.iter().enumerate().find(|&(_, &a)| !(0..set.len() as i64).contains(&a)) {
            return Err(PyValueError::new_err(format!("actions[{i}] = {a} is not an action: expected 0..={}", set.len() - 1)));
        }
        // Copied while the GIL is held: Python may write to the array once it is released.
        let actions = actions.iter().map(|&a| set[a as usize]).collect();
        let rows = self.run(py, Job::Step { actions })?;
        let obs = self.observations(py, &rows)?;
        let rewards = column(py, &rows, |r| f64::from(r.reward));
        let terminated = column(py, &rows, |r| r.terminated);
        let truncated = column(py, &rows, |r| r.truncated);
        let info = infos(py, &rows)?;
        self.time_in_calls += start.elapsed();
        PyTuple::new(py, [obs.into_any(), rewards.into_any(), terminated.into_any(), truncated.into_any(), info.into_any()])
    }

    /// The bird's-eye view of each environment.
    fn render<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let view = &self.cfg.get().birdseye;
        let stepper = &self.stepper;
        let images = py.detach(|| (0..stepper.len()).map(|i| stepper.slot(i).env.birdseye(view)).collect::<Vec<_>>());
        PyTuple::new(py, images.into_iter().map(|image| image_array(py, image)))
    }

    /// Seconds spent inside `reset` and `step` so far, and in their parallel part (stepping,
    /// resetting and rendering the environments on the threads): `(in_calls, in_threads)`.
    fn timings(&self) -> (f64, f64) {
        (self.time_in_calls.as_secs_f64(), self.time_in_threads.as_secs_f64())
    }

    /// Each environment's `state_hash` (see `Sim.state_hash`).
    fn state_hashes(&self) -> Vec<u64> {
        (0..self.stepper.len()).map(|i| self.stepper.slot(i).env.state_hash()).collect()
    }

    fn __repr__(&self) -> String {
        format!("VecSim(num_envs={}, num_threads={}, route={:?})", self.stepper.len(), self.stepper.threads(), self.cfg.get().route)
    }
}

impl VecSim {
    /// Runs `job` on every environment, without the GIL.
    fn run(&mut self, py: Python<'_>, job: Job) -> PyResult<Vec<Outcome>> {
        let start = Instant::now();
        let stepper = &self.stepper;
        let outcomes = py.detach(|| stepper.run(job));
        self.time_in_threads += start.elapsed();
        outcomes.map_err(|e| match e {
            RunError::Env(e) => env_error(e),
            RunError::Panic(message) => PyRuntimeError::new_err(format!("the simulator panicked: {message}")),
        })
    }

    /// The batched observation: with `observation="vector"` the readings as one (N, len) array,
    /// else the dict of `camera` (N, H, W, C), `speed` (N, 1), `d` (N, 1), `path` (N, 3).
    fn observations<'py>(&self, py: Python<'py>, rows: &[Outcome]) -> PyResult<Bound<'py, PyAny>> {
        let cfg = self.cfg.get();
        let n = rows.len();
        if cfg.vector {
            let len = cfg.env.vector.as_ref().expect("observation=\"vector\" configures [env.vector]").len(cfg.env.variant);
            let mut values = Vec::with_capacity(n * len);
            for r in rows {
                values.extend_from_slice(r.observation.vector.as_deref().expect("[env.vector] is configured"));
            }
            let array = Array2::from_shape_vec((n, len), values).expect("one reading of the layout's length per environment");
            return Ok(PyArray::from_owned_array(py, array).into_any());
        }
        let dict = PyDict::new(py);
        if let Some(c) = &cfg.env.camera {
            let shape = (n, c.height as usize, c.width as usize, c.stacked_channels());
            let mut camera = Vec::with_capacity(shape.0 * shape.1 * shape.2 * shape.3);
            for r in rows {
                camera.extend_from_slice(&r.observation.image.as_ref().expect("a camera is configured").data);
            }
            let array = Array4::from_shape_vec(shape, camera).expect("one frame per environment");
            dict.set_item(intern!(py, "camera"), PyArray::from_owned_array(py, array))?;
        }
        let matrix = |width: usize, values: Vec<f32>| {
            PyArray::from_owned_array(py, Array2::from_shape_vec((n, width), values).expect("width values per environment"))
        };
        dict.set_item(intern!(py, "speed"), matrix(1, rows.iter().map(|r| r.observation.speed).collect()))?;
        if cfg.env.variant == Variant::Hybrid {
            dict.set_item(intern!(py, "d"), matrix(1, rows.iter().map(|r| r.observation.d.unwrap_or(0.0)).collect()))?;
        }
        if cfg.path_features {
            let path = rows.iter().flat_map(|r| r.observation.path.unwrap_or_default()).collect();
            dict.set_item(intern!(py, "path"), matrix(PATH_FEATURES, path))?;
        }
        Ok(dict.into_any())
    }
}

fn column<'py, T: Element>(py: Python<'py>, rows: &[Outcome], f: impl Fn(&Outcome) -> T) -> Bound<'py, PyArray1<T>> {
    PyArray1::from_iter(py, rows.iter().map(f))
}

/// The batched info dict: one array of N values per key (the single env's keys, with `collision`
/// as an index into `COLLISION_KINDS`).
fn infos<'py>(py: Python<'py>, rows: &[Outcome]) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item(intern!(py, "r_v"), column(py, rows, |r| r.info.reward_terms.r_v))?;
    dict.set_item(intern!(py, "r_l"), column(py, rows, |r| r.info.reward_terms.r_l))?;
    dict.set_item(intern!(py, "r_w"), column(py, rows, |r| r.info.reward_terms.r_w))?;
    dict.set_item(intern!(py, "collision"), column(py, rows, |r| collision_code(r.info.collision)))?;
    dict.set_item(intern!(py, "arrived"), column(py, rows, |r| r.info.arrived))?;
    dict.set_item(intern!(py, "progress"), column(py, rows, |r| r.info.progress))?;
    dict.set_item(intern!(py, "d"), column(py, rows, |r| r.info.d))?;
    dict.set_item(intern!(py, "l"), column(py, rows, |r| r.info.l))?;
    dict.set_item(intern!(py, "speed"), column(py, rows, |r| r.info.speed))?;
    dict.set_item(intern!(py, "steps"), column(py, rows, |r| i64::from(r.info.steps)))?;
    dict.set_item(intern!(py, "seed"), column(py, rows, |r| r.seed))?;
    Ok(dict)
}
