//! What one environment's observation and diagnostics look like in Python: a dict of NumPy arrays
//! (the camera image handed over without a copy) or the vector sensor's reading (one `float32`
//! array, also without a copy), and an info dict of plain values.

use numpy::ndarray::Array3;
use numpy::{PyArray, PyArray1, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use pyo3::{IntoPyObjectExt, intern};
use sim_core::camera::Image;
use sim_core::collision::CollisionKind;
use sim_core::env::{Observation, StepInfo};

use crate::config::SimConfig;

/// Names of the collision kinds; a vector env's `info["collision"]` holds indices into it (0: none).
pub const COLLISION_KINDS: [&str; 9] =
    ["none", "vehicle", "parked_car", "building", "pole", "pillar", "off_road", "pedestrian", "construction"];

/// The index of `kind` in [`COLLISION_KINDS`].
pub fn collision_code(kind: Option<CollisionKind>) -> i8 {
    match kind {
        None => 0,
        Some(CollisionKind::Vehicle) => 1,
        Some(CollisionKind::ParkedCar) => 2,
        Some(CollisionKind::Building) => 3,
        Some(CollisionKind::Pole) => 4,
        Some(CollisionKind::Pillar) => 5,
        Some(CollisionKind::OffRoad) => 6,
        Some(CollisionKind::Pedestrian) => 7,
        Some(CollisionKind::Construction) => 8,
    }
}

/// An image as a NumPy array of shape (height, width, channels), taking over its buffer.
pub fn image_array(py: Python<'_>, image: Image) -> Bound<'_, PyArray3<u8>> {
    let shape = (image.height as usize, image.width as usize, usize::from(image.channels));
    let array = Array3::from_shape_vec(shape, image.data).expect("an Image's data matches its size");
    PyArray::from_owned_array(py, array)
}

/// The observation: the vector sensor's reading with `observation="vector"`, else the dict of
/// `camera` (if configured), `speed`, `d` (hybrid) and `path` (if asked).
pub fn observation<'py>(py: Python<'py>, cfg: &SimConfig, obs: Observation) -> PyResult<Bound<'py, PyAny>> {
    if cfg.vector {
        let values = obs.vector.expect("observation=\"vector\" configures [env.vector]");
        return Ok(PyArray1::from_vec(py, values).into_any());
    }
    let dict = PyDict::new(py);
    if let Some(image) = obs.image {
        dict.set_item(intern!(py, "camera"), image_array(py, image))?;
    }
    dict.set_item(intern!(py, "speed"), PyArray1::from_slice(py, &[obs.speed]))?;
    if let Some(d) = obs.d {
        dict.set_item(intern!(py, "d"), PyArray1::from_slice(py, &[d]))?;
    }
    if cfg.path_features
        && let Some(path) = obs.path
    {
        dict.set_item(intern!(py, "path"), PyArray1::from_slice(py, &path))?;
    }
    Ok(dict.into_any())
}

/// The info dict of a step (or of a reset: zero reward terms).
pub fn info<'py>(py: Python<'py>, info: &StepInfo, route: &'static str, seed: u64) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    let t = &info.reward_terms;
    dict.set_item(intern!(py, "r_v"), f64::from(t.r_v))?;
    dict.set_item(intern!(py, "r_l"), f64::from(t.r_l))?;
    dict.set_item(intern!(py, "r_w"), f64::from(t.r_w))?;
    let collision = match collision_code(info.collision) {
        0 => py.None(),
        k => COLLISION_KINDS[k as usize].into_py_any(py)?,
    };
    dict.set_item(intern!(py, "collision"), collision)?;
    dict.set_item(intern!(py, "arrived"), info.arrived)?;
    dict.set_item(intern!(py, "progress"), f64::from(info.progress))?;
    dict.set_item(intern!(py, "d"), f64::from(info.d))?;
    dict.set_item(intern!(py, "l"), f64::from(info.l))?;
    dict.set_item(intern!(py, "speed"), f64::from(info.speed))?;
    dict.set_item(intern!(py, "steps"), info.steps)?;
    // The episode's hazard (`None` without one) and whether it has fired.
    dict.set_item(intern!(py, "hazard"), info.hazard.map(|h| h.kind.name()))?;
    dict.set_item(intern!(py, "hazard_triggered"), info.hazard.is_some_and(|h| h.triggered))?;
    dict.set_item(intern!(py, "route"), route)?;
    dict.set_item(intern!(py, "seed"), seed)?;
    Ok(dict)
}
