//! `reference_rollout`: an episode driven on `sim_core::Env` directly, with none of the binding's
//! seeding, buffers or conversions, so that tests can hold what `Sim` and `VecSim` return against
//! the simulator's own values.

use pyo3::prelude::*;
use pyo3::types::PyBytes;
use sim_core::env::Env;

use crate::config::SimConfig;
use crate::errors::env_error;

/// One step as the simulator reports it.
type ReferenceStep<'py> = (f32, f32, f32, f32, bool, bool, u64, Bound<'py, PyBytes>);

/// Resets a new `Env` of `cfg` with `seed` on its route and applies the action indices `actions`
/// until they run out or the episode ends. Per step: `(reward, r_v, r_l, r_w, terminated,
/// truncated, state_hash, observation bytes)`: the camera's image, or with `observation="vector"`
/// the vector sensor's reading as native-endian `float32` (empty bytes without either).
#[pyfunction]
pub fn reference_rollout<'py>(py: Python<'py>, cfg: &SimConfig, seed: u64, actions: Vec<usize>) -> PyResult<Vec<ReferenceStep<'py>>> {
    if let Some(&a) = actions.iter().find(|&&a| a >= cfg.actions.len()) {
        return Err(pyo3::exceptions::PyValueError::new_err(format!("action {a} is not in 0..{}", cfg.actions.len())));
    }
    let mut env = Env::new(cfg.town.clone(), cfg.env.clone()).map_err(env_error)?;
    env.reset(seed, cfg.scenario).map_err(env_error)?;
    let mut out = Vec::new();
    for a in actions {
        let r = env.step(cfg.actions[a]).map_err(env_error)?;
        let t = r.info.reward_terms;
        let bytes = match (r.observation.image, r.observation.vector) {
            (_, Some(v)) if cfg.vector => v.iter().flat_map(|x| x.to_ne_bytes()).collect(),
            (Some(image), _) => image.data,
            _ => Vec::new(),
        };
        out.push((r.reward, t.r_v, t.r_l, t.r_w, r.terminated, r.truncated, env.state_hash(), PyBytes::new(py, &bytes)));
        if r.terminated || r.truncated {
            break;
        }
    }
    Ok(out)
}
