//! The run's map reaches its actors: a learner whose `[env] map` names an OpenDRIVE file reads it
//! once and sends its content at Register; an actor started in another directory, after the file
//! is gone, drives that town. A resumed run whose file changed is refused, naming both hashes.

use crate::support;

use agent::config::RunConfig;
use learner::serve::{ServeOptions, start};
use sim_core::hash::fnv1a64;
use sim_core::map::Map;
use support::{Process, actor, actor_command, free_port, wait_for, wait_for_file};

const MAP: &str = "fabriksgatan.xodr";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_actor_without_the_file_drives_the_runs_map() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(format!("{}/../sim-core/tests/data/opendrive/{MAP}", env!("CARGO_MANIFEST_DIR"))).unwrap();
    let map_path = dir.path().join(MAP);
    std::fs::write(&map_path, &text).unwrap();
    let addr = free_port();
    let mut cfg = RunConfig::tiny(&dir.path().join("run"));
    cfg.env.map = Some(map_path.display().to_string());
    cfg.env.traffic.vehicles = 2;
    cfg.service.listen = addr.clone();
    let cfg_path = dir.path().join("run.toml");
    std::fs::write(&cfg_path, cfg.to_toml()).unwrap();
    let learner = start(ServeOptions { config: Some(cfg_path.clone()), ..ServeOptions::default() }).await.unwrap();

    // Read once at the start: the file can go before any actor exists.
    std::fs::remove_file(&map_path).unwrap();
    let elsewhere = dir.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    let mut command = actor_command(&addr, "a", &["--batch-steps", "16"]);
    command.current_dir(&elsewhere);
    let log = dir.path().join("a.log");
    let _a = Process::spawn(command, &log);
    wait_for(&addr, 120, "actor a streaming steps", |s| actor(s, "a").is_some_and(|x| x.transitions > 0)).await;
    let said = wait_for_file(&log, 10, "the town the actor drives", |t| t.contains("driving the run's town"));
    let lanes = Map::from_file_text(&map_path, &text).unwrap().lanes.len();
    let hash = format!("{:016x}", fnv1a64(text.as_bytes()));
    let line = said.lines().find(|l| l.contains("driving the run's town")).unwrap();
    assert!(line.contains(&format!("lanes={lanes}")) && line.contains(&format!("map_file={MAP}")) && line.contains(&hash), "{line}");
    assert_ne!(lanes, sim_core::town::Town::default_town().map.lanes.len(), "the default town would pass too");
    learner.stop().await.unwrap();

    // The same run resumed with another file under the map's name: refused, naming both hashes.
    let changed = format!("{text}\n<!-- edited -->\n");
    std::fs::write(&map_path, &changed).unwrap();
    let run_dir = dir.path().join("run");
    let Err(e) = start(ServeOptions { run_dir: Some(run_dir), resume: true, ..ServeOptions::default() }).await else {
        panic!("a resume with a changed map file started");
    };
    let e = format!("{e:#}");
    assert!(e.contains(&hash) && e.contains(&format!("{:016x}", fnv1a64(changed.as_bytes()))), "{e}");
}
