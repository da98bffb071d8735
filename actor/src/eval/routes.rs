//! What a command drives on: the town (the embedded default or a map file) and the routes named on
//! the command line.

use std::sync::Arc;

use anyhow::{Context, Result};
use sim_core::scenario::{EvalRoute, Scenario};
use sim_core::town::Town;

/// The routes named on the command line: a route name, `all` seven, or `random` (random training
/// routes, for any map).
pub fn parse_routes(arg: &str) -> Result<Vec<(&'static str, Scenario)>> {
    Ok(match arg {
        "all" => EvalRoute::ALL.iter().map(|&r| (r.name(), Scenario::Eval(r))).collect(),
        "random" => vec![("random", Scenario::Random)],
        name => {
            let r = EvalRoute::from_name(name).with_context(|| {
                format!("unknown route `{name}`: expected `all`, `random` or one of {}", EvalRoute::ALL.map(EvalRoute::name).join(", "))
            })?;
            vec![(r.name(), Scenario::Eval(r))]
        }
    })
}

/// A town given by name (an embedded town: `default_town`, the one agents train on, or
/// `held_out_town`) or as a map file's path.
pub fn town_by_name_or_file(arg: &str) -> Result<Arc<Town>> {
    if let Some(town) = Town::embedded(arg) {
        return Ok(town);
    }
    let path = std::path::Path::new(arg);
    if !path.exists() {
        let names: Vec<&str> = sim_core::map::EMBEDDED_TOWNS.iter().map(|t| t.0).collect();
        anyhow::bail!("unknown town `{arg}`: expected one of {} or a map file", names.join(", "));
    }
    load_town(Some(path))
}

/// Loads the town: the embedded default or a map file.
pub fn load_town(map: Option<&std::path::Path>) -> Result<Arc<Town>> {
    match map {
        None => Ok(Town::default_town()),
        Some(path) => {
            let text = std::fs::read_to_string(path).with_context(|| format!("reading map file {}", path.display()))?;
            let map = sim_core::map::Map::from_file_text(path, &text).with_context(|| format!("loading map file {}", path.display()))?;
            let town = Town::new(map);
            for w in &town.map.warnings {
                tracing::warn!("{}: {w}", path.display());
            }
            Ok(town)
        }
    }
}
