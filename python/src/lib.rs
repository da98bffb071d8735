//! `hybrid_drive._core`: the Python binding of `sim-core`, a thin layer that the Python package
//! `hybrid_drive` (python/hybrid_drive/) wraps as a Gymnasium environment and vector environment.
//!
//! `SimConfig` checks what the user asked for once; `Sim` is one environment; `VecSim` steps N on a
//! thread pool with the GIL released and returns batched NumPy arrays. No simulator logic lives
//! here or in Python: episodes, rewards, rendering and routes are `sim_core::env::Env`'s.

mod bench;
mod config;
mod convert;
mod errors;
mod pool;
mod reference;
mod single;
mod slot;
mod vector;

use pyo3::prelude::*;

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
