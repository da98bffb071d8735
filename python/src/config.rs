//! `SimConfig`: what a Python user asked for (map, route, observation, camera, variant, action set,
//! config overrides), checked once and turned into what `sim_core` needs: the town, the `EnvConfig`, the
//! scenario and the action set. Every error names the bad value and what would be valid.

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use sim_core::actions::ActionSet;
use sim_core::camera::{BirdsEye, BirdsEyeConfig, CameraConfig};
use sim_core::config::{EnvConfig, Variant};
use sim_core::scenario::{EvalRoute, Scenario, eval_route};
use sim_core::sensor::VectorConfig;
use sim_core::town::Town;
use sim_core::vehicle::Action;

/// Route names accepted by `route=`: `random` (random training routes) and the paper's seven.
pub fn route_names() -> Vec<&'static str> {
    std::iter::once("random").chain(EvalRoute::ALL.iter().map(|r| r.name())).collect()
}

/// The scenario named `name`, or an error listing the valid names.
pub fn parse_route(name: &str) -> PyResult<(&'static str, Scenario)> {
    if name == "random" {
        return Ok(("random", Scenario::Random));
    }
    EvalRoute::from_name(name)
        .map(|r| (r.name(), Scenario::Eval(r)))
        .ok_or_else(|| PyValueError::new_err(format!("unknown route {name:?}: expected one of {}", route_names().join(", "))))
}

/// The observations `observation=` names: `dict` (camera, speed, d, path: a dict of arrays) and
/// `vector` (the vector sensor's reading, `[env.vector]`: one flat array, no camera).
pub const OBSERVATIONS: [&str; 2] = ["dict", "vector"];

/// A checked environment configuration, shared by `Sim`, `VecSim` and `reference_rollout`.
#[pyclass(module = "hybrid_drive._core", frozen)]
#[derive(Debug)]
pub struct SimConfig {
    pub town: Arc<Town>,
    pub env: EnvConfig,
    pub scenario: Scenario,
    pub route: &'static str,
    pub actions: &'static [Action],
    /// Whether observations carry the planner's path features (hybrid only).
    pub path_features: bool,
    /// Whether the observation is the vector sensor's reading (`observation="vector"`) rather
    /// than the dict.
    pub vector: bool,
    pub birdseye: BirdsEye,
    birdseye_size: u32,
    map: Option<PathBuf>,
}

#[pymethods]
impl SimConfig {
    /// `camera` is `(width, height)` or `None` (no image); `config` is a JSON object of
    /// `EnvConfig` fields (the `learner config` `[env]` table) applied before the other arguments;
    /// `hazards` is the probability that an episode gets a hazard (`[env.hazards] rate`; kinds
    /// and ranges through `config`). `observation="vector"` observes the vector sensor instead
    /// of the dict: `config`'s `vector` table if it has one, else the sensor's defaults, and no
    /// camera (`camera` is ignored, `config`'s `camera` table dropped: nothing is rendered).
    #[new]
    #[pyo3(signature = (*, map=None, route="random", camera=Some((84, 84)), rgb=false, variant="hybrid", vehicles=None,
                        parked_cars=None, path_features=false, action_set="paper6", config=None, birdseye_size=256, hazards=None,
                        observation="dict"))]
    #[allow(clippy::too_many_arguments)] // Python keyword arguments, all optional.
    fn new(
        map: Option<PathBuf>,
        route: &str,
        camera: Option<(u32, u32)>,
        rgb: bool,
        variant: &str,
        vehicles: Option<usize>,
        parked_cars: Option<usize>,
        path_features: bool,
        action_set: &str,
        config: Option<&str>,
        birdseye_size: u32,
        hazards: Option<f32>,
        observation: &str,
    ) -> PyResult<Self> {
        let mut env: EnvConfig = match config {
            None => EnvConfig::default(),
            Some(json) => serde_json::from_str(json).map_err(|e| PyValueError::new_err(format!("config: {e}")))?,
        };
        env.variant = match variant {
            "hybrid" => Variant::Hybrid,
            "end_to_end" => Variant::EndToEnd,
            other => return Err(PyValueError::new_err(format!("unknown variant {other:?}: expected \"hybrid\" or \"end_to_end\""))),
        };
        let vector = match observation {
            "dict" => false,
            "vector" => true,
            other => {
                return Err(PyValueError::new_err(format!(
                    "unknown observation {other:?}: expected one of {}",
                    OBSERVATIONS.map(|o| format!("{o:?}")).join(", ")
                )));
            }
        };
        if vector {
            if rgb {
                return Err(PyValueError::new_err("rgb=True needs a camera: observation=\"vector\" renders none"));
            }
            if path_features {
                return Err(PyValueError::new_err(
                    "path_features=True is for the dict observation: observation=\"vector\" holds the planner's path already (hybrid)",
                ));
            }
            env.camera = None;
            env.vector = Some(env.vector.take().unwrap_or_default());
        } else {
            env.camera = camera.map(|(width, height)| CameraConfig { width, height, rgb, ..env.camera.clone().unwrap_or_default() });
        }
        if let Some(n) = vehicles {
            env.traffic.vehicles = n;
        }
        if let Some(n) = parked_cars {
            env.traffic.parked_cars = n;
        }
        if let Some(rate) = hazards {
            env.hazards.rate = rate;
        }
        env.validate().map_err(|e| PyValueError::new_err(e.to_string()))?;
        if path_features && env.variant != Variant::Hybrid {
            return Err(PyValueError::new_err(
                "path_features=True needs variant=\"hybrid\": the end-to-end agent observes nothing of the planner",
            ));
        }
        let set: ActionSet = serde_json::from_value(serde_json::Value::String(action_set.to_owned()))
            .map_err(|e| PyValueError::new_err(format!("action_set {action_set:?}: {e}")))?;
        let birdseye_cfg = BirdsEyeConfig { size: birdseye_size, ..BirdsEyeConfig::default() };
        let birdseye = BirdsEye::new(&birdseye_cfg).map_err(|e| PyValueError::new_err(e.to_string()))?;
        let town = load_town(map.as_deref())?;
        let (route, scenario) = parse_route(route)?;
        if let Scenario::Eval(r) = scenario
            && eval_route(&town, r, env.waypoint_spacing).is_none()
        {
            let on = map.as_ref().map_or_else(|| "the default town".to_owned(), |p| format!("map {}", p.display()));
            return Err(PyValueError::new_err(format!(
                "route {route:?} needs the default town's roads, which {on} lacks: use route=\"random\" on other maps"
            )));
        }
        Ok(Self { town, env, scenario, route, actions: set.actions(), path_features, vector, birdseye, birdseye_size, map })
    }

    /// `(height, width, channels)` of the camera observation (channels × `stack` frames), or
    /// `None` without a camera.
    #[getter]
    fn camera_shape(&self) -> Option<(u32, u32, usize)> {
        self.env.camera.as_ref().map(|c| (c.height, c.width, c.stacked_channels()))
    }

    /// `"dict"` or `"vector"` (see `observation=`).
    #[getter]
    fn observation(&self) -> &'static str {
        if self.vector { OBSERVATIONS[1] } else { OBSERVATIONS[0] }
    }

    /// Values in the vector observation (`[env.vector]`'s layout for this variant), or `None`
    /// with the dict observation.
    #[getter]
    fn vector_len(&self) -> Option<usize> {
        self.vector_config().map(|v| v.len(self.env.variant))
    }

    /// The vector observation's layout in words (version and segments, as checkpoints record it,
    /// e.g. `vector/1 ego:1x3 path:1x4 ...`), or `None` with the dict observation.
    #[getter]
    fn vector_layout(&self) -> Option<String> {
        self.vector_config().map(|v| v.describe(self.env.variant))
    }

    /// The vector observation's segments, first to last: `(name, count, fields)`, `count × fields`
    /// values each; empty with the dict observation.
    #[getter]
    fn vector_segments(&self) -> Vec<(&'static str, usize, usize)> {
        self.vector_config().map(|v| v.segments(self.env.variant).iter().map(|s| (s.name, s.count, s.fields)).collect()).unwrap_or_default()
    }

    /// The highest speed the ego vehicle reaches, m/s.
    #[getter]
    fn speed_max(&self) -> f32 {
        self.env.vehicle.max_speed
    }

    /// A bound on every distance the observation holds (d, the lateral offset), metres: the map's
    /// diagonal plus a margin. An episode ends when the ego leaves the drivable surface, which lies
    /// inside the map, so the ego is never farther than one step beyond it.
    #[getter]
    fn distance_max(&self) -> f32 {
        let s = &self.town.map.surface;
        s.cell * (s.width as f32).hypot(s.height as f32) + 100.0
    }

    /// Whether the observation holds d (the hybrid variant).
    #[getter]
    fn observes_d(&self) -> bool {
        self.env.variant == Variant::Hybrid
    }

    #[getter]
    fn observes_path(&self) -> bool {
        self.path_features
    }

    #[getter]
    fn variant(&self) -> &'static str {
        match self.env.variant {
            Variant::Hybrid => "hybrid",
            Variant::EndToEnd => "end_to_end",
        }
    }

    #[getter]
    fn route(&self) -> &'static str {
        self.route
    }

    /// The discrete actions as `(throttle, brake, steer)`, in index order.
    #[getter]
    fn actions(&self) -> Vec<(f32, f32, f32)> {
        self.actions.iter().map(|a| (a.throttle, a.brake, a.steer)).collect()
    }

    #[getter]
    fn birdseye_size(&self) -> u32 {
        self.birdseye_size
    }

    /// Steps before an episode is truncated on this route.
    #[getter]
    fn time_limit(&self) -> u32 {
        match self.scenario {
            Scenario::Random => self.env.time_limit,
            Scenario::Eval(_) => self.env.eval_time_limit,
        }
    }

    /// The effective `EnvConfig` as JSON (every field, defaults included).
    fn config_json(&self) -> String {
        serde_json::to_string(&self.env).expect("EnvConfig serialises")
    }

    fn __repr__(&self) -> String {
        format!(
            "SimConfig(route={:?}, variant={:?}, observation={:?}, camera={:?}, map={:?})",
            self.route,
            self.variant(),
            self.observation(),
            self.camera_shape(),
            self.map.as_ref().map(|p| p.display().to_string())
        )
    }
}

impl SimConfig {
    /// The vector sensor's configuration, with the vector observation.
    fn vector_config(&self) -> Option<&VectorConfig> {
        self.env.vector.as_ref().filter(|_| self.vector)
    }

    /// This configuration on another route (for `reset(options={"route": ...})`).
    pub fn scenario_named(&self, name: &str) -> PyResult<(&'static str, Scenario)> {
        let (route, scenario) = parse_route(name)?;
        if let Scenario::Eval(r) = scenario
            && eval_route(&self.town, r, self.env.waypoint_spacing).is_none()
        {
            return Err(PyValueError::new_err(format!("route {route:?} needs the default town's roads, which this map lacks")));
        }
        Ok((route, scenario))
    }
}

/// The embedded default town (built once per process and shared), or a map file's.
fn load_town(map: Option<&std::path::Path>) -> PyResult<Arc<Town>> {
    static DEFAULT: OnceLock<Arc<Town>> = OnceLock::new();
    match map {
        None => Ok(DEFAULT.get_or_init(Town::default_town).clone()),
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| PyOSError::new_err((e.raw_os_error().unwrap_or(0), format!("reading map file {}: {e}", path.display()))))?;
            let map = sim_core::map::Map::from_file_text(path, &text)
                .map_err(|e| PyValueError::new_err(format!("map file {}: {e}", path.display())))?;
            Ok(Town::new(map))
        }
    }
}
