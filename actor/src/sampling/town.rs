//! The town an actor of a run drives: the run's `[env] map`, built from the content the learner
//! sent at Register (checked against its hash), so that the actor needs no copy of the file; the
//! default town for runs without a map, exactly as before maps could be named.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use proto::v1 as pb;
use sim_core::config::EnvConfig;
use sim_core::hash::fnv1a64;
use sim_core::map::Map;
use sim_core::town::Town;

/// The run's town from its environment configuration and the registration's map fields.
pub fn run_town(env: &EnvConfig, reg: &pb::RegisterResponse) -> Result<Arc<Town>> {
    let Some(map) = env.map.as_deref() else { return Ok(Town::default_town()) };
    if reg.map_text.is_empty() {
        return Town::embedded(map).with_context(|| {
            format!(
                "the run's map `{map}` is not an embedded town and the learner sent no map file with the registration \
                 (a learner older than this actor?)"
            )
        });
    }
    let hash = fnv1a64(reg.map_text.as_bytes());
    if hash != reg.map_hash {
        bail!("the run's map {} arrived damaged: its content hashes to {hash:016x}, the learner sent {:016x}", reg.map_name, reg.map_hash);
    }
    let built = Map::from_file_text(Path::new(&reg.map_name), &reg.map_text)
        .with_context(|| format!("building the run's map {} (as the learner sent it)", reg.map_name))?;
    Ok(Town::new(built))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sent(name: &str, text: &str) -> pb::RegisterResponse {
        pb::RegisterResponse {
            map_name: name.into(),
            map_text: text.into(),
            map_hash: fnv1a64(text.as_bytes()),
            ..pb::RegisterResponse::default()
        }
    }

    fn with_map(map: &str) -> EnvConfig {
        EnvConfig { map: Some(map.into()), ..EnvConfig::default() }
    }

    #[test]
    fn no_map_is_the_default_town_and_a_name_an_embedded_one() {
        let none = run_town(&EnvConfig::default(), &pb::RegisterResponse::default()).unwrap();
        assert_eq!(none.map.name, Town::default_town().map.name);
        let held = run_town(&with_map("held_out_town"), &pb::RegisterResponse::default()).unwrap();
        assert_eq!(held.map.name, Town::embedded("held_out_town").unwrap().map.name);
        let e = run_town(&with_map("/elsewhere/Town01.xodr"), &pb::RegisterResponse::default()).unwrap_err().to_string();
        assert!(e.contains("Town01.xodr") && e.contains("sent no map"), "{e}");
    }

    #[test]
    fn the_sent_content_is_built_in_the_format_its_name_says_and_checked() {
        let xodr = include_str!("../../../sim-core/tests/data/opendrive/straight_500m.xodr");
        let town = run_town(&with_map("/only/on/the/learner/straight_500m.xodr"), &sent("straight_500m.xodr", xodr)).unwrap();
        assert_eq!(town.map.lanes.len(), Map::from_opendrive(xodr).unwrap().lanes.len());
        let text = run_town(&with_map("mine.map"), &sent("mine.map", sim_core::map::DEFAULT_TOWN)).unwrap();
        assert_eq!(text.map.lanes.len(), Town::default_town().map.lanes.len());

        let mut damaged = sent("straight_500m.xodr", xodr);
        damaged.map_text.pop();
        let e = run_town(&with_map("straight_500m.xodr"), &damaged).unwrap_err().to_string();
        assert!(e.contains("damaged") && e.contains(&format!("{:016x}", fnv1a64(xodr.as_bytes()))), "{e}");
    }
}
