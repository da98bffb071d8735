//! How an observation becomes the network's inputs besides the image (which goes in as its bytes,
//! scaled by 1/255 inside `fastnet`): the raw scalars an actor sends and the replay stores with
//! each frame, and the selection and scaling that give the network's scalar inputs — or, for a
//! run with the vector sensor (`[env.vector]`), that sensor's reading, which already holds speed,
//! d and the path, scaled ([`push_network_inputs`]).

use sim_core::config::Variant;
use sim_core::env::PATH_FEATURES;

use crate::config::RunConfig;

/// What is stored with each frame besides the image: speed (m/s), d (m) and the planner's path
/// features (sim-core's `Env::path_features`: signed lateral offset in m, near and far heading
/// angles in rad). The run's config picks which of them the network sees ([`scalar_features`]),
/// so one buffer layout serves every variant.
pub type RawScalars = [f32; 2 + PATH_FEATURES];

/// Scale of the lateral path feature, metres: a lane's width.
pub const LANE_WIDTH: f32 = 3.5;

/// Packs one observation's scalars.
#[must_use]
pub fn raw_scalars(speed: f32, d: f32, path: [f32; PATH_FEATURES]) -> RawScalars {
    let [lateral, near, far] = path;
    [speed, d, lateral, near, far]
}

/// The raw scalars of an environment's current state, as the actor sends them.
#[must_use]
pub fn env_scalars(env: &sim_core::env::Env) -> RawScalars {
    raw_scalars(env.ego.speed, env.tracking.d, env.path_features())
}

/// The network's scalar inputs from an observation's raw scalars: speed/v0; d/d0 for the hybrid
/// agent; and its path features with `agent.path_features` — scaled so that typical values are
/// near 1. Their number is [`RunConfig::scalar_inputs`].
#[must_use]
pub fn scalar_features(cfg: &RunConfig, raw: &RawScalars) -> Vec<f32> {
    let r = &cfg.env.reward;
    let [speed, d, lateral, near, far] = *raw;
    match cfg.env.variant {
        // Angles are in radians already; the lateral offset is scaled by a lane's width.
        Variant::Hybrid if cfg.agent.path_features => vec![speed / r.v0(), d / r.d0, lateral / LANE_WIDTH, near, far],
        Variant::Hybrid => vec![speed / r.v0(), d / r.d0],
        Variant::EndToEnd => vec![speed / r.v0()],
    }
}

/// Appends the network's inputs besides the image for one observation to `out`: the vector
/// sensor's reading `vector` when the run has the sensor, else [`scalar_features`] of `raw`.
/// [`RunConfig::scalar_inputs`] values in either case: an end-to-end agent given a hybrid
/// environment's reading (evaluation runs the hybrid variant for everyone) sees it without the
/// planner's segments.
pub fn push_network_inputs(cfg: &RunConfig, raw: &RawScalars, vector: &[f32], out: &mut Vec<f32>) {
    if let Some(v) = &cfg.env.vector {
        if cfg.env.variant == Variant::EndToEnd && vector.len() == v.len(Variant::Hybrid) && vector.len() != cfg.vector_len() {
            out.extend(sim_core::sensor::without_planner(v, vector));
        } else {
            out.extend_from_slice(vector);
        }
    } else {
        out.extend(scalar_features(cfg, raw));
    }
}

/// The network's inputs besides the image for several environments' current states, concatenated.
#[must_use]
pub fn env_inputs<'a>(cfg: &RunConfig, envs: impl IntoIterator<Item = &'a sim_core::env::Env>) -> Vec<f32> {
    let mut out = Vec::new();
    for e in envs {
        push_network_inputs(cfg, &env_scalars(e), e.vector().unwrap_or(&[]), &mut out);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_features_follow_the_variant_and_the_path_switch() {
        let raw = raw_scalars(13.889, 4.0, [1.75, -0.2, 0.6]);
        let mut cfg = RunConfig::preset("paper").unwrap();
        let close = |got: Vec<f32>, want: &[f32]| {
            assert_eq!(got.len(), want.len(), "{got:?}");
            assert!(got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-4), "{got:?} vs {want:?}");
        };
        close(scalar_features(&cfg, &raw), &[1.0, 0.5]);
        cfg.agent.path_features = true;
        close(scalar_features(&cfg, &raw), &[1.0, 0.5, 0.5, -0.2, 0.6]);
        assert_eq!(scalar_features(&cfg, &raw).len(), cfg.scalar_inputs());
        let e2e = RunConfig::preset("end-to-end-tuned").unwrap();
        close(scalar_features(&e2e, &raw), &[1.0]);
    }

    #[test]
    fn a_vector_run_sees_the_reading_and_an_end_to_end_one_drops_the_planners_segments() {
        let raw = raw_scalars(13.889, 4.0, [1.75, -0.2, 0.6]);
        let hv = RunConfig::preset("hybrid-vector").unwrap();
        let ev = RunConfig::preset("e2e-vector").unwrap();
        let hybrid_reading: Vec<f32> = (0..hv.vector_len()).map(|k| k as f32 / 1000.0).collect();
        let mut out = Vec::new();
        push_network_inputs(&hv, &raw, &hybrid_reading, &mut out);
        assert_eq!(out, hybrid_reading, "the reading as is: it holds speed, d and the path already");
        // An end-to-end agent driving a hybrid environment (evaluation) sees ego, objects, rays.
        out.clear();
        push_network_inputs(&ev, &raw, &hybrid_reading, &mut out);
        assert_eq!(out.len(), ev.scalar_inputs());
        let planner = hv.vector_len() - ev.vector_len();
        let ego = sim_core::sensor::EGO_FIELDS;
        assert_eq!(&out[..ego], &hybrid_reading[..ego]);
        assert_eq!(&out[ego..], &hybrid_reading[ego + planner..]);
        // Its own environment's reading goes in as is.
        let own: Vec<f32> = hybrid_reading[..ev.vector_len()].to_vec();
        out.clear();
        push_network_inputs(&ev, &raw, &own, &mut out);
        assert_eq!(out, own);
    }
}
