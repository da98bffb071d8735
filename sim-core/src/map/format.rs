//! The map text format: parsing into plain [`MapSpec`] data. Geometry is built elsewhere
//! (`build.rs`); this file only reads, checks each value, and reports errors by line and field.
//!
//! The format is documented for users in `docs/MAP-FORMAT.md`. In short: one statement per line,
//! `#` starts a comment, a statement is a keyword followed by `key=value` fields:
//!
//! ```text
//! node E x=100 y=100
//! road main from=D heading=0 to=E lanes=1,1 shoulder=2.5
//!   straight length=100
//!   arc radius=40 angle=-90
//! end
//! building x=50 y=30 width=40 depth=20 height=15
//! ```

use std::collections::HashMap;
use std::fmt;

/// A map file's contents, checked value by value but not yet turned into geometry.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MapSpec {
    /// Name given by the `map` statement (default "unnamed").
    pub name: String,
    /// Named points where roads start, end and meet.
    pub nodes: Vec<NodeSpec>,
    /// Roads, each a centre line of pieces.
    pub roads: Vec<RoadSpec>,
    /// Box-shaped buildings.
    pub buildings: Vec<BuildingSpec>,
    /// Round poles (lamps, signs).
    pub poles: Vec<PoleSpec>,
    /// Overpass decks; their pillars are obstacles, the deck is above the traffic.
    pub overpasses: Vec<OverpassSpec>,
    /// Values that load but are unlikely to be meant (see [`PLAUSIBLE_LANE_WIDTH`],
    /// [`PLAUSIBLE_SPEED_KMH`]), one per line and field that set them.
    pub warnings: Vec<MapWarning>,
}

/// Lane widths, metres, that real roads have (with room on both sides: lanes are 2.7–3.7 m wide
/// on most roads). Wider or narrower ones load, with a warning.
pub const PLAUSIBLE_LANE_WIDTH: std::ops::RangeInclusive<f32> = 2.5..=5.0;
/// Speed limits, km/h, that real roads have. Others load, with a warning (a limit given in m/s by
/// mistake, 13.9 for 50 km/h, is the usual cause).
pub const PLAUSIBLE_SPEED_KMH: std::ops::RangeInclusive<f32> = 10.0..=130.0;

/// A value that loads but is unlikely to be what the map's author meant: the line and field that
/// set it, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct MapWarning {
    pub line: usize,
    pub field: String,
    pub message: String,
}

impl fmt::Display for MapWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "map line {}, field `{}`: {}", self.line, self.field, self.message)
    }
}

/// `node NAME x=.. y=..`
#[derive(Debug, Clone, PartialEq)]
pub struct NodeSpec {
    pub name: String,
    pub x: f32,
    pub y: f32,
    pub line: usize,
}

/// `road NAME from=NODE heading=DEG to=NODE lanes=F,B ...` followed by pieces and `end`.
#[derive(Debug, Clone, PartialEq)]
pub struct RoadSpec {
    pub name: String,
    pub from: String,
    pub to: String,
    /// Heading at the start, degrees counter-clockwise from +x (east).
    pub heading_deg: f32,
    /// Lanes travelling along the centre line (start → end), on its right.
    pub lanes_forward: u32,
    /// Lanes travelling against it (end → start), on its left.
    pub lanes_backward: u32,
    /// Metres, default 3.5.
    pub lane_width: f32,
    /// The line that set `lane_width`: this road's, a `defaults` line's, or 0 for the built-in
    /// default.
    pub lane_width_line: usize,
    /// Drivable (parking) strip beyond the outermost lane on each side, metres, default 0.
    pub shoulder: f32,
    /// Sidewalk beyond the shoulder on each side, metres (not drivable), default 3.
    pub sidewalk: f32,
    /// Speed limit for traffic, km/h, default 50.
    pub speed_kmh: f32,
    /// The line that set `speed_kmh` (as for `lane_width_line`).
    pub speed_line: usize,
    pub pieces: Vec<PieceSpec>,
    pub line: usize,
}

/// One piece of a road's centre line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PieceSpec {
    /// `straight length=M`
    Straight { length: f32 },
    /// `arc radius=M angle=DEG`; a positive angle turns left.
    Arc { radius: f32, angle_deg: f32 },
}

/// `building x=.. y=.. width=.. depth=.. [angle=DEG] [height=M]` (centre and size).
#[derive(Debug, Clone, PartialEq)]
pub struct BuildingSpec {
    pub x: f32,
    pub y: f32,
    pub width: f32,
    pub depth: f32,
    pub angle_deg: f32,
    pub height: f32,
    pub line: usize,
}

/// `pole x=.. y=.. [radius=0.2] [height=6]`
#[derive(Debug, Clone, PartialEq)]
pub struct PoleSpec {
    pub x: f32,
    pub y: f32,
    pub radius: f32,
    pub height: f32,
    pub line: usize,
}

/// `overpass x1=.. y1=.. x2=.. y2=.. width=.. [clearance=5] [thickness=1.2] [pillar=1.2]`: a deck
/// whose centre line runs from (x1,y1) to (x2,y2), with a square pillar at each of its four corners.
#[derive(Debug, Clone, PartialEq)]
pub struct OverpassSpec {
    pub x1: f32,
    pub y1: f32,
    pub x2: f32,
    pub y2: f32,
    pub width: f32,
    pub clearance: f32,
    pub thickness: f32,
    pub pillar: f32,
    pub line: usize,
}

/// A map that could not be read or built. The message names the line and, where there is one, the
/// field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct MapError {
    /// 1-based line number (0 when the problem is not tied to a line, e.g. an empty map).
    pub line: usize,
    /// The field at fault, if any.
    pub field: Option<String>,
    pub message: String,
}

impl fmt::Display for MapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.line, &self.field) {
            (0, _) => write!(f, "map: {}", self.message),
            (l, Some(field)) => write!(f, "map line {l}, field `{field}`: {}", self.message),
            (l, None) => write!(f, "map line {l}: {}", self.message),
        }
    }
}

impl MapError {
    pub(crate) fn at(line: usize, field: Option<&str>, message: impl Into<String>) -> Self {
        Self { line, field: field.map(str::to_owned), message: message.into() }
    }
}

/// Parses map text. Never panics, whatever the input.
pub fn parse(text: &str) -> Result<MapSpec, MapError> {
    let mut spec = MapSpec { name: "unnamed".into(), ..MapSpec::default() };
    let mut open_road: Option<RoadSpec> = None;
    let mut defaults = RoadDefaults::default();
    for (idx, raw) in text.lines().enumerate() {
        let line = idx + 1;
        let content = raw.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let mut words = content.split_whitespace();
        let keyword = words.next().unwrap_or("");
        let rest: Vec<&str> = words.collect();
        if let Some(road) = open_road.as_mut() {
            match keyword {
                "straight" => {
                    let f = Fields::parse(line, &rest, &["length"])?;
                    let length = f.positive("length")?;
                    road.pieces.push(PieceSpec::Straight { length });
                }
                "arc" => {
                    let f = Fields::parse(line, &rest, &["radius", "angle"])?;
                    let radius = f.positive("radius")?;
                    let angle_deg = f.number("angle")?;
                    if angle_deg == 0.0 || angle_deg.abs() > 270.0 {
                        return Err(f.bad("angle", format!("{angle_deg} must be non-zero and within ±270 degrees")));
                    }
                    road.pieces.push(PieceSpec::Arc { radius, angle_deg });
                }
                "end" => {
                    if !rest.is_empty() {
                        return Err(MapError::at(line, None, "`end` takes no fields"));
                    }
                    let road = open_road.take().expect("checked above");
                    if road.pieces.is_empty() {
                        return Err(MapError::at(
                            road.line,
                            None,
                            format!("road `{}` has no pieces: add `straight` or `arc` lines before `end`", road.name),
                        ));
                    }
                    spec.roads.push(road);
                }
                "map" | "defaults" | "node" | "road" | "building" | "pole" | "overpass" => {
                    // A forgotten `end`: the road's line is where the fix goes.
                    return Err(MapError::at(
                        road.line,
                        None,
                        format!("road `{}` is never closed with `end` (line {line} starts a `{keyword}` statement)", road.name),
                    ));
                }
                other => {
                    return Err(MapError::at(
                        line,
                        None,
                        format!("unknown statement `{other}` inside road `{}`: expected `straight`, `arc` or `end`", road.name),
                    ));
                }
            }
            continue;
        }
        match keyword {
            "map" => {
                let f = Fields::parse(line, &rest, &["name"])?;
                spec.name = f.text("name")?.to_owned();
            }
            "defaults" => {
                let f = Fields::parse(line, &rest, &["lane_width", "shoulder", "sidewalk", "speed"])?;
                defaults = RoadDefaults {
                    lane_width: f.positive_or("lane_width", defaults.lane_width)?,
                    lane_width_line: f.line_of("lane_width", defaults.lane_width_line),
                    shoulder: f.non_negative_or("shoulder", defaults.shoulder)?,
                    sidewalk: f.non_negative_or("sidewalk", defaults.sidewalk)?,
                    speed_kmh: f.positive_or("speed", defaults.speed_kmh)?,
                    speed_line: f.line_of("speed", defaults.speed_line),
                };
            }
            "node" => {
                let (name, rest) = split_name(line, "node", &rest)?;
                let f = Fields::parse(line, rest, &["x", "y"])?;
                if spec.nodes.iter().any(|n| n.name == name) {
                    return Err(MapError::at(line, Some("name"), format!("node `{name}` is defined twice")));
                }
                spec.nodes.push(NodeSpec { name: name.to_owned(), x: f.number("x")?, y: f.number("y")?, line });
            }
            "road" => {
                let (name, rest) = split_name(line, "road", &rest)?;
                let f = Fields::parse(line, rest, &["from", "to", "heading", "lanes", "lane_width", "shoulder", "sidewalk", "speed"])?;
                if spec.roads.iter().any(|r| r.name == name) {
                    return Err(MapError::at(line, Some("name"), format!("road `{name}` is defined twice")));
                }
                let (lanes_forward, lanes_backward) = f.lanes("lanes")?;
                open_road = Some(RoadSpec {
                    name: name.to_owned(),
                    from: f.text("from")?.to_owned(),
                    to: f.text("to")?.to_owned(),
                    heading_deg: f.number("heading")?,
                    lanes_forward,
                    lanes_backward,
                    lane_width: f.positive_or("lane_width", defaults.lane_width)?,
                    lane_width_line: f.line_of("lane_width", defaults.lane_width_line),
                    shoulder: f.non_negative_or("shoulder", defaults.shoulder)?,
                    sidewalk: f.non_negative_or("sidewalk", defaults.sidewalk)?,
                    speed_kmh: f.positive_or("speed", defaults.speed_kmh)?,
                    speed_line: f.line_of("speed", defaults.speed_line),
                    pieces: Vec::new(),
                    line,
                });
            }
            "building" => {
                let f = Fields::parse(line, &rest, &["x", "y", "width", "depth", "angle", "height"])?;
                spec.buildings.push(BuildingSpec {
                    x: f.number("x")?,
                    y: f.number("y")?,
                    width: f.positive("width")?,
                    depth: f.positive("depth")?,
                    angle_deg: f.number_or("angle", 0.0)?,
                    height: f.positive_or("height", 12.0)?,
                    line,
                });
            }
            "pole" => {
                let f = Fields::parse(line, &rest, &["x", "y", "radius", "height"])?;
                spec.poles.push(PoleSpec {
                    x: f.number("x")?,
                    y: f.number("y")?,
                    radius: f.positive_or("radius", 0.2)?,
                    height: f.positive_or("height", 6.0)?,
                    line,
                });
            }
            "overpass" => {
                let f = Fields::parse(line, &rest, &["x1", "y1", "x2", "y2", "width", "clearance", "thickness", "pillar"])?;
                let o = OverpassSpec {
                    x1: f.number("x1")?,
                    y1: f.number("y1")?,
                    x2: f.number("x2")?,
                    y2: f.number("y2")?,
                    width: f.positive("width")?,
                    clearance: f.positive_or("clearance", 5.0)?,
                    thickness: f.positive_or("thickness", 1.2)?,
                    pillar: f.positive_or("pillar", 1.2)?,
                    line,
                };
                if (o.x2 - o.x1).hypot(o.y2 - o.y1) < 1.0 {
                    return Err(f.bad("x2", "the deck's two ends must be at least 1 m apart"));
                }
                spec.overpasses.push(o);
            }
            "straight" | "arc" | "end" => {
                return Err(MapError::at(
                    line,
                    None,
                    format!("`{keyword}` outside a road: start one with `road NAME from=.. heading=.. to=.. lanes=..`"),
                ));
            }
            other => {
                return Err(MapError::at(
                    line,
                    None,
                    format!("unknown statement `{other}`: expected map, defaults, node, road, building, pole or overpass"),
                ));
            }
        }
    }
    if let Some(road) = open_road {
        return Err(MapError::at(road.line, None, format!("road `{}` is never closed with `end`", road.name)));
    }
    if spec.roads.is_empty() {
        return Err(MapError::at(0, None, "the map has no roads"));
    }
    spec.warnings = plausibility_warnings(&spec.roads);
    Ok(spec)
}

/// Warnings for roads' lane widths and speed limits outside what real roads have, each reported
/// once at the line that set it (a `defaults` line shared by many roads is one warning).
fn plausibility_warnings(roads: &[RoadSpec]) -> Vec<MapWarning> {
    let mut out: Vec<MapWarning> = Vec::new();
    let mut warn = |line: usize, field: &str, message: String| {
        if !out.iter().any(|w| w.line == line && w.field == field) {
            out.push(MapWarning { line, field: field.to_owned(), message });
        }
    };
    for r in roads {
        let (lo, hi) = (PLAUSIBLE_LANE_WIDTH.start(), PLAUSIBLE_LANE_WIDTH.end());
        if !PLAUSIBLE_LANE_WIDTH.contains(&r.lane_width) {
            warn(
                r.lane_width_line,
                "lane_width",
                format!(
                    "lane width {} m (road `{}`) is outside the plausible {lo}–{hi} m; it is in metres, and real lanes are 2.7–3.7 m",
                    r.lane_width, r.name
                ),
            );
        }
        let (lo, hi) = (PLAUSIBLE_SPEED_KMH.start(), PLAUSIBLE_SPEED_KMH.end());
        if !PLAUSIBLE_SPEED_KMH.contains(&r.speed_kmh) {
            warn(
                r.speed_line,
                "speed",
                format!(
                    "speed limit {} km/h (road `{}`) is outside the plausible {lo}–{hi} km/h; it is in km/h, not m/s",
                    r.speed_kmh, r.name
                ),
            );
        }
    }
    out.sort_by_key(|w| w.line);
    out
}

#[derive(Debug, Clone, Copy)]
struct RoadDefaults {
    lane_width: f32,
    lane_width_line: usize,
    shoulder: f32,
    sidewalk: f32,
    speed_kmh: f32,
    speed_line: usize,
}

impl Default for RoadDefaults {
    fn default() -> Self {
        Self { lane_width: 3.5, lane_width_line: 0, shoulder: 0.0, sidewalk: 3.0, speed_kmh: 50.0, speed_line: 0 }
    }
}

fn split_name<'a>(line: usize, keyword: &str, rest: &'a [&'a str]) -> Result<(&'a str, &'a [&'a str]), MapError> {
    match rest.split_first() {
        Some((name, tail)) if !name.contains('=') => {
            if name.chars().all(|c| c.is_alphanumeric() || c == '_' || c == '-') {
                Ok((name, tail))
            } else {
                Err(MapError::at(line, Some("name"), format!("`{name}` may hold only letters, digits, `_` and `-`")))
            }
        }
        _ => Err(MapError::at(line, Some("name"), format!("`{keyword}` needs a name first, e.g. `{keyword} A ...`"))),
    }
}

/// The `key=value` fields of one statement.
struct Fields<'a> {
    line: usize,
    values: HashMap<&'a str, &'a str>,
}

impl<'a> Fields<'a> {
    fn parse(line: usize, words: &[&'a str], allowed: &[&str]) -> Result<Self, MapError> {
        let mut values = HashMap::new();
        for w in words {
            let Some((k, v)) = w.split_once('=') else {
                return Err(MapError::at(line, None, format!("`{w}` is not a `key=value` field")));
            };
            if !allowed.contains(&k) {
                return Err(MapError::at(line, Some(k), format!("unknown field; expected one of: {}", allowed.join(", "))));
            }
            if values.insert(k, v).is_some() {
                return Err(MapError::at(line, Some(k), "given twice"));
            }
        }
        Ok(Self { line, values })
    }

    fn bad(&self, field: &str, message: impl Into<String>) -> MapError {
        MapError::at(self.line, Some(field), message)
    }

    fn text(&self, field: &str) -> Result<&'a str, MapError> {
        match self.values.get(field) {
            Some(v) if !v.is_empty() => Ok(v),
            _ => Err(self.bad(field, "missing")),
        }
    }

    fn number(&self, field: &str) -> Result<f32, MapError> {
        let v = self.text(field)?;
        match v.parse::<f32>() {
            Ok(x) if x.is_finite() && x.abs() <= 1.0e6 => Ok(x),
            Ok(_) => Err(self.bad(field, format!("`{v}` is out of range (|value| must be at most 1e6)"))),
            Err(_) => Err(self.bad(field, format!("`{v}` is not a number"))),
        }
    }

    fn number_or(&self, field: &str, default: f32) -> Result<f32, MapError> {
        if self.values.contains_key(field) { self.number(field) } else { Ok(default) }
    }

    fn positive(&self, field: &str) -> Result<f32, MapError> {
        let x = self.number(field)?;
        if x > 0.0 { Ok(x) } else { Err(self.bad(field, format!("{x} must be > 0"))) }
    }

    fn positive_or(&self, field: &str, default: f32) -> Result<f32, MapError> {
        if self.values.contains_key(field) { self.positive(field) } else { Ok(default) }
    }

    /// This statement's line if it sets `field`, else `inherited` (the line the default came from).
    fn line_of(&self, field: &str, inherited: usize) -> usize {
        if self.values.contains_key(field) { self.line } else { inherited }
    }

    fn non_negative_or(&self, field: &str, default: f32) -> Result<f32, MapError> {
        if !self.values.contains_key(field) {
            return Ok(default);
        }
        let x = self.number(field)?;
        if x >= 0.0 { Ok(x) } else { Err(self.bad(field, format!("{x} must be >= 0"))) }
    }

    /// `lanes=F,B`: forward and backward lane counts, each 0–4, at least one lane in all.
    fn lanes(&self, field: &str) -> Result<(u32, u32), MapError> {
        let v = self.text(field)?;
        let parsed = v.split_once(',').and_then(|(a, b)| Some((a.trim().parse::<u32>().ok()?, b.trim().parse::<u32>().ok()?)));
        match parsed {
            Some((f, b)) if f <= 4 && b <= 4 && f + b > 0 => Ok((f, b)),
            _ => Err(self.bad(field, format!("`{v}` must be FORWARD,BACKWARD lane counts, each 0 to 4 and not both 0 (e.g. `lanes=1,1`)"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "map name=t\nnode A x=0 y=0\nroad r from=A heading=0 to=B lanes=1,1\n  straight length=50 # comment\n  arc radius=20 angle=-90\nend\nbuilding x=10 y=20 width=5 depth=5\n";

    #[test]
    fn parses_a_small_map() {
        let spec = parse(SMALL).unwrap();
        assert_eq!(spec.name, "t");
        assert_eq!(spec.roads[0].pieces, vec![PieceSpec::Straight { length: 50.0 }, PieceSpec::Arc { radius: 20.0, angle_deg: -90.0 }]);
        assert_eq!(spec.roads[0].lane_width, 3.5);
        assert_eq!(spec.buildings[0].height, 12.0);
    }

    fn error_of(text: &str) -> MapError {
        parse(text).expect_err("should fail")
    }

    #[test]
    fn errors_name_line_and_field() {
        let e = error_of(&SMALL.replace("radius=20", "radius=-3"));
        assert_eq!((e.line, e.field.as_deref()), (5, Some("radius")));
        assert_eq!(e.to_string(), "map line 5, field `radius`: -3 must be > 0");

        let e = error_of(&SMALL.replace("lanes=1,1", "lanes=two"));
        assert_eq!((e.line, e.field.as_deref()), (3, Some("lanes")));

        let e = error_of(&SMALL.replace("width=5 ", "width=abc "));
        assert_eq!((e.line, e.field.as_deref()), (7, Some("width")));
        assert!(e.to_string().contains("`abc` is not a number"), "{e}");

        let e = error_of(&SMALL.replace("x=0 y=0", "x=0"));
        assert_eq!((e.line, e.field.as_deref()), (2, Some("y")));
        assert!(e.to_string().contains("missing"));

        let e = error_of(&SMALL.replace("heading=0", "heading=0 colour=red"));
        assert_eq!(e.field.as_deref(), Some("colour"));
    }

    #[test]
    fn structural_errors_name_the_line() {
        assert_eq!(error_of(&SMALL.replace("end\n", "")).line, 3);
        assert_eq!(error_of("straight length=3\n").line, 1);
        assert_eq!(error_of(&SMALL.replace("building", "tower")).line, 7);
        assert_eq!(error_of("node A x=0 y=0\n").line, 0);
    }
}
