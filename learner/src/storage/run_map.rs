//! The run's map file (`[env] map` naming a file rather than an embedded town): read once when
//! the learner starts, checked by building it, and handed whole to every actor at `Register`, so
//! that remote actors need no copy and every actor of a run drives the same town. Its hash is kept
//! in the run directory: a resumed run whose file changed is refused, naming both hashes.

use std::path::Path;

use anyhow::{Context, Result, bail};
use sim_core::config::EnvConfig;
use sim_core::hash::fnv1a64;
use sim_core::map::{EMBEDDED_TOWNS, Map};

/// In the run directory: the map's FNV-1a 64 hash (16 hex digits) and its file name.
pub const HASH_FILE: &str = "map.hash";
/// What a Register reply carries besides the map, bytes: the map may take the rest of the
/// learner's largest message.
const REPLY_MARGIN: usize = 1 << 20;

/// A map file as a run carries it to its actors.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunMap {
    /// The file's name without its directory: its extension chooses the format (`.xodr`).
    pub name: String,
    pub text: String,
    /// FNV-1a 64 of `text`'s bytes.
    pub hash: u64,
}

impl RunMap {
    /// The file `cfg.map` names, read and built once to check it; `None` for runs on an embedded
    /// town (the default, or one named). `max_message_bytes` bounds its size: it travels in one
    /// Register reply.
    pub fn read(cfg: &EnvConfig, max_message_bytes: usize) -> Result<Option<Self>> {
        let Some(path) = cfg.map.as_deref() else { return Ok(None) };
        if EMBEDDED_TOWNS.iter().any(|(name, _)| *name == path) {
            return Ok(None);
        }
        let text = std::fs::read_to_string(path).with_context(|| {
            let names: Vec<&str> = EMBEDDED_TOWNS.iter().map(|t| t.0).collect();
            format!("config field `env.map`: reading map file `{path}` (expected a readable map file or one of {})", names.join(", "))
        })?;
        let limit = max_message_bytes.saturating_sub(REPLY_MARGIN);
        if text.len() > limit {
            bail!(
                "config field `env.map`: map file `{path}` is {} bytes; it is sent to every actor in one message, so it must be at most {limit} \
                 (service.max_message_bytes {max_message_bytes} less 1 MiB)",
                text.len()
            );
        }
        let name = Path::new(path).file_name().and_then(|n| n.to_str()).unwrap_or(path).to_owned();
        Map::from_file_text(Path::new(&name), &text).with_context(|| format!("config field `env.map`: loading map file `{path}`"))?;
        let hash = fnv1a64(text.as_bytes());
        Ok(Some(Self { name, text, hash }))
    }

    /// A fresh run records the hash in `run_dir`; a resumed one must find the same hash there
    /// (a run directory from before maps were recorded gets it now).
    pub fn check_run_dir(&self, run_dir: &Path, resume: bool) -> Result<()> {
        let path = run_dir.join(HASH_FILE);
        let line = format!("{:016x} {}\n", self.hash, self.name);
        if resume && let Ok(before) = std::fs::read_to_string(&path) {
            let recorded = before.split_whitespace().next().unwrap_or("");
            if recorded != format!("{:016x}", self.hash) {
                bail!(
                    "the run's map file {} has changed since the run started: its hash is {:016x}, the run was trained on {recorded} \
                     ({}); restore the file, or start a new run directory",
                    self.name,
                    self.hash,
                    path.display()
                );
            }
            return Ok(());
        }
        std::fs::write(&path, line).with_context(|| format!("writing {}", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(map: &str) -> EnvConfig {
        EnvConfig { map: Some(map.to_owned()), ..EnvConfig::default() }
    }

    #[test]
    fn embedded_towns_and_no_map_send_nothing() {
        assert_eq!(RunMap::read(&EnvConfig::default(), 64 << 20).unwrap(), None);
        assert_eq!(RunMap::read(&cfg("held_out_town"), 64 << 20).unwrap(), None);
    }

    #[test]
    fn a_file_is_read_checked_and_its_change_refused_on_resume() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("town.map");
        std::fs::write(&file, sim_core::map::DEFAULT_TOWN).unwrap();
        let run = RunMap::read(&cfg(file.to_str().unwrap()), 64 << 20).unwrap().expect("a file");
        assert_eq!((run.name.as_str(), run.hash), ("town.map", fnv1a64(sim_core::map::DEFAULT_TOWN.as_bytes())));
        run.check_run_dir(dir.path(), false).unwrap();
        run.check_run_dir(dir.path(), true).unwrap();
        let changed = RunMap { hash: run.hash ^ 1, ..run.clone() };
        let e = changed.check_run_dir(dir.path(), true).unwrap_err().to_string();
        assert!(e.contains(&format!("{:016x}", run.hash)) && e.contains(&format!("{:016x}", run.hash ^ 1)), "{e}");

        let too_small = RunMap::read(&cfg(file.to_str().unwrap()), 1 << 20).unwrap_err().to_string();
        assert!(too_small.contains("service.max_message_bytes"), "{too_small}");
        std::fs::write(&file, "road r from=A\n").unwrap();
        let bad = format!("{:#}", RunMap::read(&cfg(file.to_str().unwrap()), 64 << 20).unwrap_err());
        assert!(bad.contains("env.map") && bad.contains("line 1"), "{bad}");
        let missing = format!("{:#}", RunMap::read(&cfg("no/such.xodr"), 64 << 20).unwrap_err());
        assert!(missing.contains("no/such.xodr") && missing.contains("default_town"), "{missing}");
    }
}
