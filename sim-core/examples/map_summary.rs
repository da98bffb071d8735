fn main() {
    let t = std::time::Instant::now();
    let m = sim_core::map::Map::default_town();
    println!("built in {:?}", t.elapsed());
    println!("roads {} lanes {} junctions {} obstacles {}", m.roads.len(), m.lanes.len(), m.junctions.len(), m.obstacles.len());
    for (i, j) in m.junctions.iter().enumerate() {
        let nconf: usize = j.conflicts.iter().map(|c| c.len()).sum();
        println!("junction {i} at {:?} connectors {} conflicts {} outline {}", j.centre, j.connectors.len(), nconf, j.outline.len());
    }
    for (i, l) in m.lanes.iter().enumerate().take(200) {
        println!(
            "lane {i} {:?} len {:.1} start {:?} end {:?} succ {:?}",
            l.kind,
            l.path.length(),
            l.path.start(),
            l.path.end(),
            l.successors
        );
    }
    println!("raster {}x{}", m.surface.width, m.surface.height);
}
