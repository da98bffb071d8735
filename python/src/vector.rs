//! `VecSim`: N environments stepped together on a thread pool with the GIL released, for
//! `hybrid_drive.HybridDriveVectorEnv`. Each call returns batched NumPy arrays; the cameras render
//! into one (N, H, W, C) buffer that NumPy then owns, with no per-environment Python object.
//!
//! Auto-reset follows Gymnasium's `NEXT_STEP` mode: the step that ends an episode returns its last
//! observation; the next `step` resets that environment (its action is ignored) and returns the new
//! episode's first observation with reward 0 and neither terminated nor truncated.

use std::time::{Duration, Instant};

use numpy::ndarray::{Array2, Array4};
use numpy::{Element, PyArray, PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use rayon::prelude::*;
use rayon::{ThreadPool, ThreadPoolBuilder};
use sim_core::env::{EnvError, Observation, PATH_FEATURES, StepInfo};

use crate::config::SimConfig;
use crate::convert::{collision_code, image_array};
use crate::errors::env_error;
use crate::slot::Slot;

#[pyclass(module = "hybrid_drive._core")]
#[derive(Debug)]
pub struct VecSim {
    cfg: Py<SimConfig>,
    slots: Vec<Slot>,
    /// `None` steps on the calling thread (one thread asked for, or one environment).
    pool: Option<ThreadPool>,
    threads: usize,
    /// Time spent in `reset` and `step` calls, and in their parallel part (for the benchmark's
    /// profile).
    time_in_calls: Duration,
    time_in_threads: Duration,
}

/// What one environment contributes to a batch, besides its camera image.
#[derive(Debug)]
struct Row {
    speed: f32,
    d: f32,
    path: [f32; PATH_FEATURES],
    reward: f32,
    terminated: bool,
    truncated: bool,
    info: StepInfo,
    seed: u64,
}

impl Row {
    fn new(obs: Observation, frame: &mut [u8], reward: f32, terminated: bool, truncated: bool, slot: &Slot) -> Self {
        if let Some(image) = &obs.image {
            frame.copy_from_slice(&image.data);
        }
        Self {
            speed: obs.speed,
            d: obs.d.unwrap_or(0.0),
            path: obs.path.unwrap_or_default(),
            reward,
            terminated,
            truncated,
            info: slot.env.info().clone(),
            seed: slot.episode_seed(),
        }
    }
}

#[pymethods]
impl VecSim {
    /// `num_envs` environments of `cfg`, environment i reset with seed `seed + i`; `num_threads`
    /// defaults to the machine's cores (at most one per environment).
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
        let pool = if threads > 1 {
            let pool = ThreadPoolBuilder::new()
                .num_threads(threads)
                .thread_name(|i| format!("hybrid-drive-{i}"))
                .build()
                .map_err(|e| PyValueError::new_err(format!("starting {threads} threads: {e}")))?;
            Some(pool)
        } else {
            None
        };
        let c = cfg.get();
        let make = |i: usize| Slot::new(c, seed.wrapping_add(i as u64));
        let slots = py
            .detach(|| match &pool {
                Some(pool) => pool.install(|| (0..num_envs).into_par_iter().map(make).collect::<Result<Vec<_>, _>>()),
                None => (0..num_envs).map(make).collect(),
            })
            .map_err(env_error)?;
        Ok(Self { cfg, slots, pool, threads, time_in_calls: Duration::ZERO, time_in_threads: Duration::ZERO })
    }

    #[getter]
    fn num_envs(&self) -> usize {
        self.slots.len()
    }

    #[getter]
    fn num_threads(&self) -> usize {
        self.threads
    }

    /// Resets every environment: environment i with `seeds[i]`, or without seeds with the next
    /// seed of its stream; on `route` from now on if given. Returns `(observations, infos)`.
    #[pyo3(signature = (seeds=None, route=None))]
    fn reset<'py>(&mut self, py: Python<'py>, seeds: Option<Vec<u64>>, route: Option<&str>) -> PyResult<Bound<'py, PyTuple>> {
        let start = Instant::now();
        let n = self.slots.len();
        if let Some(s) = &seeds
            && s.len() != n
        {
            return Err(PyValueError::new_err(format!("{} seeds for {n} environments: give one per environment", s.len())));
        }
        if let Some(name) = route {
            let (route, scenario) = self.cfg.get().scenario_named(name)?;
            for slot in &mut self.slots {
                (slot.route, slot.scenario) = (route, scenario);
            }
        }
        let (camera, rows) = self.run(py, |i, slot, frame| {
            let obs = slot.reset(seeds.as_ref().map(|s| s[i]))?;
            Ok(Row::new(obs, frame, 0.0, false, false, slot))
        })?;
        let obs = self.observations(py, camera, &rows)?;
        let info = infos(py, &rows)?;
        self.time_in_calls += start.elapsed();
        PyTuple::new(py, [obs.into_any(), info.into_any()])
    }

    /// Steps environment i under action `actions[i]` (an index into the action set), or resets it
    /// if its episode ended at the previous step. Returns `(observations, rewards, terminated,
    /// truncated, infos)`.
    fn step<'py>(&mut self, py: Python<'py>, actions: PyReadonlyArray1<'py, i64>) -> PyResult<Bound<'py, PyTuple>> {
        let start = Instant::now();
        let cfg = self.cfg.get();
        let actions = actions.as_slice()?;
        let n = self.slots.len();
        if actions.len() != n {
            return Err(PyValueError::new_err(format!("{} actions for {n} environments: give one per environment", actions.len())));
        }
        let set = cfg.actions;
        if let Some((i, a)) = actions.iter().enumerate().find(|&(_, &a)| !(0..set.len() as i64).contains(&a)) {
            return Err(PyValueError::new_err(format!("actions[{i}] = {a} is not an action: expected 0..={}", set.len() - 1)));
        }
        // Copied while the GIL is held: Python may write to the array once it is released.
        let actions: Vec<usize> = actions.iter().map(|&a| a as usize).collect();
        let (camera, rows) = self.run(py, |i, slot, frame| {
            if slot.env.is_done() {
                let obs = slot.reset(None)?;
                return Ok(Row::new(obs, frame, 0.0, false, false, slot));
            }
            let r = slot.step(set[actions[i]])?;
            Ok(Row::new(r.observation, frame, r.reward, r.terminated, r.truncated, slot))
        })?;
        let obs = self.observations(py, camera, &rows)?;
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
        let slots = &mut self.slots;
        let images = py.detach(|| slots.iter_mut().map(|s| s.env.birdseye(view)).collect::<Vec<_>>());
        PyTuple::new(py, images.into_iter().map(|image| image_array(py, image)))
    }

    /// Seconds spent inside `reset` and `step` so far, and in their parallel part (stepping,
    /// resetting and rendering the environments on the threads): `(in_calls, in_threads)`.
    fn timings(&self) -> (f64, f64) {
        (self.time_in_calls.as_secs_f64(), self.time_in_threads.as_secs_f64())
    }

    /// Each environment's `state_hash` (see `Sim.state_hash`).
    fn state_hashes(&self) -> Vec<u64> {
        self.slots.iter().map(|s| s.env.state_hash()).collect()
    }

    fn __repr__(&self) -> String {
        format!("VecSim(num_envs={}, num_threads={}, route={:?})", self.slots.len(), self.threads, self.cfg.get().route)
    }
}

impl VecSim {
    /// Runs `f` on every environment (on the pool, without the GIL), each with its slice of a
    /// fresh camera buffer. Returns the buffer and the rows in environment order.
    fn run<F>(&mut self, py: Python<'_>, f: F) -> PyResult<(Vec<u8>, Vec<Row>)>
    where
        F: Fn(usize, &mut Slot, &mut [u8]) -> Result<Row, EnvError> + Send + Sync,
    {
        let n = self.slots.len();
        let frame = self.frame_len();
        let mut camera = vec![0u8; n * frame];
        let slots = &mut self.slots;
        let pool = &self.pool;
        let start = Instant::now();
        let rows = py.detach(|| {
            let frames: Vec<&mut [u8]> =
                if frame == 0 { (0..n).map(|_| <&mut [u8]>::default()).collect() } else { camera.chunks_mut(frame).collect() };
            match pool {
                Some(pool) => pool.install(|| {
                    slots.par_iter_mut().zip(frames).enumerate().map(|(i, (slot, fr))| f(i, slot, fr)).collect::<Result<Vec<_>, _>>()
                }),
                None => slots.iter_mut().zip(frames).enumerate().map(|(i, (slot, fr))| f(i, slot, fr)).collect(),
            }
        });
        self.time_in_threads += start.elapsed();
        Ok((camera, rows.map_err(env_error)?))
    }

    fn frame_len(&self) -> usize {
        self.cfg.get().env.camera.as_ref().map_or(0, |c| c.width as usize * c.height as usize * usize::from(c.channels()))
    }

    /// The batched observation dict: `camera` (N, H, W, C), `speed` (N, 1), `d` (N, 1), `path` (N, 3).
    fn observations<'py>(&self, py: Python<'py>, camera: Vec<u8>, rows: &[Row]) -> PyResult<Bound<'py, PyDict>> {
        let cfg = self.cfg.get();
        let n = rows.len();
        let dict = PyDict::new(py);
        if let Some(c) = &cfg.env.camera {
            let shape = (n, c.height as usize, c.width as usize, usize::from(c.channels()));
            let array = Array4::from_shape_vec(shape, camera).expect("one frame per environment");
            dict.set_item(intern!(py, "camera"), PyArray::from_owned_array(py, array))?;
        }
        let matrix = |width: usize, values: Vec<f32>| {
            PyArray::from_owned_array(py, Array2::from_shape_vec((n, width), values).expect("width values per environment"))
        };
        dict.set_item(intern!(py, "speed"), matrix(1, rows.iter().map(|r| r.speed).collect()))?;
        if cfg.env.variant == sim_core::config::Variant::Hybrid {
            dict.set_item(intern!(py, "d"), matrix(1, rows.iter().map(|r| r.d).collect()))?;
        }
        if cfg.path_features {
            dict.set_item(intern!(py, "path"), matrix(PATH_FEATURES, rows.iter().flat_map(|r| r.path).collect()))?;
        }
        Ok(dict)
    }
}

fn column<'py, T: Element>(py: Python<'py>, rows: &[Row], f: impl Fn(&Row) -> T) -> Bound<'py, PyArray1<T>> {
    PyArray1::from_iter(py, rows.iter().map(f))
}

/// The batched info dict: one array of N values per key (the single env's keys, with `collision`
/// as an index into `COLLISION_KINDS`).
fn infos<'py>(py: Python<'py>, rows: &[Row]) -> PyResult<Bound<'py, PyDict>> {
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
