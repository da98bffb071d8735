//! Turns a checked [`MapSpec`] into geometry: centre lines, lanes, junction connectors and their
//! conflicts, obstacles and the surface raster. Errors that only geometry reveals (a road that does
//! not reach its end node, a road too short for its junctions) name the road's line and field.

use super::connectors::{add_connector, conflict_sets};
use super::format::{MapError, MapSpec, PieceSpec, RoadSpec};
use super::surface::{Surface, SurfaceRaster};
use super::{Junction, Lane, LaneId, LaneKind, Map, ObstacleKind, Overpass, Road, StaticObstacle, Turn};
use crate::math::{Vec2, cross, dir, left_normal, wrap_angle};
use crate::polyline::Polyline;

/// Centre lines are sampled at least this densely, metres.
const SAMPLE: f32 = 1.0;
/// A road must end within this distance of its `to` node, metres.
const END_TOLERANCE: f32 = 0.5;
/// Junction area reaches this far beyond the widest road's half-width, metres.
const JUNCTION_MARGIN: f32 = 2.0;
/// Raster cell size, metres.
pub(super) const RASTER_CELL: f32 = 0.25;

/// One end of a road at a node.
#[derive(Debug, Clone, Copy)]
struct RoadEnd {
    road: usize,
    at_start: bool,
}

pub(super) fn build(spec: &MapSpec) -> Result<Map, MapError> {
    // Node positions, growing as roads create their end nodes.
    let mut nodes: Vec<(String, Vec2)> = spec.nodes.iter().map(|n| (n.name.clone(), Vec2::new(n.x, n.y))).collect();
    let mut centres = Vec::with_capacity(spec.roads.len());
    let mut ends: Vec<(usize, usize)> = Vec::with_capacity(spec.roads.len()); // (from node, to node)
    for r in &spec.roads {
        let from = nodes.iter().position(|(n, _)| *n == r.from).ok_or_else(|| {
            MapError::at(
                r.line,
                Some("from"),
                format!("unknown node `{}`: define it with `node {} x=.. y=..` or end an earlier road there", r.from, r.from),
            )
        })?;
        let centre = centre_line(r, nodes[from].1)?;
        let end = centre.end();
        let to = match nodes.iter().position(|(n, _)| *n == r.to) {
            Some(i) => {
                let gap = nodes[i].1.distance(end);
                if gap > END_TOLERANCE {
                    return Err(MapError::at(
                        r.line,
                        Some("to"),
                        format!(
                            "the road's pieces end at ({:.1}, {:.1}), {gap:.1} m from node `{}` at ({:.1}, {:.1}); adjust the pieces or the node",
                            end.x, end.y, r.to, nodes[i].1.x, nodes[i].1.y
                        ),
                    ));
                }
                i
            }
            None => {
                nodes.push((r.to.clone(), end));
                nodes.len() - 1
            }
        };
        if from == to {
            return Err(MapError::at(r.line, Some("to"), "a road must join two different nodes"));
        }
        centres.push(centre);
        ends.push((from, to));
    }
    check_extent(spec, &centres)?;

    // Road ends per node.
    let mut at_node: Vec<Vec<RoadEnd>> = vec![Vec::new(); nodes.len()];
    for (i, &(from, to)) in ends.iter().enumerate() {
        at_node[from].push(RoadEnd { road: i, at_start: true });
        at_node[to].push(RoadEnd { road: i, at_start: false });
    }

    // Which nodes are junctions, and how much of each road they take.
    let outward = |e: RoadEnd| -> f32 {
        let c = &centres[e.road];
        if e.at_start { c.heading_at(0.0) } else { wrap_angle(c.heading_at(c.length()) + std::f32::consts::PI) }
    };
    let half_width = |r: &RoadSpec| (r.lanes_forward.max(r.lanes_backward) as f32) * r.lane_width + r.shoulder;
    let mut is_junction = vec![false; nodes.len()];
    let mut cut = vec![0.0f32; nodes.len()];
    // The road whose width sets each junction's size, to blame when the junction does not fit.
    let mut widest: Vec<Option<usize>> = vec![None; nodes.len()];
    for (n, list) in at_node.iter().enumerate() {
        is_junction[n] = match list.as_slice() {
            [] | [_] => false,
            [a, b] => !smooth_joint(spec, *a, *b, outward(*a), outward(*b)),
            _ => true,
        };
        if is_junction[n] {
            let w = list.iter().max_by(|a, b| half_width(&spec.roads[a.road]).total_cmp(&half_width(&spec.roads[b.road])));
            widest[n] = w.map(|e| e.road);
            cut[n] = w.map_or(0.0, |e| half_width(&spec.roads[e.road])) + JUNCTION_MARGIN;
        }
    }

    // Roads and their lanes.
    let mut roads = Vec::with_capacity(spec.roads.len());
    let mut lanes: Vec<Lane> = Vec::new();
    for (i, r) in spec.roads.iter().enumerate() {
        let centre = centres[i].clone();
        let (from, to) = ends[i];
        let (cut_start, cut_end) = (cut[from], cut[to]);
        if centre.length() - cut_start - cut_end < 2.0 {
            // A lane width beyond what roads have is the likelier mistake: blame the line that
            // set it (perhaps a `defaults` line, or another road's) rather than this road's.
            let implausible = [from, to]
                .into_iter()
                .filter_map(|n| widest[n])
                .map(|w| &spec.roads[w])
                .find(|w| !super::format::PLAUSIBLE_LANE_WIDTH.contains(&w.lane_width) && w.lane_width_line > 0);
            if let Some(w) = implausible {
                return Err(MapError::at(
                    w.lane_width_line,
                    Some("lane_width"),
                    format!(
                        "lane width {} m (road `{}`) makes its junctions take {:.1} m of road `{}` (line {}), which is {:.1} m long; \
                         lanes are 2.5–5 m wide",
                        w.lane_width,
                        w.name,
                        cut_start + cut_end,
                        r.name,
                        r.line,
                        centre.length()
                    ),
                ));
            }
            return Err(MapError::at(
                r.line,
                None,
                format!(
                    "road `{}` is {:.1} m long but its junctions take {:.1} m: make it longer",
                    r.name,
                    centre.length(),
                    cut_start + cut_end
                ),
            ));
        }
        let speed_limit = r.speed_kmh / 3.6;
        let mut make = |forward: bool, index: usize| -> LaneId {
            let offset = (index as f32 + 0.5) * r.lane_width * if forward { -1.0 } else { 1.0 };
            let mut pts = offset_points(&centre, offset, cut_start, centre.length() - cut_end);
            if !forward {
                pts.reverse();
            }
            lanes.push(Lane {
                kind: LaneKind::Road { road: i, forward, index },
                path: Polyline::new(pts).expect("road longer than its cuts"),
                width: r.lane_width,
                speed_limit,
                successors: Vec::new(),
                left: None,
                right: None,
                ends_at_junction: None,
            });
            lanes.len() - 1
        };
        let forward: Vec<LaneId> = (0..r.lanes_forward as usize).map(|k| make(true, k)).collect();
        let backward: Vec<LaneId> = (0..r.lanes_backward as usize).map(|k| make(false, k)).collect();
        for group in [&forward, &backward] {
            for w in group.windows(2) {
                lanes[w[0]].right = Some(w[1]);
                lanes[w[1]].left = Some(w[0]);
            }
        }
        roads.push(Road {
            name: r.name.clone(),
            centre,
            lane_width: r.lane_width,
            shoulder: r.shoulder,
            sidewalk: r.sidewalk,
            speed_limit,
            forward,
            backward,
            cut_start,
            cut_end,
        });
    }

    // Lanes arriving at / leaving a node through a road end, innermost first.
    let incoming = |roads: &[Road], e: RoadEnd| -> Vec<LaneId> {
        if e.at_start { roads[e.road].backward.clone() } else { roads[e.road].forward.clone() }
    };
    let outgoing = |roads: &[Road], e: RoadEnd| -> Vec<LaneId> {
        if e.at_start { roads[e.road].forward.clone() } else { roads[e.road].backward.clone() }
    };

    let mut junctions = Vec::new();
    for (n, list) in at_node.iter().enumerate() {
        if !is_junction[n] {
            if let [a, b] = list.as_slice() {
                // Smooth joint: lane k continues as lane k.
                for (x, y) in [(*a, *b), (*b, *a)] {
                    for (l_in, l_out) in incoming(&roads, x).into_iter().zip(outgoing(&roads, y)) {
                        lanes[l_in].successors.push(l_out);
                    }
                }
            }
            continue;
        }
        let jid = junctions.len();
        let mut connectors = Vec::new();
        for &e_in in list {
            let ins = incoming(&roads, e_in);
            if ins.is_empty() {
                continue;
            }
            for &e_out in list {
                if e_out.road == e_in.road && e_out.at_start == e_in.at_start {
                    continue;
                }
                let outs = outgoing(&roads, e_out);
                if outs.is_empty() {
                    continue;
                }
                let h_in = lanes[ins[0]].path.heading_at(lanes[ins[0]].path.length());
                let h_out = lanes[outs[0]].path.heading_at(0.0);
                let delta = wrap_angle(h_out - h_in);
                if delta.abs() > 150f32.to_radians() {
                    continue; // a U-turn
                }
                let (turn, pairs): (Turn, Vec<(LaneId, LaneId)>) = if delta.abs() < 35f32.to_radians() {
                    (Turn::Straight, ins.iter().zip(&outs).map(|(a, b)| (*a, *b)).collect())
                } else if delta > 0.0 {
                    (Turn::Left, vec![(ins[0], outs[0])])
                } else {
                    (Turn::Right, vec![(*ins.last().expect("non-empty"), *outs.last().expect("non-empty"))])
                };
                for (from, to) in pairs {
                    let path = connector_path(&lanes[from].path, &lanes[to].path);
                    let (width, speed_limit) = (lanes[from].width, lanes[from].speed_limit.min(lanes[to].speed_limit));
                    connectors.push(add_connector(&mut lanes, jid, (from, to), turn, path, width, speed_limit));
                }
            }
        }
        let outline = convex_hull(list.iter().flat_map(|e| cross_section(&roads[e.road], e.at_start, 0.0)).collect());
        let conflicts = conflict_sets(&lanes, &connectors);
        junctions.push(Junction { centre: nodes[n].1, outline, connectors, conflicts });
    }

    let mut obstacles = Vec::new();
    for b in &spec.buildings {
        obstacles.push(StaticObstacle {
            kind: ObstacleKind::Building,
            centre: Vec2::new(b.x, b.y),
            half_extents: Vec2::new(b.width / 2.0, b.depth / 2.0),
            angle: b.angle_deg.to_radians(),
            height: b.height,
        });
    }
    for p in &spec.poles {
        obstacles.push(StaticObstacle {
            kind: ObstacleKind::Pole,
            centre: Vec2::new(p.x, p.y),
            half_extents: Vec2::splat(p.radius),
            angle: 0.0,
            height: p.height,
        });
    }
    let mut overpasses = Vec::new();
    for o in &spec.overpasses {
        let (a, b) = (Vec2::new(o.x1, o.y1), Vec2::new(o.x2, o.y2));
        let axis = (b - a).normalize();
        let side = left_normal(axis) * (o.width / 2.0);
        for corner in [a + side, a - side, b + side, b - side] {
            obstacles.push(StaticObstacle {
                kind: ObstacleKind::Pillar,
                centre: corner,
                half_extents: Vec2::splat(o.pillar / 2.0),
                angle: axis.y.atan2(axis.x),
                height: o.clearance,
            });
        }
        overpasses.push(Overpass { a, b, width: o.width, clearance: o.clearance, thickness: o.thickness });
    }

    let surface = paint_surface(&roads, &junctions, &at_node, &is_junction, &obstacles, &overpasses);
    Ok(Map { name: spec.name.clone(), roads, lanes, junctions, obstacles, overpasses, surface, warnings: spec.warnings.clone() })
}

/// The surface raster may hold at most this many cells (64 MiB: 4 km² at `RASTER_CELL`).
pub(super) const MAX_RASTER_CELLS: f64 = (1u64 << 26) as f64;

/// Refuses maps whose bounding box (as `paint_surface` computes it, 30 m margin included) would
/// need a raster too large to allocate: coordinates up to ±1e6 m are valid numbers, but a map
/// spanning them would abort the process on allocation.
fn check_extent(spec: &MapSpec, centres: &[Polyline]) -> Result<(), MapError> {
    let mut pts: Vec<Vec2> = centres.iter().flat_map(|c| c.points().iter().copied()).collect();
    pts.extend(spec.buildings.iter().map(|b| Vec2::new(b.x, b.y)));
    pts.extend(spec.poles.iter().map(|p| Vec2::new(p.x, p.y)));
    for o in &spec.overpasses {
        let r = Vec2::splat(o.width / 2.0);
        pts.extend([Vec2::new(o.x1, o.y1) - r, Vec2::new(o.x1, o.y1) + r, Vec2::new(o.x2, o.y2) - r, Vec2::new(o.x2, o.y2) + r]);
    }
    let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for p in pts {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let (w, h) = (f64::from(hi.x - lo.x) + 60.0, f64::from(hi.y - lo.y) + 60.0);
    let cells = (w / f64::from(RASTER_CELL)).ceil() * (h / f64::from(RASTER_CELL)).ceil();
    if cells > MAX_RASTER_CELLS {
        return Err(MapError::at(
            0,
            None,
            format!("the map spans {w:.0} m × {h:.0} m (roads and obstacles, with margins); it must fit in 4 km² (e.g. 2 km × 2 km)"),
        ));
    }
    Ok(())
}

/// Whether two road ends at a node continue each other smoothly (same direction, same lanes).
fn smooth_joint(spec: &MapSpec, a: RoadEnd, b: RoadEnd, out_a: f32, out_b: f32) -> bool {
    let straight = wrap_angle(out_a - out_b - std::f32::consts::PI).abs() < 10f32.to_radians();
    let (ra, rb) = (&spec.roads[a.road], &spec.roads[b.road]);
    // Lanes leaving the node through `a` must match lanes arriving through `b`, and vice versa.
    let (out_of_a, into_a) = if a.at_start { (ra.lanes_forward, ra.lanes_backward) } else { (ra.lanes_backward, ra.lanes_forward) };
    let (out_of_b, into_b) = if b.at_start { (rb.lanes_forward, rb.lanes_backward) } else { (rb.lanes_backward, rb.lanes_forward) };
    straight && out_of_a == into_b && into_a == out_of_b && ra.lane_width == rb.lane_width && ra.shoulder == rb.shoulder
}

/// Samples a road's centre line from its start node.
fn centre_line(r: &RoadSpec, start: Vec2) -> Result<Polyline, MapError> {
    let mut p = start;
    let mut h = r.heading_deg.to_radians();
    let mut pts = vec![p];
    for piece in &r.pieces {
        match *piece {
            PieceSpec::Straight { length } => {
                let n = (length / SAMPLE).ceil().max(1.0) as usize;
                let d = dir(h);
                pts.extend((1..=n).map(|k| p + d * (length * k as f32 / n as f32)));
                p += d * length;
            }
            PieceSpec::Arc { radius, angle_deg } => {
                let angle = angle_deg.to_radians();
                let sign = angle.signum();
                let centre = p + left_normal(dir(h)) * (sign * radius);
                let n = (radius * angle.abs() / SAMPLE).ceil().max(2.0) as usize;
                let at = |phi: f32| centre - left_normal(dir(phi)) * (sign * radius);
                pts.extend((1..=n).map(|k| at(h + angle * k as f32 / n as f32)));
                h = wrap_angle(h + angle);
                p = at(h);
            }
        }
    }
    Polyline::new(pts).ok_or_else(|| MapError::at(r.line, None, format!("road `{}` has zero length", r.name)))
}

/// Points offset sideways (positive = left) from a centre line between arc lengths `s0` and `s1`.
fn offset_points(centre: &Polyline, offset: f32, s0: f32, s1: f32) -> Vec<Vec2> {
    let at = |s: f32| centre.point_at(s) + left_normal(centre_tangent(centre, s)) * offset;
    let mut pts = vec![at(s0)];
    let mut s = (s0 / SAMPLE).floor() * SAMPLE + SAMPLE;
    while s < s1 - 0.05 {
        pts.push(at(s));
        s += SAMPLE;
    }
    pts.push(at(s1));
    pts
}

/// The tangent at arc length `s`, averaged with the neighbouring segment at a vertex so that offset
/// curves do not kink.
fn centre_tangent(centre: &Polyline, s: f32) -> Vec2 {
    let a = centre.tangent_at((s - 0.01).max(0.0));
    let b = centre.tangent_at((s + 0.01).min(centre.length()));
    (a + b).normalize_or(a)
}

/// The drivable cross-section of a road (left and right edge points) at its start or end,
/// `extra` metres beyond the drivable edge, at the junction cut.
fn cross_section(road: &Road, at_start: bool, extra: f32) -> [Vec2; 2] {
    let s = if at_start { road.cut_start } else { road.centre.length() - road.cut_end };
    let c = road.centre.point_at(s);
    let n = left_normal(centre_tangent(&road.centre, s));
    [c + n * (road.left_width() + extra), c - n * (road.right_width() + extra)]
}

/// A cubic Bézier from the end of `a` to the start of `b`, tangent to both.
fn connector_path(a: &Polyline, b: &Polyline) -> Polyline {
    let p0 = a.end();
    let p3 = b.start();
    let t0 = a.tangent_at(a.length());
    let t1 = b.tangent_at(0.0);
    let handle = p0.distance(p3) * 0.4;
    let (p1, p2) = (p0 + t0 * handle, p3 - t1 * handle);
    let n = ((p0.distance(p3) / 0.5).ceil() as usize).max(4);
    let pts = (0..=n).map(|k| {
        let t = k as f32 / n as f32;
        let u = 1.0 - t;
        p0 * (u * u * u) + p1 * (3.0 * u * u * t) + p2 * (3.0 * u * t * t) + p3 * (t * t * t)
    });
    Polyline::new(pts).unwrap_or_else(|| Polyline::new([p0, p0 + t0 * 0.1]).expect("two distinct points"))
}

/// Convex hull (Andrew's monotone chain), counter-clockwise.
pub(super) fn convex_hull(mut pts: Vec<Vec2>) -> Vec<Vec2> {
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let mut hull: Vec<Vec2> = Vec::with_capacity(pts.len() * 2);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &Vec2>> = if pass == 0 { Box::new(pts.iter()) } else { Box::new(pts.iter().rev()) };
        for &p in iter {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 1] - hull[hull.len() - 2], p - hull[hull.len() - 2]) <= 0.0 {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// Paints sidewalks, shoulders, lanes and junctions into a raster over the whole map.
fn paint_surface(
    roads: &[Road],
    junctions: &[Junction],
    at_node: &[Vec<RoadEnd>],
    is_junction: &[bool],
    obstacles: &[StaticObstacle],
    overpasses: &[Overpass],
) -> SurfaceRaster {
    let margin = 30.0;
    let mut lo = Vec2::splat(f32::INFINITY);
    let mut hi = Vec2::splat(f32::NEG_INFINITY);
    for r in roads {
        for &p in r.centre.points() {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    for o in obstacles {
        lo = lo.min(o.centre);
        hi = hi.max(o.centre);
    }
    let mut raster = SurfaceRaster::new(lo - Vec2::splat(margin), hi + Vec2::splat(margin), RASTER_CELL);
    for r in roads {
        let (s0, s1) = (r.cut_start, r.centre.length() - r.cut_end);
        let samples = offset_points(&r.centre, 0.0, s0, s1);
        let stations: Vec<f32> = samples.iter().map(|&p| r.centre.project(p).s).collect();
        for w in stations.windows(2) {
            let strip = |left: f32, right: f32| -> [Vec2; 4] {
                let corner = |s: f32, off: f32| r.centre.point_at(s) + left_normal(centre_tangent(&r.centre, s)) * off;
                [corner(w[0], -right), corner(w[1], -right), corner(w[1], left), corner(w[0], left)]
            };
            let (lw, rw) = (r.left_width(), r.right_width());
            raster.fill_convex(&strip(lw + r.sidewalk, rw + r.sidewalk), Surface::Sidewalk);
            raster.fill_convex(&strip(lw, rw), Surface::Shoulder);
            raster.fill_convex(&strip(lw - r.shoulder, rw - r.shoulder), Surface::Road);
        }
        paint_markings(&mut raster, r);
    }
    let mut j = 0;
    for (n, list) in at_node.iter().enumerate() {
        if !is_junction[n] {
            continue;
        }
        let sidewalk = list.iter().map(|e| roads[e.road].sidewalk).fold(0.0, f32::max);
        let outer = convex_hull(list.iter().flat_map(|e| cross_section(&roads[e.road], e.at_start, sidewalk)).collect());
        raster.fill_convex(&outer, Surface::Sidewalk);
        raster.fill_convex(&junctions[j].outline, Surface::Junction);
        j += 1;
    }
    for o in overpasses {
        let axis = (o.b - o.a).normalize();
        let side = left_normal(axis) * (o.width / 2.0);
        raster.shade_convex(&[o.a - side, o.b - side, o.b + side, o.a + side]);
    }
    raster.build_levels(RASTER_LEVELS);
    raster
}

/// Levels of the surface raster pyramid (0.25, 0.5, 1, 2 and 4 m cells).
pub(super) const RASTER_LEVELS: usize = 5;

/// Width of painted lines, metres (wide enough to stay continuous on the raster).
const LINE_WIDTH: f32 = 0.3;
/// Dashed lines: painted and gap lengths, metres.
const DASH: (f32, f32) = (3.0, 6.0);

/// Paints a road's lines: a solid yellow centre line between the two directions, dashed white
/// lines between lanes of one direction, solid white edge lines where there is a shoulder.
fn paint_markings(raster: &mut SurfaceRaster, r: &Road) {
    let (s0, s1) = (r.cut_start, r.centre.length() - r.cut_end);
    let (nf, nb) = (r.forward.len() as f32, r.backward.len() as f32);
    let w = r.lane_width;
    let mut lines: Vec<(f32, Surface, bool)> = Vec::new(); // (offset, kind, dashed)
    if nf > 0.0 && nb > 0.0 {
        lines.push((0.0, Surface::YellowLine, false));
    }
    for k in 1..r.forward.len() {
        lines.push((-(k as f32) * w, Surface::WhiteLine, true));
    }
    for k in 1..r.backward.len() {
        lines.push((k as f32 * w, Surface::WhiteLine, true));
    }
    if r.shoulder > 0.0 {
        lines.push((-nf * w, Surface::WhiteLine, false));
        lines.push((nb * w, Surface::WhiteLine, false));
    }
    let corner = |s: f32, off: f32| r.centre.point_at(s) + left_normal(centre_tangent(&r.centre, s)) * off;
    for (offset, kind, dashed) in lines {
        let mut s = s0;
        while s < s1 {
            let step = if dashed { DASH.0 } else { SAMPLE };
            let e = (s + step).min(s1);
            let h = LINE_WIDTH / 2.0;
            raster.fill_convex(&[corner(s, offset - h), corner(e, offset - h), corner(e, offset + h), corner(s, offset + h)], kind);
            s = if dashed { e + DASH.1 } else { e };
        }
    }
}
