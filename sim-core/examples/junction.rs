use sim_core::map::LaneKind;
fn main() {
    let town = sim_core::town::Town::default_town();
    let j = &town.map.junctions[std::env::args().nth(1).map_or(4, |a| a.parse().unwrap())];
    for (k, &c) in j.connectors.iter().enumerate() {
        if let LaneKind::Connector { from, to, turn, .. } = town.map.lanes[c].kind {
            let confl: Vec<usize> = j.conflicts[k].iter().map(|&i| j.connectors[i]).collect();
            println!("conn {c} from {from} to {to} {turn:?} len {:.1} conflicts {confl:?}", town.map.lanes[c].path.length());
        }
    }
}
