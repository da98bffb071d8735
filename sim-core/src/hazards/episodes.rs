//! The hazard suite's episodes, defined once: `actor eval --suite hazards` drives them and the
//! hazard presets train on them, so that training episodes are like the test (route length and
//! time limit here; the hazard's distance and parameters are [`HazardsConfig`]'s ranges).

use super::config::HazardsConfig;
use crate::config::EnvConfig;

/// Route length of a hazard episode, metres: room for a hazard 45–75 m in and after it.
pub const ROUTE_LENGTH: (f32, f32) = (120.0, 220.0);
/// Steps before a hazard episode is truncated: room to wait behind a hazard and pass it.
pub const TIME_LIMIT: u32 = 600;

/// Sets `cfg`'s training episodes to the hazard suite's: its route lengths and time limit, and
/// the hazard parameters' ranges of [`HazardsConfig::default`] (rate and kinds are left as set).
pub fn use_suite_episodes(cfg: &mut EnvConfig) {
    (cfg.route_length_min, cfg.route_length_max) = ROUTE_LENGTH;
    cfg.time_limit = TIME_LIMIT;
    let (rate, kinds) = (cfg.hazards.rate, std::mem::take(&mut cfg.hazards.kinds));
    cfg.hazards = HazardsConfig { rate, kinds, ..HazardsConfig::default() };
}
