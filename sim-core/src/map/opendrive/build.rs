//! OpenDRIVE records → the simulator's [`Map`]: each lane section of an ordinary road becomes a
//! map road with its driving lanes (right lanes travel along the reference line, left lanes
//! against it: right-hand traffic); junction lane chains become connectors with conflict sets;
//! the lanes of every type are painted into the surface raster.

use std::collections::{BTreeMap, BTreeSet};

use super::error::OpenDriveError;
use super::lanes::{SampledSection, sample};
use super::parse::{Contact, Link, Network, Road as OdRoad};
use crate::map::build::{MAX_RASTER_CELLS, RASTER_CELL, RASTER_LEVELS, convex_hull};
use crate::map::connectors::{add_connector, conflict_sets};
use crate::map::{Junction, Lane, LaneId, LaneKind, Map, MapWarning, Road, Surface, SurfaceRaster, Turn};
use crate::math::Vec2;
use crate::polyline::Polyline;

/// Linked lanes must meet within this distance, metres, to be joined in the lane graph.
const JOIN_TOLERANCE: f32 = 0.5;
/// ... and head within this angle of each other, radians.
const JOIN_HEADING: f32 = 0.6;
/// A speed limit for roads that give none: 50 km/h, the usual urban limit.
const DEFAULT_SPEED: f32 = 50.0 / 3.6;
/// At most this many warnings of one kind are listed; the rest are counted in one line.
const WARNINGS_PER_KIND: usize = 20;
/// A chain of connecting roads through one junction is followed this far.
const MAX_CHAIN: usize = 4;

/// Lane types vehicles drive in (the lane graph).
fn is_driving(kind: &str) -> bool {
    matches!(kind, "driving" | "entry" | "exit" | "onRamp" | "offRamp" | "connectingRamp")
}

/// What a lane type paints: driving lanes the road, strips beside them a drivable shoulder,
/// sidewalks, curbs and medians the not-drivable edge. A `border` is "a hard border at the edge
/// of a road, the same height as the drivable lane" (OpenDRIVE 1.6, lane types): drivable ground, as a
/// shoulder, unlike the raised `curb`. (esmini's towns put a 0.3 m border between the lane and
/// the sidewalk; painted as sidewalk, a car leaving a tight left turn clipped it.)
fn surface_of(kind: &str) -> Option<Surface> {
    match kind {
        k if is_driving(k) => Some(Surface::Road),
        "shoulder" | "border" | "parking" | "biking" | "stop" | "restricted" | "bidirectional" => Some(Surface::Shoulder),
        "sidewalk" | "curb" | "median" => Some(Surface::Sidewalk),
        _ => None,
    }
}

/// A drivable OpenDRIVE lane: where it is and its centre line in the direction of travel.
#[derive(Debug)]
struct OdLane {
    road: usize,
    section: usize,
    id: i32,
    path: Polyline,
    width: f32,
    speed: f32,
    in_junction: bool,
}

/// Collects warnings, a bounded number of each kind.
#[derive(Default)]
struct Warnings {
    list: Vec<MapWarning>,
    counts: BTreeMap<&'static str, usize>,
}

impl Warnings {
    fn push(&mut self, kind: &'static str, line: u32, message: String) {
        let n = self.counts.entry(kind).or_insert(0);
        *n += 1;
        if *n <= WARNINGS_PER_KIND {
            self.list.push(MapWarning { line: line as usize, field: kind.to_owned(), message });
        }
    }

    fn finish(mut self) -> Vec<MapWarning> {
        for (kind, n) in self.counts {
            if n > WARNINGS_PER_KIND {
                self.list.push(MapWarning {
                    line: 0,
                    field: kind.to_owned(),
                    message: format!("{} more like this", n - WARNINGS_PER_KIND),
                });
            }
        }
        self.list
    }
}

pub(super) fn build(net: Network) -> Result<Map, OpenDriveError> {
    let mut warnings = Warnings { list: net.warnings.clone(), ..Warnings::default() };
    let mut road_index: BTreeMap<&str, usize> = BTreeMap::new();
    for (i, r) in net.roads.iter().enumerate() {
        if road_index.insert(r.id.as_str(), i).is_some() {
            return Err(OpenDriveError::at(r.pos.line, r.pos.column, format!("two roads with id {}", r.id)));
        }
    }
    let sampled: Vec<Vec<SampledSection>> = net.roads.iter().map(|r| (0..r.sections.len()).map(|k| sample(r, k)).collect()).collect();
    for (r, secs) in net.roads.iter().zip(&sampled) {
        let negative: usize = secs.iter().map(|s| s.negative_widths).sum();
        if negative > 0 {
            warnings.push(
                "width",
                r.pos.line,
                format!("road {}: a lane width polynomial goes below 0 at {negative} stations (taken as 0)", r.id),
            );
        }
    }

    // Every drivable lane, by (road, section, id).
    let mut od_lanes: Vec<OdLane> = Vec::new();
    let mut lane_at: BTreeMap<(usize, usize, i32), usize> = BTreeMap::new();
    for (ri, r) in net.roads.iter().enumerate() {
        let speed = r.speed.map_or(DEFAULT_SPEED, |v| v as f32);
        for (k, sec) in r.sections.iter().enumerate() {
            let smp = &sampled[ri][k];
            for (lane, sl) in sec.lanes.iter().zip(&smp.lanes) {
                if !is_driving(&lane.kind) {
                    continue;
                }
                let mut pts: Vec<Vec2> = (0..smp.stations.len()).map(|i| smp.point(i, sl.centre(i))).collect();
                if lane.id > 0 {
                    pts.reverse();
                }
                let Some(path) = Polyline::new(pts) else {
                    warnings.push(
                        "laneSection",
                        sec.pos.line,
                        format!("road {}: lane {} of the section at s = {} has no length; left out", r.id, lane.id, sec.s),
                    );
                    continue;
                };
                let n = smp.stations.len();
                let width = ((0..n).map(|i| sl.width(i)).sum::<f64>() / n as f64) as f32;
                if width < 0.5 {
                    warnings.push(
                        "width",
                        lane.pos.line,
                        format!("road {}: lane {} is {width:.2} m wide on average; left out of the lane graph", r.id, lane.id),
                    );
                    continue;
                }
                lane_at.insert((ri, k, lane.id), od_lanes.len());
                od_lanes.push(OdLane { road: ri, section: k, id: lane.id, path, width, speed, in_junction: r.junction.is_some() });
            }
        }
    }

    // Candidate links between lanes, from lane links, road links and junction lane links; each
    // oriented by geometry below (one lane's end meets the other's start).
    let mut pairs: BTreeSet<(usize, usize)> = BTreeSet::new();
    let mut add = |a: Option<&usize>, b: Option<&usize>| {
        if let (Some(&a), Some(&b)) = (a, b) {
            pairs.insert((a.min(b), a.max(b)));
        }
    };
    for (ri, r) in net.roads.iter().enumerate() {
        let last = r.sections.len() - 1;
        for (k, sec) in r.sections.iter().enumerate() {
            for lane in &sec.lanes {
                let me = lane_at.get(&(ri, k, lane.id));
                // Within the road: the next section (the same id when no link is given).
                if k < last {
                    add(me, lane_at.get(&(ri, k + 1, lane.successor.unwrap_or(lane.id))));
                }
                for (end_link, link_id, at_end) in [(&r.successor, lane.successor, k == last), (&r.predecessor, lane.predecessor, k == 0)] {
                    if !at_end {
                        continue;
                    }
                    if let (Some(Link::Road { id, contact, pos }), Some(target_lane)) = (end_link, link_id) {
                        let Some(&t) = road_index.get(id.as_str()) else {
                            return Err(OpenDriveError::at(
                                pos.line,
                                pos.column,
                                format!("road {}: links to road {id}, which the file does not have", r.id),
                            ));
                        };
                        let ts = if *contact == Contact::Start { 0 } else { net.roads[t].sections.len() - 1 };
                        add(me, lane_at.get(&(t, ts, target_lane)));
                    }
                }
            }
        }
        for link in [&r.successor, &r.predecessor].into_iter().flatten() {
            let missing = match link {
                Link::Junction { id, pos } => (!net.junctions.iter().any(|j| &j.id == id)).then_some(("junction", id, pos)),
                Link::Road { id, pos, .. } => (!road_index.contains_key(id.as_str())).then_some(("road", id, pos)),
            };
            if let Some((what, id, pos)) = missing {
                return Err(OpenDriveError::at(
                    pos.line,
                    pos.column,
                    format!("road {}: links to {what} {id}, which the file does not have", r.id),
                ));
            }
        }
    }
    for j in &net.junctions {
        for c in &j.connections {
            let (Some(&inc), Some(&con)) = (road_index.get(c.incoming.as_str()), road_index.get(c.connecting.as_str())) else {
                return Err(OpenDriveError::at(
                    c.pos.line,
                    c.pos.column,
                    format!(
                        "junction {}: connection between roads {} and {}, which the file does not both have",
                        j.id, c.incoming, c.connecting
                    ),
                ));
            };
            let cs = if c.contact == Contact::Start { 0 } else { net.roads[con].sections.len() - 1 };
            // The incoming road touches the junction at whichever end links to it.
            let inc_road: &OdRoad = &net.roads[inc];
            let touches = |l: &Option<Link>| matches!(l, Some(Link::Junction { id, .. }) if *id == j.id);
            let mut ends = Vec::new();
            if touches(&inc_road.predecessor) {
                ends.push(0);
            }
            if touches(&inc_road.successor) {
                ends.push(inc_road.sections.len() - 1);
            }
            if ends.is_empty() {
                ends = vec![0, inc_road.sections.len() - 1];
            }
            for &(from, to) in &c.lane_links {
                for &e in &ends {
                    add(lane_at.get(&(inc, e, from)), lane_at.get(&(con, cs, to)));
                }
            }
        }
    }
    let mut next: Vec<Vec<usize>> = vec![Vec::new(); od_lanes.len()];
    for (a, b) in pairs {
        let meets = |x: &OdLane, y: &OdLane| {
            x.path.end().distance(y.path.start()) < JOIN_TOLERANCE
                && crate::math::wrap_angle(x.path.heading_at(x.path.length()) - y.path.heading_at(0.0)).abs() < JOIN_HEADING
        };
        let (la, lb) = (&od_lanes[a], &od_lanes[b]);
        if meets(la, lb) {
            next[a].push(b);
        } else if meets(lb, la) {
            next[b].push(a);
        } else {
            let gap = la.path.end().distance(lb.path.start()).min(lb.path.end().distance(la.path.start()));
            let (ra, rb) = (&net.roads[la.road], &net.roads[lb.road]);
            warnings.push(
                "link",
                ra.pos.line,
                format!(
                    "road {} lane {} and road {} lane {} are linked but do not meet ({gap:.2} m apart); not joined",
                    ra.id, la.id, rb.id, lb.id
                ),
            );
        }
    }

    // Map roads: one per section of an ordinary road that has drivable lanes.
    let mut roads: Vec<Road> = Vec::new();
    let mut lanes: Vec<Lane> = Vec::new();
    let mut map_lane: Vec<Option<LaneId>> = vec![None; od_lanes.len()];
    for (ri, r) in net.roads.iter().enumerate() {
        if r.junction.is_some() {
            continue;
        }
        for (k, smp) in sampled[ri].iter().enumerate() {
            let mut mine: Vec<usize> = (0..od_lanes.len()).filter(|&l| od_lanes[l].road == ri && od_lanes[l].section == k).collect();
            if mine.is_empty() {
                continue;
            }
            mine.sort_by_key(|&l| od_lanes[l].id.abs());
            let road_id = roads.len();
            let (mut forward, mut backward) = (Vec::new(), Vec::new());
            let mut od_id: BTreeMap<LaneId, i32> = BTreeMap::new();
            for &l in &mine {
                let od = &od_lanes[l];
                let fwd = od.id < 0;
                let group: &mut Vec<LaneId> = if fwd { &mut forward } else { &mut backward };
                map_lane[l] = Some(lanes.len());
                od_id.insert(lanes.len(), od.id);
                lanes.push(Lane {
                    kind: LaneKind::Road { road: road_id, forward: fwd, index: group.len() },
                    path: od.path.clone(),
                    width: od.width,
                    speed_limit: od.speed,
                    successors: Vec::new(),
                    left: None,
                    right: None,
                    ends_at_junction: None,
                });
                group.push(lanes.len() - 1);
            }
            // Neighbours: lanes whose ids are adjacent (lane changes across a gap are not made).
            for group in [&forward, &backward] {
                for w in group.windows(2) {
                    if (od_id[&w[0]].abs() - od_id[&w[1]].abs()).abs() == 1 {
                        lanes[w[0]].right = Some(w[1]);
                        lanes[w[1]].left = Some(w[0]);
                    }
                }
            }
            let centre_pts: Vec<Vec2> = (0..smp.stations.len()).map(|i| smp.point(i, smp.offset[i])).collect();
            let centre =
                Polyline::new(centre_pts).unwrap_or_else(|| lanes[forward.first().or(backward.first()).copied().unwrap_or(0)].path.clone());
            let all: Vec<LaneId> = forward.iter().chain(&backward).copied().collect();
            let lane_width = all.iter().map(|&l| lanes[l].width).sum::<f32>() / all.len() as f32;
            let name = if r.sections.len() == 1 { r.id.clone() } else { format!("{}:{k}", r.id) };
            let speed_limit = r.speed.map_or(DEFAULT_SPEED, |v| v as f32);
            roads.push(Road {
                name,
                centre,
                lane_width,
                shoulder: 0.0,
                sidewalk: 0.0,
                speed_limit,
                forward,
                backward,
                cut_start: 0.0,
                cut_end: 0.0,
            });
        }
    }

    // Successors: road lane → road lane directly; road lane → chains through junction lanes →
    // road lane as one connector.
    let junction_index: BTreeMap<&str, usize> = net.junctions.iter().enumerate().map(|(i, j)| (j.id.as_str(), i)).collect();
    let mut connectors_of: Vec<Vec<LaneId>> = vec![Vec::new(); net.junctions.len()];
    for a in 0..od_lanes.len() {
        let Some(from) = map_lane[a] else { continue };
        let mut stack: Vec<Vec<usize>> = next[a].iter().map(|&b| vec![b]).collect();
        while let Some(chain) = stack.pop() {
            let last = *chain.last().expect("chains are not empty");
            if !od_lanes[last].in_junction {
                if chain.len() == 1 {
                    let to = map_lane[last].expect("ordinary lanes are map lanes");
                    if !lanes[from].successors.contains(&to) {
                        lanes[from].successors.push(to);
                    }
                    continue;
                }
                let to = map_lane[last].expect("ordinary lanes are map lanes");
                let inner = &chain[..chain.len() - 1];
                let od_junction = net.roads[od_lanes[inner[0]].road].junction.as_deref().unwrap_or("");
                let Some(&jid) = junction_index.get(od_junction) else {
                    let r = &net.roads[od_lanes[inner[0]].road];
                    warnings.push(
                        "junction",
                        r.pos.line,
                        format!("road {} is in junction {od_junction}, which the file does not have", r.id),
                    );
                    continue;
                };
                let mut pts: Vec<Vec2> = Vec::new();
                for &l in inner {
                    pts.extend_from_slice(od_lanes[l].path.points());
                }
                let Some(path) = Polyline::new(pts) else { continue };
                let delta = crate::math::wrap_angle(path.heading_at(path.length()) - path.heading_at(0.0));
                let turn = if delta.abs() < 35f32.to_radians() {
                    Turn::Straight
                } else if delta > 0.0 {
                    Turn::Left
                } else {
                    Turn::Right
                };
                let speed = inner.iter().map(|&l| od_lanes[l].speed).fold(lanes[from].speed_limit.min(lanes[to].speed_limit), f32::min);
                let width = inner.iter().map(|&l| od_lanes[l].width).sum::<f32>() / inner.len() as f32;
                connectors_of[jid].push(add_connector(&mut lanes, jid, (from, to), turn, path, width, speed));
            } else if chain.len() < MAX_CHAIN {
                for &b in &next[last] {
                    if !chain.contains(&b) {
                        let mut longer = chain.clone();
                        longer.push(b);
                        stack.push(longer);
                    }
                }
            }
        }
    }
    // Map junction ids must be dense: renumber the junctions that have connectors.
    let mut junctions: Vec<Junction> = Vec::new();
    let mut renumber: Vec<Option<usize>> = vec![None; net.junctions.len()];
    for (j, connectors) in connectors_of.iter().enumerate() {
        if connectors.is_empty() {
            continue;
        }
        renumber[j] = Some(junctions.len());
        let edge_pts: Vec<Vec2> = connectors
            .iter()
            .flat_map(|&c| {
                let lane = &lanes[c];
                let pts = lane.path.points();
                let w = lane.width / 2.0;
                pts.iter().enumerate().flat_map(move |(i, &p)| {
                    let t = pts[(i + 1).min(pts.len() - 1)] - pts[i.saturating_sub(1)];
                    let n = crate::math::left_normal(t.normalize_or(Vec2::X));
                    [p + n * w, p - n * w]
                })
            })
            .collect();
        let centre = edge_pts.iter().fold(Vec2::ZERO, |a, &b| a + b) / edge_pts.len().max(1) as f32;
        let conflicts = conflict_sets(&lanes, connectors);
        junctions.push(Junction { centre, outline: convex_hull(edge_pts), connectors: connectors.clone(), conflicts });
    }
    for lane in &mut lanes {
        if let LaneKind::Connector { junction, .. } = &mut lane.kind {
            *junction = renumber[*junction].expect("a connector's junction has connectors");
        }
        lane.ends_at_junction = lane.ends_at_junction.and_then(|j| renumber[j]);
    }
    if lanes.is_empty() {
        return Err(OpenDriveError::whole("the file has no driving lanes (lanes of type `driving`) of positive width"));
    }
    let surface = paint(&net, &sampled, &junctions)?;
    Ok(Map { name: net.name, roads, lanes, junctions, obstacles: Vec::new(), overpasses: Vec::new(), surface, warnings: warnings.finish() })
}

/// Width of painted lines, metres.
const LINE_WIDTH: f64 = 0.15;
/// Dashed lines: painted and gap lengths, metres.
const DASH: (f64, f64) = (3.0, 6.0);

/// Paints every lane of every section into a raster over the whole network: edges first, then
/// the junctions' outlines, shoulders, then driving lanes (junction lanes as the junction), then the lane lines.
fn paint(net: &Network, sampled: &[Vec<SampledSection>], junctions: &[Junction]) -> Result<SurfaceRaster, OpenDriveError> {
    let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for secs in sampled {
        for smp in secs {
            for lane in &smp.lanes {
                for i in 0..smp.stations.len() {
                    let p = smp.point(i, lane.outer[i]);
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
            for i in 0..smp.stations.len() {
                let p = smp.point(i, smp.offset[i]);
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
    }
    let margin = 30.0;
    let (w, h) = (f64::from(hi.x - lo.x) + 2.0 * margin, f64::from(hi.y - lo.y) + 2.0 * margin);
    let cells = (w / f64::from(RASTER_CELL)).ceil() * (h / f64::from(RASTER_CELL)).ceil();
    if cells.is_nan() || cells > MAX_RASTER_CELLS {
        return Err(OpenDriveError::whole(format!(
            "the road network spans {w:.0} m × {h:.0} m (with margins); the simulator's maps must fit in 4 km² (e.g. 2 km × 2 km)"
        )));
    }
    let mut raster = SurfaceRaster::new(lo - Vec2::splat(margin as f32), hi + Vec2::splat(margin as f32), RASTER_CELL);
    for pass in [Surface::Sidewalk, Surface::Shoulder, Surface::Road] {
        if pass == Surface::Shoulder {
            // A junction is paved between its connectors (as the text format's junctions are):
            // a vehicle cutting a corner stays on the road.
            for j in junctions {
                raster.fill_convex(&j.outline, Surface::Junction);
            }
        }
        for (r, secs) in net.roads.iter().zip(sampled) {
            for (sec, smp) in r.sections.iter().zip(secs) {
                for (lane, sl) in sec.lanes.iter().zip(&smp.lanes) {
                    if surface_of(&lane.kind) != Some(pass) {
                        continue;
                    }
                    let kind = if pass == Surface::Road && r.junction.is_some() { Surface::Junction } else { pass };
                    for i in 1..smp.stations.len() {
                        let quad = [
                            smp.point(i - 1, sl.inner[i - 1]),
                            smp.point(i, sl.inner[i]),
                            smp.point(i, sl.outer[i]),
                            smp.point(i - 1, sl.outer[i - 1]),
                        ];
                        raster.fill_convex(&quad, kind);
                    }
                }
            }
        }
    }
    for (r, secs) in net.roads.iter().zip(sampled) {
        if r.junction.is_some() {
            continue;
        }
        for (sec, smp) in r.sections.iter().zip(secs) {
            let driving = |id: i32| sec.lanes.iter().any(|l| l.id == id && is_driving(&l.kind));
            let mut lines: Vec<(Vec<f64>, Surface, bool)> = Vec::new();
            if driving(1) && driving(-1) {
                lines.push((smp.offset.clone(), Surface::YellowLine, false));
            }
            for (lane, sl) in sec.lanes.iter().zip(&smp.lanes) {
                let further = if lane.id > 0 { lane.id + 1 } else { lane.id - 1 };
                if is_driving(&lane.kind) && driving(further) {
                    lines.push((sl.outer.clone(), Surface::WhiteLine, true));
                }
            }
            for (t, kind, dashed) in lines {
                for i in 1..smp.stations.len() {
                    let phase = (smp.stations[i - 1] - sec.s).rem_euclid(DASH.0 + DASH.1);
                    if dashed && phase > DASH.0 {
                        continue;
                    }
                    let hw = LINE_WIDTH;
                    let quad = [
                        smp.point(i - 1, t[i - 1] - hw),
                        smp.point(i, t[i] - hw),
                        smp.point(i, t[i] + hw),
                        smp.point(i - 1, t[i - 1] + hw),
                    ];
                    raster.fill_convex(&quad, kind);
                }
            }
        }
    }
    raster.build_levels(RASTER_LEVELS);
    Ok(raster)
}
