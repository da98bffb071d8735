//! The front camera: a pinhole camera on the ego vehicle, rendered column by column.
//!
//! Model: a "shift-lens" camera — the optical axis is horizontal and the image is shifted so that
//! the horizon sits where a camera pitched down by `pitch_deg` would put it. Vertical edges stay
//! vertical, which lets every box face be drawn as a run of vertical spans with perspective-correct
//! depth; the ground is looked up per pixel in the map's surface raster through offsets computed
//! once per camera. A depth buffer resolves occlusion between ground, boxes and the overpass.

use serde::{Deserialize, Serialize};

use super::image::Image;
use super::palette::{self, luma, scale};
use super::scene::SceneBox;
use crate::config::error::ConfigError;
use crate::map::Overpass;
use crate::math::{Vec2, cross, dir, left_normal, tan};
use crate::town::Town;

/// Where the camera sits on the ego vehicle and what it sees.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraConfig {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// RGB (3 bytes per pixel) instead of gray (1 byte).
    pub rgb: bool,
    /// Horizontal field of view, degrees.
    pub hfov_deg: f32,
    /// Height of the lens above the ground, metres.
    pub mount_height: f32,
    /// Distance of the lens ahead of the vehicle's centre, metres.
    pub mount_forward: f32,
    /// Downward tilt, degrees, realised as a lens shift.
    pub pitch_deg: f32,
    /// Nothing farther than this is drawn, metres.
    pub max_distance: f32,
    /// Frames the observation holds: the last `stack` images, oldest first, interleaved per pixel
    /// (`FrameStack`), so that motion is observable. 1 is a single frame, the paper's.
    pub stack: u32,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            width: 84,
            height: 84,
            rgb: false,
            hfov_deg: 90.0,
            mount_height: 1.6,
            mount_forward: 1.0,
            pitch_deg: 8.0,
            max_distance: 150.0,
            stack: 1,
        }
    }
}

impl CameraConfig {
    /// Bytes per pixel.
    #[must_use]
    pub fn channels(&self) -> u8 {
        if self.rgb { 3 } else { 1 }
    }

    /// Bytes per pixel of the stacked observation: `channels()` × `stack`.
    #[must_use]
    pub fn stacked_channels(&self) -> usize {
        usize::from(self.channels()) * self.stack as usize
    }

    /// Checks every field; the error names it (prefixed `camera.`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let err = |field: &str, message: String| Err(ConfigError { field: format!("camera.{field}"), message });
        for (v, f) in [(self.width, "width"), (self.height, "height")] {
            if !(8..=1024).contains(&v) {
                return err(f, format!("{v} pixels is outside 8..=1024"));
            }
        }
        if !(self.hfov_deg.is_finite() && self.hfov_deg > 10.0 && self.hfov_deg < 170.0) {
            return err("hfov_deg", format!("{} must be between 10 and 170 degrees", self.hfov_deg));
        }
        if !(self.mount_height.is_finite() && self.mount_height > 0.1 && self.mount_height < 10.0) {
            return err("mount_height", format!("{} m must be between 0.1 and 10", self.mount_height));
        }
        if !(self.mount_forward.is_finite() && self.mount_forward.abs() <= 5.0) {
            return err("mount_forward", format!("{} m must be within ±5", self.mount_forward));
        }
        if !(self.pitch_deg.is_finite() && self.pitch_deg.abs() <= 45.0) {
            return err("pitch_deg", format!("{} must be within ±45 degrees", self.pitch_deg));
        }
        if !(self.max_distance.is_finite() && self.max_distance >= 10.0) {
            return err("max_distance", format!("{} m must be at least 10", self.max_distance));
        }
        if !(1..=MAX_STACK).contains(&self.stack) {
            return err("stack", format!("{} frames is outside 1..={MAX_STACK} (1: a single frame)", self.stack));
        }
        Ok(())
    }
}

/// Most frames an observation may stack.
pub const MAX_STACK: u32 = 8;

/// Nearest depth drawn, metres.
const NEAR: f32 = 0.1;

/// A front camera with its precomputed per-pixel tables and scratch buffers.
#[derive(Debug, Clone)]
pub struct Camera {
    cfg: CameraConfig,
    /// Focal length in pixels.
    f: f32,
    /// Principal point (the horizon row is `cy`).
    cx: f32,
    cy: f32,
    /// Image rows showing the ground within `max_distance`.
    ground: Vec<GroundRow>,
    /// Depth and colour every pixel starts with (sky, haze, or ground depth).
    base_depth: Vec<f32>,
    base_colour: Vec<[u8; 3]>,
    /// Colour of every raw raster value.
    raster_rgb: Box<[[u8; 3]; 256]>,
    raster_gray: Box<[u8; 256]>,
    depth: Vec<f32>,
    /// The frame being drawn: one of the two, by `cfg.rgb`.
    rgb: Vec<[u8; 3]>,
    gray: Vec<u8>,
}

/// A pixel format the renderer draws into directly.
trait Pixel: Copy {
    fn from_rgb(c: [u8; 3]) -> Self;
}

impl Pixel for [u8; 3] {
    #[inline]
    fn from_rgb(c: [u8; 3]) -> Self {
        c
    }
}

impl Pixel for u8 {
    #[inline]
    fn from_rgb(c: [u8; 3]) -> Self {
        luma(c)
    }
}

/// Fixed-point scale of raster coordinates in the ground loop (16 fractional bits).
const FIX: f32 = 65536.0;

/// An image row that sees the ground: all its pixels are at the same depth `z`.
#[derive(Debug, Clone, Copy)]
struct GroundRow {
    /// Index of the row's first pixel.
    start: usize,
    z: f32,
    /// Raster level whose cells are about one pixel's footprint at this depth.
    level: usize,
}

/// Where the camera is in the world for one frame.
#[derive(Debug, Clone, Copy)]
struct View {
    origin: Vec2,
    forward: Vec2,
    left: Vec2,
}

impl View {
    /// World point to camera frame: (depth along the axis, offset to the left).
    #[inline]
    fn camera_coords(&self, p: Vec2) -> (f32, f32) {
        let d = p - self.origin;
        (d.dot(self.forward), d.dot(self.left))
    }
}

impl Camera {
    /// A camera for a validated configuration.
    pub fn new(cfg: &CameraConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let (w, h) = (cfg.width as usize, cfg.height as usize);
        let f = (cfg.width as f32 / 2.0) / tan(cfg.hfov_deg.to_radians() / 2.0);
        let cx = cfg.width as f32 / 2.0;
        let cy = cfg.height as f32 / 2.0 - f * tan(cfg.pitch_deg.to_radians());
        let mut ground = Vec::new();
        // Base raster cell size: the default town's. A map with another cell size only changes
        // which level is sharpest, not correctness.
        let base_cell = 0.25f32;
        let mut base_depth = vec![f32::INFINITY; w * h];
        let mut base_colour = vec![palette::SKY_TOP; w * h];
        for r in 0..h {
            let v = r as f32 + 0.5;
            let below = v - cy;
            let z = if below > 0.0 { f * cfg.mount_height / below } else { f32::INFINITY };
            if z <= cfg.max_distance {
                let footprint = z / f;
                let level = (footprint / base_cell).log2().floor().max(0.0) as usize;
                ground.push(GroundRow { start: r * w, z, level });
            }
            for c in 0..w {
                let i = r * w + c;
                if z <= cfg.max_distance {
                    base_depth[i] = z;
                } else if below > 0.0 {
                    base_colour[i] = palette::HAZE;
                    base_depth[i] = cfg.max_distance;
                } else {
                    // Sky: lighter toward the horizon.
                    let k = ((cy - v) / cy.max(1.0)).clamp(0.0, 1.0);
                    let (a, b) = (palette::SKY_HORIZON, palette::SKY_TOP);
                    base_colour[i] = [0, 1, 2].map(|j| (f32::from(a[j]) * (1.0 - k) + f32::from(b[j]) * k) as u8);
                }
            }
        }
        Ok(Self {
            cfg: cfg.clone(),
            f,
            cx,
            cy,
            ground,
            base_depth,
            base_colour,
            raster_rgb: Box::new(palette::raster_table()),
            raster_gray: Box::new(palette::raster_table().map(luma)),
            depth: vec![0.0; w * h],
            rgb: if cfg.rgb { vec![[0; 3]; w * h] } else { Vec::new() },
            gray: if cfg.rgb { Vec::new() } else { vec![0; w * h] },
        })
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &CameraConfig {
        &self.cfg
    }

    /// The pixel (column, row), as floats, where a world point at `height` metres appears for a
    /// vehicle at `pos` facing `heading`; `None` behind the camera.
    #[must_use]
    pub fn project(&self, pos: Vec2, heading: f32, point: Vec2, height: f32) -> Option<(f32, f32)> {
        let view = self.view(pos, heading);
        let (z, l) = view.camera_coords(point);
        (z > NEAR).then(|| (self.cx - self.f * l / z, self.cy - self.f * (height - self.cfg.mount_height) / z))
    }

    fn view(&self, pos: Vec2, heading: f32) -> View {
        let forward = dir(heading);
        View { origin: pos + forward * self.cfg.mount_forward, forward, left: left_normal(forward) }
    }

    /// Renders the view from a vehicle at `pos` facing `heading` into `out`, with the town's
    /// static scenery and the given vehicles.
    pub fn render(&mut self, town: &Town, pos: Vec2, heading: f32, vehicles: &[SceneBox], out: &mut Image) {
        let view = self.view(pos, heading);
        let mut depth = std::mem::take(&mut self.depth);
        depth.copy_from_slice(&self.base_depth);
        out.width = self.cfg.width;
        out.height = self.cfg.height;
        out.channels = self.cfg.channels();
        out.data.clear();
        if self.cfg.rgb {
            let mut buf = std::mem::take(&mut self.rgb);
            self.draw_scene(&view, town, vehicles, &mut depth, &mut buf, &self.raster_rgb);
            out.data.extend(buf.iter().flatten());
            self.rgb = buf;
        } else {
            let mut buf = std::mem::take(&mut self.gray);
            self.draw_scene(&view, town, vehicles, &mut depth, &mut buf, &self.raster_gray);
            out.data.extend_from_slice(&buf);
            self.gray = buf;
        }
        self.depth = depth;
    }

    fn draw_scene<P: Pixel>(&self, view: &View, town: &Town, vehicles: &[SceneBox], depth: &mut [f32], buf: &mut [P], table: &[P; 256]) {
        for (px, &c) in buf.iter_mut().zip(&self.base_colour) {
            *px = P::from_rgb(c);
        }
        // Ground: along a row the world point moves linearly, so do its raster coordinates
        // (16.16 fixed point, so that stepping is exact and cheap).
        let levels = town.map.surface.levels();
        let w = self.cfg.width as usize;
        for row in &self.ground {
            let lv = &levels[row.level.min(levels.len() - 1)];
            let first = view.origin + view.forward * row.z + view.left * ((self.cx - 0.5) * row.z / self.f);
            let step = view.left * (-row.z / self.f);
            let to_fix = |v: f32| (v * FIX).clamp(-1.0e9, 1.0e9) as i64;
            let (mut fx, mut fy) = (to_fix((first.x - lv.origin.x) * lv.inv_cell), to_fix((first.y - lv.origin.y) * lv.inv_cell));
            let (dx, dy) = (to_fix(step.x * lv.inv_cell), to_fix(step.y * lv.inv_cell));
            let (lw, lh) = (lv.width as u64, lv.height as u64);
            for px in &mut buf[row.start..row.start + w] {
                let (ix, iy) = ((fx >> 16) as u64, (fy >> 16) as u64);
                // Negative coordinates wrap to huge unsigned values and fail the bounds test.
                let v = if ix < lw && iy < lh { lv.cells[(iy * lw + ix) as usize] } else { 0 };
                *px = table[v as usize];
                fx += dx;
                fy += dy;
            }
        }

        // Boxes: static obstacles and overpass decks, then vehicles.
        for b in &town.scene_statics {
            self.draw_box(view, b, depth, buf);
        }
        for o in &town.map.overpasses {
            self.draw_underside(view, o, depth, buf);
        }
        for b in vehicles {
            self.draw_box(view, b, depth, buf);
        }
    }

    fn draw_box<P: Pixel>(&self, view: &View, b: &SceneBox, depth: &mut [f32], buf: &mut [P]) {
        let radius = b.footprint.half.length();
        let (zc, lc) = view.camera_coords(b.footprint.centre);
        let half_fov = self.cx / self.f;
        if zc < -radius || zc > self.cfg.max_distance + radius || lc.abs() > (zc + radius) * half_fov + radius {
            return;
        }
        let corners = b.footprint.corners();
        for i in 0..4 {
            let (a, c) = (corners[i], corners[(i + 1) % 4]);
            // Counter-clockwise corners: the outward normal is to the right of the edge.
            if cross(c - a, view.origin - a) >= 0.0 {
                continue;
            }
            let edge = c - a;
            let normal = Vec2::new(edge.y, -edge.x).normalize_or_zero();
            // Fixed light from the south-west, so that faces read as solid.
            let shade = 0.78 + 0.22 * normal.dot(Vec2::new(-0.6, -0.8));
            self.draw_face(view.camera_coords(a), view.camera_coords(c), b.bottom, b.top, P::from_rgb(scale(b.colour, shade)), depth, buf);
        }
    }

    /// Draws a vertical face between camera-frame points `a` and `b` from height `h0` to `h1`.
    #[allow(clippy::too_many_arguments)]
    fn draw_face<P: Pixel>(&self, mut a: (f32, f32), mut b: (f32, f32), h0: f32, h1: f32, colour: P, depth: &mut [f32], buf: &mut [P]) {
        if a.0 < NEAR && b.0 < NEAR {
            return;
        }
        let clip = |p: (f32, f32), q: (f32, f32)| {
            let t = (NEAR - p.0) / (q.0 - p.0);
            (NEAR, p.1 + (q.1 - p.1) * t)
        };
        if a.0 < NEAR {
            a = clip(a, b);
        } else if b.0 < NEAR {
            b = clip(b, a);
        }
        let (f, cx, cy) = (self.f, self.cx, self.cy);
        let (mut ua, mut ub) = (cx - f * a.1 / a.0, cx - f * b.1 / b.0);
        let (mut ia, mut ib) = (1.0 / a.0, 1.0 / b.0);
        if ua > ub {
            std::mem::swap(&mut ua, &mut ub);
            std::mem::swap(&mut ia, &mut ib);
        }
        let (w, h) = (self.cfg.width as i32, self.cfg.height as i32);
        let c0 = ((ua - 0.5).ceil() as i32).max(0);
        let c1 = ((ub - 0.5).floor() as i32).min(w - 1);
        if c1 < c0 || ub - ua < 1e-6 {
            return;
        }
        let (top_k, bot_k) = (f * (h1 - self.cfg.mount_height), f * (h0 - self.cfg.mount_height));
        for c in c0..=c1 {
            let alpha = (c as f32 + 0.5 - ua) / (ub - ua);
            let inv_z = ia + (ib - ia) * alpha;
            let z = 1.0 / inv_z;
            let r0 = ((cy - top_k * inv_z - 0.5).ceil() as i32).max(0);
            let r1 = ((cy - bot_k * inv_z - 0.5).floor() as i32).min(h - 1);
            for r in r0..=r1 {
                let i = (r * w + c) as usize;
                if z < depth[i] {
                    depth[i] = z;
                    buf[i] = colour;
                }
            }
        }
    }

    /// Draws the underside of an overpass deck: the ceiling plane at the deck's clearance,
    /// wherever a pixel above the horizon looks at it.
    fn draw_underside<P: Pixel>(&self, view: &View, o: &Overpass, depth: &mut [f32], buf: &mut [P]) {
        let centre = (o.a + o.b) / 2.0;
        let reach = o.a.distance(o.b) / 2.0 + o.width;
        let (zc, _) = view.camera_coords(centre);
        if zc < -reach || zc > self.cfg.max_distance + reach {
            return;
        }
        let rise = o.clearance - self.cfg.mount_height;
        if rise <= 0.0 {
            return;
        }
        let axis = (o.b - o.a).normalize_or_zero();
        let half_len = o.a.distance(o.b) / 2.0;
        let w = self.cfg.width as usize;
        let last_row = (self.cy - 0.5).floor().max(-1.0) as i32;
        for r in 0..=last_row {
            let above = self.cy - (r as f32 + 0.5);
            let z = self.f * rise / above;
            if z > self.cfg.max_distance {
                continue;
            }
            for c in 0..w {
                let i = r as usize * w + c;
                if z >= depth[i] {
                    continue;
                }
                let l = -(c as f32 + 0.5 - self.cx) * z / self.f;
                let d = view.origin + view.forward * z + view.left * l - centre;
                if d.dot(axis).abs() <= half_len && cross(axis, d).abs() <= o.width / 2.0 {
                    depth[i] = z;
                    buf[i] = P::from_rgb(palette::DECK_UNDERSIDE);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::palette::{luma, surface};
    use crate::camera::scene::car_box;
    use crate::collision::Obb;
    use crate::map::Surface;

    /// A straight east–west road with one pole beside it, no junctions.
    fn one_road_town() -> std::sync::Arc<Town> {
        Town::from_map_text("node A x=0 y=0\nroad r from=A heading=0 to=B lanes=1,1 shoulder=2\n straight length=300\nend\npole x=40 y=-9 radius=0.3 height=8\n")
            .expect("valid map")
    }

    fn gray(kind: Surface) -> u8 {
        luma(surface(kind))
    }

    #[test]
    fn a_known_point_projects_to_the_expected_pixel() {
        // 84 px wide, 90° field of view: f = 42 px. Horizon row: 42 − 42·tan 8° = 36.097.
        let cam = Camera::new(&CameraConfig::default()).unwrap();
        let (pos, heading) = (Vec2::new(5.0, 5.0), 0.0);
        // Lens at x = 6 (1 m ahead of the centre), 1.6 m high. A point 10 m ahead at lens height
        // is on the optical axis: column 42, the horizon row.
        let (c, r) = cam.project(pos, heading, Vec2::new(16.0, 5.0), 1.6).unwrap();
        assert!((c - 42.0).abs() < 1e-4 && (r - 36.097).abs() < 1e-3, "({c}, {r})");
        // 2 m to the left: 42 − 42·2/10 = 33.6. On the ground: 36.097 + 42·1.6/10 = 42.817.
        let (c, r) = cam.project(pos, heading, Vec2::new(16.0, 7.0), 0.0).unwrap();
        assert!((c - 33.6).abs() < 1e-4 && (r - 42.817).abs() < 1e-3, "({c}, {r})");
        assert!(cam.project(pos, heading, Vec2::new(0.0, 5.0), 0.0).is_none(), "behind the lens");
    }

    #[test]
    fn a_pole_appears_where_it_projects() {
        let town = one_road_town();
        let mut cam = Camera::new(&CameraConfig::default()).unwrap();
        let mut img = Image::new(0, 0, 1);
        // Driving east in the right lane (y = −1.75); the pole stands at (40, −9), 8 m tall.
        let pos = Vec2::new(10.0, -1.75);
        cam.render(&town, pos, 0.0, &[], &mut img);
        let (c, r) = cam.project(pos, 0.0, Vec2::new(40.0, -9.0), 4.0).unwrap();
        let px = img.pixel(c as u32, r as u32)[0];
        let pole = luma(palette::obstacle(crate::map::ObstacleKind::Pole, 0));
        assert!(px.abs_diff(pole) <= 10, "pixel ({c}, {r}) is {px}, pole gray is about {pole}");
    }

    #[test]
    fn a_straight_road_fills_the_lower_middle_and_sky_the_top() {
        let town = one_road_town();
        let mut cam = Camera::new(&CameraConfig::default()).unwrap();
        let mut img = Image::new(0, 0, 1);
        cam.render(&town, Vec2::new(10.0, -1.75), 0.0, &[], &mut img);
        assert_eq!((img.width, img.height, img.channels, img.data.len()), (84, 84, 1, 84 * 84));
        // Bottom rows, middle columns: asphalt (or lane lines) of our lane.
        let road = [gray(Surface::Road), gray(Surface::WhiteLine), gray(Surface::YellowLine)];
        for (c, r) in [(42, 83), (45, 70), (40, 60)] {
            assert!(road.contains(&img.pixel(c, r)[0]), "({c}, {r}) = {}", img.pixel(c, r)[0]);
        }
        // Above the horizon (row 36): sky, brighter than anything on the ground here.
        for c in [0, 42, 83] {
            assert!(img.pixel(c, 2)[0] > 150, "sky at ({c}, 2) = {}", img.pixel(c, 2)[0]);
        }
    }

    #[test]
    fn a_vehicle_ahead_hides_the_road_behind_it() {
        let town = one_road_town();
        let mut cam = Camera::new(&CameraConfig { rgb: true, ..CameraConfig::default() }).unwrap();
        let mut img = Image::new(0, 0, 3);
        let pos = Vec2::new(10.0, -1.75);
        cam.render(&town, pos, 0.0, &[], &mut img);
        // Where the road 15 m ahead shows now...
        let (c, r) = cam.project(pos, 0.0, Vec2::new(26.0, -1.75), 0.0).unwrap();
        let (c, r) = (c as u32, r as u32 - 1);
        assert_eq!(img.pixel(c, r), surface(Surface::Road));
        // ...a car 10 m ahead in the same lane covers it.
        let car = car_box(Obb::new(Vec2::new(21.0, -1.75), Vec2::new(2.25, 0.95), 0.0), 3);
        cam.render(&town, pos, 0.0, &[car], &mut img);
        let px = img.pixel(c, r);
        assert_ne!(px, surface(Surface::Road));
        // The face seen is the car's back (facing west), its colour shaded by the fixed light.
        assert_eq!(px, scale(car.colour, 0.78 + 0.22 * Vec2::new(-1.0, 0.0).dot(Vec2::new(-0.6, -0.8))));
    }

    #[test]
    fn rendering_is_deterministic_and_sensitive_to_the_pose() {
        let town = Town::default_town();
        let mut a = Camera::new(&CameraConfig::default()).unwrap();
        let mut b = Camera::new(&CameraConfig::default()).unwrap();
        let (mut ia, mut ib) = (Image::new(0, 0, 1), Image::new(0, 0, 1));
        a.render(&town, Vec2::new(101.75, 40.0), std::f32::consts::FRAC_PI_2, &[], &mut ia);
        b.render(&town, Vec2::new(101.75, 40.0), std::f32::consts::FRAC_PI_2, &[], &mut ib);
        assert_eq!(ia.hash(), ib.hash());
        b.render(&town, Vec2::new(101.75, 41.0), std::f32::consts::FRAC_PI_2, &[], &mut ib);
        assert_ne!(ia.hash(), ib.hash());
    }

    #[test]
    fn invalid_camera_config_names_the_field() {
        let e = Camera::new(&CameraConfig { width: 0, ..CameraConfig::default() }).unwrap_err();
        assert_eq!(e.field, "camera.width");
        assert_eq!(e.to_string(), "config field `camera.width`: 0 pixels is outside 8..=1024");
        let e = Camera::new(&CameraConfig { hfov_deg: 200.0, ..CameraConfig::default() }).unwrap_err();
        assert_eq!(e.field, "camera.hfov_deg");
        let e = Camera::new(&CameraConfig { mount_height: f32::NAN, ..CameraConfig::default() }).unwrap_err();
        assert_eq!(e.field, "camera.mount_height");
    }
}
