//! OpenDRIVE XML → typed records (`Network`), checked: every number finite, every length and
//! width non-negative, every required attribute present. Errors carry the element's line and
//! column; nothing here panics, whatever the input.

use roxmltree::{Document, Node};

use super::error::OpenDriveError;
use super::geometry::{Cubic, Geometry, Pose, Shape};
use crate::map::MapWarning;

/// Larger files are refused before parsing (Town01 is 1 MB).
pub const MAX_BYTES: usize = 64 << 20;
/// More roads than this are refused.
pub const MAX_ROADS: usize = 20_000;
/// Roads longer than this are refused, metres (the simulator's maps fit in 2 km × 2 km).
pub const MAX_ROAD_LENGTH: f64 = 10_000.0;
/// Coordinates farther from the origin than this are refused, metres.
pub const MAX_COORDINATE: f64 = 1.0e6;
/// Curvatures beyond this are refused, 1/m: no road bends tighter than a 1 m radius (Town01's
/// tightest is 0.24), and a spiral's integration cost grows with its curvature.
pub const MAX_CURVATURE: f64 = 1.0;
/// Geometry pieces shorter than this are skipped (exporters write slivers of 1e-10 m).
const MIN_PIECE: f64 = 1e-6;

/// Where an element starts in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Pos {
    pub line: u32,
    pub column: u32,
}

/// Which end of a road a link touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Contact {
    Start,
    End,
}

/// A road's `predecessor` or `successor`.
#[derive(Debug, Clone, PartialEq)]
pub enum Link {
    Road { id: String, contact: Contact, pos: Pos },
    Junction { id: String, pos: Pos },
}

/// One `<lane>` of a lane section.
#[derive(Debug, Clone, PartialEq)]
pub struct Lane {
    /// Positive on the left of the reference line, negative on the right (0, the centre, is not
    /// kept).
    pub id: i32,
    pub kind: String,
    /// Width records with `s` relative to the section's start.
    pub widths: Vec<Cubic>,
    pub predecessor: Option<i32>,
    pub successor: Option<i32>,
    pub pos: Pos,
}

/// One `<laneSection>`.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    pub s: f64,
    /// Left lanes by increasing id, then right lanes by decreasing id (1, 2, …, -1, -2, …).
    pub lanes: Vec<Lane>,
    pub pos: Pos,
}

/// One `<road>`.
#[derive(Debug, Clone, PartialEq)]
pub struct Road {
    pub id: String,
    pub length: f64,
    /// The junction this road is a connecting road of, if any.
    pub junction: Option<String>,
    pub predecessor: Option<Link>,
    pub successor: Option<Link>,
    /// The first `<type><speed>`, m/s.
    pub speed: Option<f64>,
    pub geometry: Vec<Geometry>,
    pub lane_offset: Vec<Cubic>,
    pub sections: Vec<Section>,
    pub pos: Pos,
}

/// One junction `<connection>`.
#[derive(Debug, Clone, PartialEq)]
pub struct Connection {
    pub incoming: String,
    pub connecting: String,
    pub contact: Contact,
    /// (lane of the incoming road, lane of the connecting road).
    pub lane_links: Vec<(i32, i32)>,
    pub pos: Pos,
}

/// One `<junction>`.
#[derive(Debug, Clone, PartialEq)]
pub struct Junction {
    pub id: String,
    pub connections: Vec<Connection>,
    pub pos: Pos,
}

/// The records of a whole file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Network {
    pub name: String,
    pub roads: Vec<Road>,
    pub junctions: Vec<Junction>,
    pub warnings: Vec<MapWarning>,
}

struct Reader<'a, 'input> {
    doc: &'a Document<'input>,
    /// Byte offset of each line's start: positions by binary search (roxmltree's `text_pos_at`
    /// scans from the file's start on every call).
    line_starts: Vec<usize>,
    warnings: Vec<MapWarning>,
}

impl<'input> Reader<'_, 'input> {
    fn pos(&self, n: Node<'_, 'input>) -> Pos {
        let at = n.range().start;
        let line = self.line_starts.partition_point(|&s| s <= at).max(1);
        let start = self.line_starts[line - 1];
        let column = self.doc.input_text().get(start..at).map_or(0, |t| t.chars().count()) + 1;
        Pos { line: u32::try_from(line).unwrap_or(u32::MAX), column: u32::try_from(column).unwrap_or(u32::MAX) }
    }

    fn err(&self, n: Node<'_, 'input>, message: impl Into<String>) -> OpenDriveError {
        let p = self.pos(n);
        OpenDriveError::at(p.line, p.column, message)
    }

    fn warn(&mut self, n: Node<'_, 'input>, message: impl Into<String>) {
        let line = self.pos(n).line as usize;
        self.warnings.push(MapWarning { line, field: n.tag_name().name().to_owned(), message: message.into() });
    }

    fn text<'n>(&self, n: Node<'n, 'input>, attr: &str, ctx: &str) -> Result<&'n str, OpenDriveError> {
        n.attribute(attr).ok_or_else(|| self.err(n, format!("{ctx}: <{}> lacks the required attribute `{attr}`", n.tag_name().name())))
    }

    fn number(&self, n: Node<'_, 'input>, attr: &str, ctx: &str) -> Result<f64, OpenDriveError> {
        let raw = self.text(n, attr, ctx)?;
        self.parse_number(n, attr, raw, ctx)
    }

    fn number_or(&self, n: Node<'_, 'input>, attr: &str, default: f64, ctx: &str) -> Result<f64, OpenDriveError> {
        match n.attribute(attr) {
            None => Ok(default),
            Some(raw) => self.parse_number(n, attr, raw, ctx),
        }
    }

    fn parse_number(&self, n: Node<'_, 'input>, attr: &str, raw: &str, ctx: &str) -> Result<f64, OpenDriveError> {
        match raw.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.err(n, format!("{ctx}: <{}> attribute `{attr}` is `{raw}`; expected a finite number", n.tag_name().name()))),
        }
    }

    fn integer(&self, n: Node<'_, 'input>, attr: &str, ctx: &str) -> Result<i32, OpenDriveError> {
        let raw = self.text(n, attr, ctx)?;
        raw.trim()
            .parse::<i32>()
            .map_err(|_| self.err(n, format!("{ctx}: <{}> attribute `{attr}` is `{raw}`; expected an integer", n.tag_name().name())))
    }

    fn cubic(&self, n: Node<'_, 'input>, s_attr: &str, ctx: &str) -> Result<Cubic, OpenDriveError> {
        let s = self.number(n, s_attr, ctx)?;
        if s < 0.0 {
            return Err(self.err(n, format!("{ctx}: <{}> attribute `{s_attr}` is {s}; expected ≥ 0", n.tag_name().name())));
        }
        let mut coefficients = [0.0; 4];
        for (c, name) in coefficients.iter_mut().zip(["a", "b", "c", "d"]) {
            *c = self.number(n, name, ctx)?;
        }
        Ok(Cubic { s, coefficients })
    }

    fn contact(&self, n: Node<'_, 'input>, ctx: &str) -> Result<Contact, OpenDriveError> {
        match self.text(n, "contactPoint", ctx)? {
            "start" => Ok(Contact::Start),
            "end" => Ok(Contact::End),
            other => Err(self.err(n, format!("{ctx}: contactPoint is `{other}`; expected `start` or `end`"))),
        }
    }
}

fn children<'a, 'input>(n: Node<'a, 'input>, tag: &'a str) -> impl Iterator<Item = Node<'a, 'input>> + 'a {
    n.children().filter(move |c| c.is_element() && c.tag_name().name() == tag)
}

fn child<'a, 'input>(n: Node<'a, 'input>, tag: &'a str) -> Option<Node<'a, 'input>> {
    children(n, tag).next()
}

/// Parses an OpenDRIVE document. Never panics.
pub fn parse(xml: &str) -> Result<Network, OpenDriveError> {
    if xml.len() > MAX_BYTES {
        return Err(OpenDriveError::whole(format!(
            "the file is {} MB; the importer reads files up to {} MB (Town01 is 1 MB)",
            xml.len() >> 20,
            MAX_BYTES >> 20
        )));
    }
    let options = roxmltree::ParsingOptions { allow_dtd: true, ..roxmltree::ParsingOptions::default() };
    let doc = Document::parse_with_options(xml, options).map_err(|e| {
        let p = e.pos();
        OpenDriveError::at(p.row, p.col, format!("malformed XML: {e}"))
    })?;
    let root = doc.root_element();
    let line_starts = std::iter::once(0).chain(xml.match_indices('\n').map(|(i, _)| i + 1)).collect();
    let mut r = Reader { doc: &doc, line_starts, warnings: Vec::new() };
    if root.tag_name().name() != "OpenDRIVE" {
        return Err(r.err(root, format!("the root element is <{}>; expected <OpenDRIVE>", root.tag_name().name())));
    }
    let name = child(root, "header").and_then(|h| h.attribute("name")).filter(|n| !n.is_empty()).unwrap_or("opendrive").to_owned();
    let road_nodes: Vec<Node<'_, '_>> = children(root, "road").collect();
    if road_nodes.len() > MAX_ROADS {
        return Err(OpenDriveError::whole(format!("the file has {} roads; the importer reads up to {MAX_ROADS}", road_nodes.len())));
    }
    let mut roads = Vec::with_capacity(road_nodes.len());
    for n in road_nodes {
        roads.push(road(&mut r, n)?);
    }
    let mut junctions = Vec::new();
    for n in children(root, "junction") {
        junctions.push(junction(&r, n)?);
    }
    let (mut objects, mut signals) = (0usize, 0usize);
    for n in root.descendants().filter(Node::is_element) {
        match n.tag_name().name() {
            "object" => objects += 1,
            "signal" => signals += 1,
            _ => {}
        }
    }
    if objects + signals > 0 {
        r.warnings.push(MapWarning {
            line: 0,
            field: "objects/signals".into(),
            message: format!("{objects} objects and {signals} signals ignored (no static obstacles or traffic lights are imported)"),
        });
    }
    Ok(Network { name, roads, junctions, warnings: r.warnings })
}

fn road<'input>(r: &mut Reader<'_, 'input>, n: Node<'_, 'input>) -> Result<Road, OpenDriveError> {
    let id = r.text(n, "id", "a road")?.to_owned();
    let ctx = format!("road {id}");
    let length = r.number(n, "length", &ctx)?;
    if length <= 0.0 || length > MAX_ROAD_LENGTH {
        return Err(r.err(n, format!("{ctx}: length is {length}; expected a positive length in metres, at most {MAX_ROAD_LENGTH}")));
    }
    let junction = n.attribute("junction").filter(|j| *j != "-1" && !j.is_empty()).map(str::to_owned);
    let (mut predecessor, mut successor) = (None, None);
    if let Some(link) = child(n, "link") {
        predecessor = child(link, "predecessor").map(|l| road_link(r, l, &ctx)).transpose()?;
        successor = child(link, "successor").map(|l| road_link(r, l, &ctx)).transpose()?;
    }
    let mut speed = None;
    if let Some(s) = children(n, "type").find_map(|t| child(t, "speed")) {
        let max = r.number(s, "max", &ctx)?;
        let factor = match s.attribute("unit").unwrap_or("m/s") {
            "mph" => 0.447_04,
            "km/h" => 1.0 / 3.6,
            "m/s" => 1.0,
            other => return Err(r.err(s, format!("{ctx}: speed unit `{other}`; expected `m/s`, `km/h` or `mph`"))),
        };
        if max <= 0.0 {
            r.warn(s, format!("{ctx}: speed limit {max} ignored (not positive)"));
        } else {
            speed = Some(max * factor);
        }
    }
    let plan = child(n, "planView").ok_or_else(|| r.err(n, format!("{ctx}: no <planView>")))?;
    let mut geometry = Vec::new();
    for g in children(plan, "geometry") {
        let s = r.number(g, "s", &ctx)?;
        let start = Pose { x: r.number(g, "x", &ctx)?, y: r.number(g, "y", &ctx)?, hdg: r.number(g, "hdg", &ctx)? };
        if start.x.abs().max(start.y.abs()) > MAX_COORDINATE {
            return Err(
                r.err(g, format!("{ctx}: geometry starts at ({}, {}); coordinates must be within ±{MAX_COORDINATE} m", start.x, start.y))
            );
        }
        let len = r.number(g, "length", &ctx)?;
        if len < 0.0 {
            return Err(r.err(g, format!("{ctx}: geometry length is {len}; expected ≥ 0")));
        }
        let shape_node = g.children().find(Node::is_element).ok_or_else(|| r.err(g, format!("{ctx}: <geometry> holds no shape")))?;
        let shape = match shape_node.tag_name().name() {
            "line" => Shape::Line,
            "arc" => Shape::Arc { curvature: r.number(shape_node, "curvature", &ctx)? },
            "spiral" => Shape::Spiral { start: r.number(shape_node, "curvStart", &ctx)?, end: r.number(shape_node, "curvEnd", &ctx)? },
            "poly3" => {
                let c = |a| r.number(shape_node, a, &ctx);
                Shape::Poly3 { a: c("a")?, b: c("b")?, c: c("c")?, d: c("d")? }
            }
            "paramPoly3" => {
                let c = |a| r.number(shape_node, a, &ctx);
                let normalized = match shape_node.attribute("pRange").unwrap_or("normalized") {
                    "normalized" => true,
                    "arcLength" => false,
                    other => return Err(r.err(shape_node, format!("{ctx}: pRange `{other}`; expected `arcLength` or `normalized`"))),
                };
                Shape::ParamPoly3 { u: [c("aU")?, c("bU")?, c("cU")?, c("dU")?], v: [c("aV")?, c("bV")?, c("cV")?, c("dV")?], normalized }
            }
            other => {
                return Err(
                    r.err(shape_node, format!("{ctx}: unknown geometry <{other}>; expected line, arc, spiral, poly3 or paramPoly3"))
                );
            }
        };
        let curvatures: &[(&str, f64)] = match shape {
            Shape::Arc { curvature } => &[("curvature", curvature)],
            Shape::Spiral { start, end } => &[("curvStart", start), ("curvEnd", end)],
            _ => &[],
        };
        if let Some((attr, k)) = curvatures.iter().find(|(_, k)| k.abs() > MAX_CURVATURE) {
            return Err(r.err(
                shape_node,
                format!(
                    "{ctx}: <{}> `{attr}` is {k} 1/m; expected within ±{MAX_CURVATURE} (a radius of at least 1 m)",
                    shape_node.tag_name().name()
                ),
            ));
        }
        if len < MIN_PIECE {
            continue;
        }
        if let Some(prev) = geometry.last().map(|p: &Geometry| p.s)
            && s < prev
        {
            return Err(r.err(g, format!("{ctx}: geometry starts at s = {s}, before the previous piece (s = {prev})")));
        }
        geometry.push(Geometry { s, start, length: len, shape });
    }
    if geometry.is_empty() {
        return Err(r.err(plan, format!("{ctx}: <planView> has no geometry of positive length")));
    }
    let covered: f64 = geometry.last().map_or(0.0, |g| g.s + g.length);
    if (covered - length).abs() > 0.01 {
        r.warn(plan, format!("{ctx}: the geometry ends at s = {covered:.3} but the road is {length:.3} m long"));
    }
    for (tag, what) in [("elevationProfile", "elevation"), ("lateralProfile", "superelevation")] {
        if let Some(p) = child(n, tag) {
            let nonzero =
                children(p, what).any(|e| ["a", "b", "c", "d"].iter().any(|a| r.number_or(e, a, 0.0, &ctx).is_ok_and(|v| v != 0.0)));
            if nonzero {
                r.warn(p, format!("{ctx}: non-zero {what} ignored (the simulator is flat)"));
            }
        }
    }
    let lanes = child(n, "lanes").ok_or_else(|| r.err(n, format!("{ctx}: no <lanes>")))?;
    let mut lane_offset = Vec::new();
    for o in children(lanes, "laneOffset") {
        lane_offset.push(r.cubic(o, "s", &ctx)?);
    }
    lane_offset.sort_by(|a, b| a.s.total_cmp(&b.s));
    let mut sections = Vec::new();
    for sec in children(lanes, "laneSection") {
        let s = r.number(sec, "s", &ctx)?;
        if let Some(prev) = sections.last().map(|p: &Section| p.s)
            && s < prev
        {
            return Err(r.err(sec, format!("{ctx}: laneSection starts at s = {s}, before the previous one (s = {prev})")));
        }
        let mut lanes = Vec::new();
        for side in ["left", "right"] {
            let Some(side_node) = child(sec, side) else { continue };
            let mut side_lanes = Vec::new();
            for l in children(side_node, "lane") {
                side_lanes.push(lane(r, l, &ctx, side == "left")?);
            }
            side_lanes.sort_by_key(|l| l.id.abs());
            for w in side_lanes.windows(2) {
                if w[0].id == w[1].id {
                    return Err(r.err(n, format!("{ctx}: two lanes with id {} in the laneSection at s = {s}", w[0].id)));
                }
            }
            lanes.extend(side_lanes);
        }
        sections.push(Section { s, lanes, pos: r.pos(sec) });
    }
    if sections.is_empty() {
        return Err(r.err(lanes, format!("{ctx}: <lanes> has no <laneSection>")));
    }
    // Sections that start at or beyond the road's end hold nothing.
    let first_s = sections[0].s;
    sections.retain(|sec| sec.s < length - 1e-6 || sec.s == first_s);
    Ok(Road { id, length, junction, predecessor, successor, speed, geometry, lane_offset, sections, pos: r.pos(n) })
}

fn lane<'input>(r: &mut Reader<'_, 'input>, n: Node<'_, 'input>, ctx: &str, left: bool) -> Result<Lane, OpenDriveError> {
    let id = r.integer(n, "id", ctx)?;
    if id == 0 || (id > 0) != left {
        return Err(r.err(
            n,
            format!(
                "{ctx}: lane id {id} on the {} side; left lanes have positive ids, right lanes negative",
                if left { "left" } else { "right" }
            ),
        ));
    }
    let ctx = format!("{ctx}, lane {id}");
    let kind = n.attribute("type").unwrap_or("none").to_owned();
    if child(n, "border").is_some() && child(n, "width").is_none() {
        return Err(r.err(n, format!("{ctx}: lane given by <border> records; the importer reads <width> records only")));
    }
    let mut widths = Vec::new();
    for w in children(n, "width") {
        let c = r.cubic(w, "sOffset", &ctx)?;
        if c.coefficients[0] < 0.0 {
            return Err(r.err(w, format!("{ctx}: width starts at {} m; expected ≥ 0", c.coefficients[0])));
        }
        widths.push(c);
    }
    widths.sort_by(|a, b| a.s.total_cmp(&b.s));
    let (mut predecessor, mut successor) = (None, None);
    if let Some(link) = child(n, "link") {
        predecessor = child(link, "predecessor").map(|p| r.integer(p, "id", &ctx)).transpose()?;
        successor = child(link, "successor").map(|p| r.integer(p, "id", &ctx)).transpose()?;
    }
    Ok(Lane { id, kind, widths, predecessor, successor, pos: r.pos(n) })
}

fn road_link<'input>(r: &Reader<'_, 'input>, n: Node<'_, 'input>, ctx: &str) -> Result<Link, OpenDriveError> {
    let id = r.text(n, "elementId", ctx)?.to_owned();
    match r.text(n, "elementType", ctx)? {
        "road" => Ok(Link::Road { id, contact: r.contact(n, ctx)?, pos: r.pos(n) }),
        "junction" => Ok(Link::Junction { id, pos: r.pos(n) }),
        other => Err(r.err(n, format!("{ctx}: link elementType `{other}`; expected `road` or `junction`"))),
    }
}

fn junction<'input>(r: &Reader<'_, 'input>, n: Node<'_, 'input>) -> Result<Junction, OpenDriveError> {
    let id = r.text(n, "id", "a junction")?.to_owned();
    let ctx = format!("junction {id}");
    let mut connections = Vec::new();
    for c in children(n, "connection") {
        let incoming = r.text(c, "incomingRoad", &ctx)?.to_owned();
        let connecting = r.text(c, "connectingRoad", &ctx)?.to_owned();
        let contact = r.contact(c, &ctx)?;
        let mut lane_links = Vec::new();
        for l in children(c, "laneLink") {
            lane_links.push((r.integer(l, "from", &ctx)?, r.integer(l, "to", &ctx)?));
        }
        connections.push(Connection { incoming, connecting, contact, lane_links, pos: r.pos(c) });
    }
    Ok(Junction { id, connections, pos: r.pos(n) })
}
