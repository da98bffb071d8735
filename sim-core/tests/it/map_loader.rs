//! Loading maps: errors that name the line and field, robustness of the parser and the geometry
//! builder on arbitrary and near-valid text, and the embedded default town.

use std::collections::BTreeSet;

use crate::common;

use common::fuzz_config;
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use proptest::test_runner::TestRunner;
use sim_core::map::format::parse;
use sim_core::map::{DEFAULT_TOWN, LaneKind, Map, MapError, ObstacleKind, Turn};
use sim_core::math::Vec2;
use sim_core::scenario::{EvalRoute, eval_route};
use sim_core::town::Town;

// ---------------------------------------------------------------------------------------------
// Errors by line and field

/// A valid two-node map; line 4 is the road.
const BASE: &str = "\
map name=t
node A x=0 y=0
node B x=100 y=0
road ab from=A heading=0 to=B lanes=1,1
  straight length=100
end
";

fn error_of(text: &str) -> MapError {
    Map::from_text(text).expect_err("the map should be refused")
}

/// Asserts the error's line and field, and that its message says `map line N`.
fn assert_at(e: &MapError, line: usize, field: Option<&str>) {
    assert_eq!((e.line, e.field.as_deref()), (line, field), "{e}");
    assert!(e.to_string().contains(&format!("map line {line}")), "message does not name line {line}: {e}");
    if let Some(f) = field {
        assert!(e.to_string().contains(&format!("field `{f}`")), "message does not name field {f}: {e}");
    }
}

#[test]
fn the_base_map_is_valid() {
    let map = Map::from_text(BASE).expect("BASE builds");
    assert_eq!(map.roads.len(), 1);
    assert_eq!(map.lanes.len(), 2, "one lane each way");
}

#[test]
fn road_ending_far_from_its_to_node() {
    // 80 m of straight from (0, 0) ends at (80, 0), 20 m short of B at (100, 0).
    let e = error_of(&BASE.replace("length=100", "length=80"));
    assert_at(&e, 4, Some("to"));
    assert!(e.message.contains("20.0 m from node `B`"), "{e}");
    // Within the 0.5 m tolerance of build.rs it is accepted.
    Map::from_text(&BASE.replace("length=100", "length=99.6")).expect("0.4 m off is within tolerance");
}

#[test]
fn unknown_from_node() {
    let e = error_of(&BASE.replace("from=A", "from=Z"));
    assert_at(&e, 4, Some("from"));
    assert!(e.message.contains("unknown node `Z`"), "{e}");
}

/// A road `ab` of `len` metres between two T junctions (three 1+1-lane roads meet at A and at B).
fn short_road_map(len: f32) -> String {
    format!(
        "\
node A x=0 y=0
road ab from=A heading=0 to=B lanes=1,1
  straight length={len}
end
road a_north from=A heading=90 to=N1 lanes=1,1
  straight length=50
end
road a_west from=A heading=180 to=W lanes=1,1
  straight length=50
end
road b_north from=B heading=90 to=N2 lanes=1,1
  straight length=50
end
road b_east from=B heading=0 to=E lanes=1,1
  straight length=50
end
"
    )
}

#[test]
fn road_too_short_for_its_junctions() {
    // Each junction takes the widest half-width (1 lane × 3.5 m, no shoulder) + 2 m margin =
    // 5.5 m of the road (build.rs), and a road must keep at least 2 m: 5.5 + 5.5 + 2 = 13 m.
    let e = error_of(&short_road_map(10.0));
    assert_at(&e, 2, None);
    assert!(e.message.contains("10.0 m long but its junctions take 11.0 m"), "{e}");
    let e = error_of(&short_road_map(12.9));
    assert_eq!(e.line, 2, "{e}");
    let map = Map::from_text(&short_road_map(13.5)).expect("13.5 m leaves 2.5 m of road");
    assert_eq!(map.junctions.len(), 2);
}

#[test]
fn duplicate_node_name() {
    let e = error_of(&BASE.replace("node B x=100 y=0", "node A x=100 y=0"));
    assert_at(&e, 3, Some("name"));
    assert!(e.message.contains("defined twice"), "{e}");
}

#[test]
fn negative_lane_width() {
    let e = error_of(&BASE.replace("lanes=1,1", "lanes=1,1 lane_width=-3.5"));
    assert_at(&e, 4, Some("lane_width"));
    assert!(e.message.contains("must be > 0"), "{e}");
    let e = error_of(&BASE.replace("map name=t", "map name=t\ndefaults lane_width=-1"));
    assert_at(&e, 2, Some("lane_width"));
}

#[test]
fn a_bad_lane_width_is_blamed_on_the_line_that_set_it() {
    // 35 m lanes on `a_north` (set on its own line, 5) make the junction at A take 37 m of `ab`:
    // the error names line 5 and its field, not ab's line 2.
    let wide_road = short_road_map(30.0).replace("to=N1 lanes=1,1", "to=N1 lanes=1,1 lane_width=35");
    let e = error_of(&wide_road);
    assert_at(&e, 5, Some("lane_width"));
    assert!(e.message.contains("lane width 35 m (road `a_north`)") && e.message.contains("road `ab` (line 2)"), "{e}");
    // Set by a `defaults` line (line 1 here), the blame goes there.
    let e = error_of(&format!("defaults lane_width=35\n{}", short_road_map(30.0)));
    assert_at(&e, 1, Some("lane_width"));
    // A plausible width on a road that is simply too short keeps the road's own line.
    assert_at(&error_of(&short_road_map(10.0)), 2, None);
}

#[test]
fn implausible_lane_widths_and_speed_limits_load_with_a_warning_at_their_line() {
    assert!(Map::from_text(BASE).unwrap().warnings.is_empty());
    let map = Map::from_text(&BASE.replace("lanes=1,1", "lanes=1,1 lane_width=35 speed=8.3")).expect("loads");
    let got: Vec<(usize, &str)> = map.warnings.iter().map(|w| (w.line, w.field.as_str())).collect();
    assert_eq!(got, [(4, "lane_width"), (4, "speed")], "{:?}", map.warnings);
    assert!(map.warnings[0].to_string().starts_with("map line 4, field `lane_width`: lane width 35 m"), "{}", map.warnings[0]);
    assert!(map.warnings[1].message.contains("8.3 km/h") && map.warnings[1].message.contains("10–130 km/h"), "{}", map.warnings[1]);
    // One warning per line that set the value, however many roads inherit it.
    let two_roads = format!("defaults lane_width=2 speed=140\n{}", short_road_map(30.0));
    let got: Vec<(usize, String)> = Map::from_text(&two_roads).unwrap().warnings.into_iter().map(|w| (w.line, w.field)).collect();
    assert_eq!(got, [(1, "lane_width".to_owned()), (1, "speed".to_owned())]);
    // The edges of the plausible ranges are plausible.
    let edges = BASE.replace("lanes=1,1", "lanes=1,1 lane_width=2.5 speed=130");
    assert!(Map::from_text(&edges).unwrap().warnings.is_empty());
    assert!(Map::default_town().warnings.is_empty(), "the default town is plausible");
}

#[test]
fn forgotten_end_names_the_road() {
    // Without `end`, the next top-level statement shows the road was never closed.
    let e = error_of(&format!("{}building x=50 y=50 width=5 depth=5\n", BASE.replace("end\n", "")));
    assert_at(&e, 4, None);
    assert!(e.message.contains("never closed"), "{e}");
}

#[test]
fn maps_too_large_for_the_surface_raster_are_refused() {
    // Coordinates up to ±1e6 m are valid numbers (format.rs), but a building 1000 km away would
    // need a raster of 4e6 × 4e6 cells: refused with an error rather than an allocation failure.
    let e = error_of(&format!("{BASE}building x=1000000 y=1000000 width=5 depth=5\n"));
    assert_eq!(e.line, 0, "{e}");
    assert!(e.message.contains("4 km²"), "{e}");
    let e = error_of(&BASE.replace("x=100 y=0", "x=1000000 y=0").replace("length=100", "length=1000000"));
    assert!(e.message.contains("4 km²"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Never panic

/// Odd and out-of-range values: zero, negatives, huge, non-finite, malformed.
const ODD_VALUES: &[&str] = &[
    "0", "-0", "-1", "-3.5", "0.0001", "1e-30", "1e6", "1000000", "-1e6", "1e30", "-1e30", "1e39", "NaN", "nan", "inf", "-inf", "infinity",
    "", "x", "12abc", "0x10", "1e", "+5", "3.5.1", "∞", "1,1", "0,0", "5,1",
];

/// Lines that are wrong in shape (or harmless) wherever they appear.
const ODD_LINES: &[&str] = &[
    "end",
    "straight length=10",
    "arc radius=5",
    "road",
    "node",
    "# comment",
    "   ",
    "road r from=A",
    "node A x=1 y=2 z=3",
    "building x=1",
    "map",
    "defaults lane_width=0",
    "overpass x1=0 y1=0 x2=0 y2=0 width=5",
    "node E0 x=0 y=0",
];

fn int(lo: i32, hi: i32) -> impl Strategy<Value = String> {
    (lo..hi).prop_map(|v| v.to_string())
}

/// A positive number, sometimes fractional, sometimes tiny.
fn positive(hi: f32) -> impl Strategy<Value = String> {
    prop_oneof![3 => (1..hi as i32).prop_map(|v| v.to_string()), 2 => (0.01f32..hi).prop_map(|v| v.to_string())]
}

fn heading() -> impl Strategy<Value = String> {
    prop_oneof![3 => prop::sample::select(&["0", "90", "180", "270", "-90", "45"][..]).prop_map(str::to_owned), 1 => int(-400, 400)]
}

fn lanes() -> impl Strategy<Value = &'static str> {
    prop::sample::select(&["1,1", "1,1", "1,1", "2,2", "1,0", "0,1", "4,4", "2,1"][..])
}

fn piece() -> impl Strategy<Value = String> {
    prop_oneof![
        3 => positive(150.0).prop_map(|l| format!("  straight length={l}")),
        2 => (positive(80.0), prop::sample::select(&["90", "-90", "45", "-30", "180", "270", "-270", "1", "-135"][..]))
            .prop_map(|(r, a)| format!("  arc radius={r} angle={a}")),
    ]
}

/// Optional extra road fields.
fn road_extras() -> impl Strategy<Value = String> {
    prop::collection::vec((prop::sample::select(&["lane_width", "shoulder", "sidewalk", "speed"][..]), positive(8.0)), 0..2)
        .prop_map(|fields| fields.iter().map(|(k, v)| format!(" {k}={v}")).collect())
}

/// A road statement, its pieces and its `end`, with `ROAD`, `FROM` and `TO` to fill in (see
/// `map_text`), and two picks for the nodes.
fn road_block() -> impl Strategy<Value = (String, usize, Option<usize>)> {
    let to = prop_oneof![4 => Just(None), 1 => any::<usize>().prop_map(Some)];
    (any::<usize>(), to, heading(), lanes(), road_extras(), prop::collection::vec(piece(), 1..4)).prop_map(
        |(from, to, h, lanes, extras, pieces)| {
            let mut s = format!("road ROAD from=FROM heading={h} to=TO lanes={lanes}{extras}\n");
            for p in pieces {
                s.push_str(&p);
                s.push('\n');
            }
            s.push_str("end\n");
            (s, from, to)
        },
    )
}

/// One well-formed statement other than a road, with random values of the right kind.
fn statement() -> impl Strategy<Value = String> {
    prop_oneof![
        (int(-100, 300), int(-100, 300), positive(40.0), positive(40.0))
            .prop_map(|(x, y, w, d)| format!("building x={x} y={y} width={w} depth={d}\n")),
        (int(-100, 300), int(-100, 300)).prop_map(|(x, y)| format!("pole x={x} y={y}\n")),
        (int(-100, 300), int(-100, 300), int(-100, 300), int(-100, 300), positive(20.0))
            .prop_map(|(a, b, c, d, w)| format!("overpass x1={a} y1={b} x2={c} y2={d} width={w}\n")),
        (positive(6.0), int(0, 4)).prop_map(|(w, s)| format!("defaults lane_width={w} shoulder={s}\n")),
    ]
}

/// A damage done to a well-formed map text, at positions taken modulo its size.
#[derive(Debug, Clone)]
enum Corruption {
    /// Replace the value of the k-th `key=value` field of line i.
    Value(usize, usize, &'static str),
    /// Insert an odd line before line i.
    Insert(usize, &'static str),
    /// Delete line i.
    Delete(usize),
}

fn corruption() -> impl Strategy<Value = Corruption> {
    prop_oneof![
        3 => (any::<usize>(), any::<usize>(), prop::sample::select(ODD_VALUES)).prop_map(|(i, k, v)| Corruption::Value(i, k, v)),
        1 => (any::<usize>(), prop::sample::select(ODD_LINES)).prop_map(|(i, l)| Corruption::Insert(i, l)),
        1 => any::<usize>().prop_map(Corruption::Delete),
    ]
}

fn corrupt(text: &str, damage: &[Corruption]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    for d in damage {
        let n = lines.len().max(1);
        match *d {
            Corruption::Value(i, k, v) => {
                let Some(line) = lines.get_mut(i % n) else { continue };
                let mut words: Vec<String> = line.split_whitespace().map(str::to_owned).collect();
                let fields: Vec<usize> = (0..words.len()).filter(|&w| words[w].contains('=')).collect();
                if let Some(&w) = fields.get(k % fields.len().max(1)) {
                    let key = words[w].split('=').next().unwrap_or("").to_owned();
                    words[w] = format!("{key}={v}");
                    *line = words.join(" ");
                }
            }
            Corruption::Insert(i, l) => lines.insert(i % n, l.to_owned()),
            Corruption::Delete(i) => {
                if !lines.is_empty() {
                    lines.remove(i % n);
                }
            }
        }
    }
    lines.join("\n")
}

/// Four defined nodes (A–D), one to five roads, up to three other statements, then up to two
/// corruptions. Road i starts at a defined node or at the end of an earlier road, and usually ends
/// at a node of its own (`E{i}`), sometimes at an existing one (which it rarely reaches exactly).
fn map_text() -> impl Strategy<Value = String> {
    (
        prop::collection::vec((int(-100, 300), int(-100, 300)), 4),
        prop::collection::vec(road_block(), 1..6),
        prop::collection::vec(statement(), 0..4),
        prop::collection::vec(corruption(), 0..3),
    )
        .prop_map(|(nodes, roads, others, damage)| {
            let mut names: Vec<String> = ["A", "B", "C", "D"].map(str::to_owned).to_vec();
            let mut text: String = nodes.iter().zip(&names).map(|((x, y), n)| format!("node {n} x={x} y={y}\n")).collect();
            for (i, (road, from, to)) in roads.iter().enumerate() {
                let from = &names[from % names.len()];
                let to = to.map_or_else(|| format!("E{i}"), |k| names[k % names.len()].clone());
                text.push_str(&road.replace("ROAD", &format!("r{i}")).replace("FROM", from).replace("TO", &to));
                names.push(format!("E{i}"));
            }
            text.push_str(&others.concat());
            corrupt(&text, &damage)
        })
}

/// How far a text got through loading.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Loaded {
    ParseError,
    BuildError,
    /// Built, with this many junction connectors.
    Built(usize),
}

/// Loads `text` all the way: parse, build, and the town's derived indices (planning graph,
/// obstacle grid). Checks the error agrees between `parse` and `from_text`, and that built maps
/// are well-formed.
fn load(text: &str) -> Loaded {
    let parsed = parse(text);
    let built = Map::from_text(text);
    if let (Err(p), Err(b)) = (&parsed, &built) {
        assert_eq!(p, b, "from_text must report the parse error");
    }
    match built {
        Err(e) => {
            assert!(!e.message.is_empty());
            if parsed.is_ok() { Loaded::BuildError } else { Loaded::ParseError }
        }
        Ok(map) => {
            assert!(parsed.is_ok(), "built a map whose text does not parse");
            for (i, lane) in map.lanes.iter().enumerate() {
                assert!(lane.path.length() > 0.0 && lane.path.length().is_finite(), "lane {i}");
                assert!(lane.successors.iter().all(|&s| s < map.lanes.len()), "lane {i} has a bad successor");
            }
            for j in &map.junctions {
                assert!(j.connectors.iter().all(|&c| matches!(map.lanes[c].kind, LaneKind::Connector { .. })));
                assert_eq!(j.conflicts.len(), j.connectors.len());
            }
            let connectors = map.junctions.iter().map(|j| j.connectors.len()).sum();
            let town = Town::new(map);
            assert_eq!(town.graph.lane_stations.len(), town.map.lanes.len());
            Loaded::Built(connectors)
        }
    }
}

proptest! {
    #![proptest_config(fuzz_config(256))]

    #[test]
    fn arbitrary_text_never_panics(text in any::<String>()) {
        let _ = parse(&text);
        let _ = Map::from_text(&text);
    }

    #[test]
    fn plausible_statements_with_odd_values_never_panic(text in map_text()) {
        load(&text);
    }
}

/// The generator above must reach the geometry builder, or "never panics" says little about it:
/// over 256 deterministic samples, parse errors, build errors and built maps must all be common,
/// and some built maps must have junctions.
#[test]
fn statement_generator_reaches_the_builder() {
    let mut runner = TestRunner::deterministic();
    let strategy = map_text();
    let (mut parse_errors, mut build_errors, mut built, mut with_junctions) = (0, 0, 0, 0);
    for _ in 0..256 {
        let text = strategy.new_tree(&mut runner).expect("strategy generates").current();
        match load(&text) {
            Loaded::ParseError => parse_errors += 1,
            Loaded::BuildError => build_errors += 1,
            Loaded::Built(connectors) => {
                built += 1;
                if connectors > 0 {
                    with_junctions += 1;
                }
            }
        }
    }
    let counts = (parse_errors, build_errors, built, with_junctions);
    // At least 5% (13 of 256) of each outcome, and 4% (10) of built maps with junctions.
    assert!(parse_errors >= 13 && build_errors >= 13 && built >= 13 && with_junctions >= 10, "{counts:?}");
}

// ---------------------------------------------------------------------------------------------
// The default town

/// The distinct roads feeding a junction's connectors.
fn incoming_roads(map: &Map, junction: usize) -> BTreeSet<usize> {
    map.junctions[junction]
        .connectors
        .iter()
        .map(|&c| match map.lanes[c].kind {
            LaneKind::Connector { from, .. } => match map.lanes[from].kind {
                LaneKind::Road { road, .. } => road,
                LaneKind::Connector { .. } => panic!("connector {c} starts on a connector"),
            },
            LaneKind::Road { .. } => panic!("junction {junction} lists road lane {c} as a connector"),
        })
        .collect()
}

fn turns(map: &Map, junction: usize) -> [usize; 3] {
    let mut n = [0; 3];
    for &c in &map.junctions[junction].connectors {
        if let LaneKind::Connector { turn, .. } = map.lanes[c].kind {
            n[match turn {
                Turn::Straight => 0,
                Turn::Left => 1,
                Turn::Right => 2,
            }] += 1;
        }
    }
    n
}

#[test]
fn default_town_parses_and_builds() {
    let spec = parse(DEFAULT_TOWN).expect("default town parses");
    assert_eq!(spec.name, "default_town");
    // default_town.map: 9 grid nodes A–I; 12 grid streets, 2 highway roads, the sharp bend and
    // the street under the overpass.
    assert_eq!(spec.nodes.len(), 9);
    assert_eq!(spec.roads.len(), 16);
    let map = Map::from_text(DEFAULT_TOWN).expect("default town builds");
    assert_eq!(map.roads.len(), 16);
    assert_eq!(map.name, "default_town");
}

#[test]
fn default_town_has_a_four_way_and_t_junctions() {
    let map = Map::default_town();
    let one_plus_one = |r: usize| map.roads[r].forward.len() == 1 && map.roads[r].backward.len() == 1;
    // A 4-way junction of 1+1-lane roads: 4 incoming lanes × 3 exits (straight, left, right; no
    // U-turns) = 12 connectors. default_town.map puts it at E (100, 100).
    let four_way: Vec<usize> = (0..map.junctions.len())
        .filter(|&j| {
            let roads = incoming_roads(&map, j);
            roads.len() == 4 && roads.iter().all(|&r| one_plus_one(r))
        })
        .collect();
    assert_eq!(four_way.len(), 1, "exactly one all-1+1 4-way junction (E)");
    let e = four_way[0];
    assert_eq!(map.junctions[e].connectors.len(), 12);
    assert_eq!(turns(&map, e), [4, 4, 4], "straight, left, right");
    assert!(map.junctions[e].centre.distance(Vec2::new(100.0, 100.0)) < 1e-3);
    // Crossing straight paths conflict; so does every left turn with the oncoming straight.
    assert!(map.junctions[e].conflicts.iter().all(|c| !c.is_empty()));

    // T junctions of 1+1-lane roads: 3 incoming lanes × 2 exits = 6 connectors, one of each
    // turn per direction pair. default_town.map has them at B, C, D, G and H (F also meets the
    // 2+2 highway, so it is not all 1+1).
    let t_junctions: Vec<usize> = (0..map.junctions.len())
        .filter(|&j| {
            let roads = incoming_roads(&map, j);
            roads.len() == 3 && roads.iter().all(|&r| one_plus_one(r))
        })
        .collect();
    assert!(!t_junctions.is_empty(), "no T junction");
    for &j in &t_junctions {
        assert_eq!(map.junctions[j].connectors.len(), 6, "T junction at {:?}", map.junctions[j].centre);
        assert_eq!(turns(&map, j), [2, 2, 2], "T junction at {:?}", map.junctions[j].centre);
    }
    let centres: BTreeSet<(i32, i32)> =
        t_junctions.iter().map(|&j| (map.junctions[j].centre.x.round() as i32, map.junctions[j].centre.y.round() as i32)).collect();
    let expected: BTreeSet<(i32, i32)> = [(100, 0), (200, 0), (0, 100), (0, 200), (100, 200)].into_iter().collect();
    assert_eq!(centres, expected, "T junctions at B, C, D, G, H");
}

#[test]
fn default_town_has_a_two_lane_highway() {
    let map = Map::default_town();
    let highway = &map.roads[map.road_by_name("highway").expect("highway road")];
    assert_eq!((highway.forward.len(), highway.backward.len()), (2, 2));
    for group in [&highway.forward, &highway.backward] {
        // Innermost first; the outer lane is to the right of the inner one.
        assert_eq!(map.lanes[group[0]].right, Some(group[1]));
        assert_eq!(map.lanes[group[1]].left, Some(group[0]));
    }
    // Lanes are 3.5 m wide (the map's defaults): centres 1.75 and 5.25 m from the centre line,
    // forward lanes on the right (negative lateral), backward ones on the left.
    let mid = |lane: usize| {
        let p = &map.lanes[lane].path;
        highway.centre.project(p.point_at(p.length() / 2.0)).lateral
    };
    let offsets = [mid(highway.forward[0]), mid(highway.forward[1]), mid(highway.backward[0]), mid(highway.backward[1])];
    for (got, want) in offsets.iter().zip([-1.75, -5.25, 1.75, 5.25]) {
        assert!((got - want).abs() < 0.01, "lane offsets {offsets:?}");
    }
}

#[test]
fn default_town_has_an_overpass_on_four_pillars() {
    let map = Map::default_town();
    assert_eq!(map.overpasses.len(), 1);
    let pillars: Vec<_> = map.obstacles.iter().filter(|o| o.kind == ObstacleKind::Pillar).collect();
    assert_eq!(pillars.len(), 4);
    // default_town.map: deck from (−24, 290) to (24, 290), 10 m wide, pillars 1.4 m square at its
    // corners, as tall as the 5.5 m clearance.
    let mut corners: Vec<(i32, i32)> = pillars.iter().map(|p| (p.centre.x.round() as i32, p.centre.y.round() as i32)).collect();
    corners.sort_unstable();
    assert_eq!(corners, vec![(-24, 285), (-24, 295), (24, 285), (24, 295)]);
    for p in &pillars {
        assert!((p.half_extents - Vec2::splat(0.7)).length() < 1e-5);
        assert_eq!(p.height, 5.5);
    }
}

#[test]
fn every_evaluation_route_resolves_and_plans() {
    let town = Town::default_town();
    let map = &town.map;
    for route in EvalRoute::ALL {
        let [from, to] = route.endpoints(map).unwrap_or_else(|| panic!("{}: endpoints", route.name()));
        // Endpoints are road stations projected onto a lane: `distance` is that lane's offset from
        // the centre line, (index + 0.5) lane widths (all endpoints lie on straight stretches).
        for end in [from, to] {
            let lane = &map.lanes[end.lane];
            let LaneKind::Road { index, .. } = lane.kind else { panic!("{}: endpoint on a connector", route.name()) };
            assert!((end.distance - (index as f32 + 0.5) * lane.width).abs() < 0.05, "{}: {end:?}", route.name());
        }
        let r = eval_route(&town, route, 8.0).unwrap_or_else(|| panic!("{}: no route", route.name()));
        let (a, b) = (map.lanes[from.lane].path.point_at(from.s), map.lanes[to.lane].path.point_at(to.s));
        // Route length: at least the straight line; at most √2 times it (an L-shaped turn).
        let straight = a.distance(b);
        assert!(r.length() >= straight - 1e-3 && r.length() <= straight * 1.42, "{}: {} m for {straight} m", route.name(), r.length());
        let conn_turns: Vec<Turn> = r
            .lanes
            .iter()
            .filter_map(|&(l, _)| match map.lanes[l].kind {
                LaneKind::Connector { turn, .. } => Some(turn),
                LaneKind::Road { .. } => None,
            })
            .collect();
        let expected: &[Turn] = match route {
            // Through the 4-way junction E; right and left at E (scenario.rs).
            EvalRoute::StraightUrban => &[Turn::Straight],
            EvalRoute::RightTurn => &[Turn::Right],
            EvalRoute::LeftTurn => &[Turn::Left],
            // Along one road, or two joined smoothly (highway → highway_curve): no junction.
            _ => &[],
        };
        assert_eq!(conn_turns, expected, "{}", route.name());
    }
}
