//! Traffic: cars that follow lanes with the Intelligent Driver Model and cross junctions only
//! holding a reservation of their connector.
//!
//! Right of way: a car (or the ego vehicle) nearing a junction requests its connector; requests
//! are granted first come, first served, and only when no conflicting connector (one whose path
//! comes within touching distance, see `map::Junction::conflicts`) is held or was requested
//! earlier, and when the exit lane has room. A car without a reservation stops at the stop line.
//! Two cars can therefore never be on conflicting paths inside a junction at once.

use rand::{Rng, RngExt};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::collision::Obb;
use crate::map::LaneId;
use crate::math::Vec2;
use crate::town::Town;
use crate::vehicle::VehicleParams;

/// Intelligent Driver Model parameters (Treiber et al. 2000). Defaults are typical urban values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IdmParams {
    /// Maximum acceleration, m/s².
    pub accel: f32,
    /// Comfortable deceleration, m/s².
    pub comfort_decel: f32,
    /// Hardest braking, m/s².
    pub max_decel: f32,
    /// Minimum bumper-to-bumper gap, metres.
    pub min_gap: f32,
    /// Desired time headway, seconds.
    pub headway: f32,
}

impl Default for IdmParams {
    fn default() -> Self {
        Self { accel: 2.0, comfort_decel: 2.0, max_decel: 9.0, min_gap: 2.0, headway: 1.2 }
    }
}

impl IdmParams {
    /// The IDM's desired gap s* at speed `v` behind a stopped obstacle, metres.
    #[must_use]
    pub fn desired_gap(&self, v: f32) -> f32 {
        self.min_gap + v * self.headway + v * v / (2.0 * (self.accel * self.comfort_decel).sqrt())
    }

    /// How far before a junction's stop line a vehicle at speed `v` asks for its connector: its
    /// comfortable braking distance and a margin. Asking earlier would hold the junction idle.
    #[must_use]
    pub fn request_distance(&self, v: f32) -> f32 {
        v * v / (2.0 * self.comfort_decel) + self.min_gap + 3.0
    }

    /// IDM acceleration at speed `v` with desired speed `v0`, and a leader `gap` metres ahead
    /// (bumper to bumper) moving at `v_lead`.
    #[must_use]
    pub fn accel(&self, v: f32, v0: f32, leader: Option<(f32, f32)>) -> f32 {
        let free = 1.0 - (v / v0.max(0.1)).powi(4);
        let interaction = leader.map_or(0.0, |(gap, v_lead)| {
            let s_star = self.min_gap + (v * self.headway + v * (v - v_lead) / (2.0 * (self.accel * self.comfort_decel).sqrt())).max(0.0);
            (s_star / gap.max(0.1)).powi(2)
        });
        (self.accel * (free - interaction)).max(-self.max_decel)
    }
}

/// Look-ahead for leaders and stop lines, metres.
const LOOKAHEAD: f32 = 80.0;
/// How far ahead a car looks for a hazard's walkers and closures, metres: its braking distance
/// from the speed limits of towns, with a margin.
const YIELD_LOOKAHEAD: f32 = 40.0;
/// A reservation is released once the car's centre is this far along the exit lane, metres: half a
/// car length and a margin, so that its rear has left the connector.
pub const RELEASE_DISTANCE: f32 = 2.75;
/// Spacing kept between spawned cars, metres.
const SPAWN_SPACING: f32 = 15.0;

/// A car of the traffic.
#[derive(Debug, Clone, PartialEq)]
pub struct TrafficCar {
    pub lane: LaneId,
    /// Arc length of the body centre along `lane`.
    pub s: f32,
    pub speed: f32,
    /// Speed it would drive at on an empty straight road, m/s.
    pub desired_speed: f32,
    /// The lane it will take after this one.
    pub next: Option<LaneId>,
    pub pos: Vec2,
    pub heading: f32,
    /// Connector reserved (held from grant until its rear clears the exit).
    pub hold: Option<LaneId>,
    /// Step at which it first asked for its current connector.
    pub requested_at: Option<u64>,
    /// A parked car standing on a lane (never moves).
    pub parked: bool,
    /// False while waiting off the map to re-enter after reaching a dead end.
    pub active: bool,
    /// An acceleration imposed by a hazard's script instead of the IDM's (None for traffic).
    pub forced_accel: Option<f32>,
    /// Sideways offset from the lane's centre line, metres, positive to the left (a hazard's car
    /// changing lanes or pulling out; 0 for traffic).
    pub lateral: f32,
    segment: usize,
}

impl TrafficCar {
    /// A car driving on `lane` at `s`, placed at `pose` (position, heading, the path segment).
    fn driving(lane: LaneId, s: f32, speed: f32, desired_speed: f32, next: Option<LaneId>, pose: (Vec2, f32, usize)) -> Self {
        let (pos, heading, segment) = pose;
        Self {
            lane,
            s,
            speed,
            desired_speed,
            next,
            pos,
            heading,
            hold: None,
            requested_at: None,
            parked: false,
            active: true,
            forced_accel: None,
            lateral: 0.0,
            segment,
        }
    }
}

/// What traffic must know of the ego vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EgoView {
    pub body: Obb,
    pub speed: f32,
    /// The connector the ego holds, if any.
    pub hold: Option<LaneId>,
}

/// The ego vehicle's request to cross a junction: its connector and when it first asked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EgoRequest {
    pub connector: LaneId,
    pub since: u64,
}

/// All traffic cars and their per-lane ordering.
#[derive(Debug, Clone)]
pub struct Traffic {
    pub cars: Vec<TrafficCar>,
    pub idm: IdmParams,
    pub params: VehicleParams,
    /// Things every car stops for when they stand in its lane ahead: a hazard's walkers and
    /// closures (empty without hazards).
    pub yield_to: Vec<Obb>,
    /// Car indices on each lane, sorted by `s` (rebuilt every step).
    lane_cars: Vec<Vec<u32>>,
    touched: Vec<LaneId>,
    accel: Vec<f32>,
    /// `manage_junctions`' scratch, kept to spare allocations.
    junction_scratch: JunctionScratch,
}

/// Requests (first asked, car index, connector), held and denied connectors of one step's
/// junction management.
#[derive(Debug, Clone, Default)]
struct JunctionScratch {
    requests: Vec<(u64, usize, LaneId)>,
    held: Vec<LaneId>,
    denied: Vec<LaneId>,
}

impl Traffic {
    /// Traffic with no cars.
    #[must_use]
    pub fn empty(town: &Town, idm: IdmParams, params: VehicleParams) -> Self {
        Self {
            cars: Vec::new(),
            idm,
            params,
            yield_to: Vec::new(),
            lane_cars: vec![Vec::new(); town.map.lanes.len()],
            touched: Vec::new(),
            accel: Vec::new(),
            junction_scratch: JunctionScratch::default(),
        }
    }

    /// Places `n` cars on random road lanes, `SPAWN_SPACING` apart and at least `keep_clear`
    /// metres from each of `avoid`. Gives up on a car after a number of tries (dense requests on a
    /// small map place fewer cars).
    pub fn spawn(&mut self, town: &Town, n: usize, avoid: &[Vec2], keep_clear: f32, rng: &mut ChaCha8Rng) {
        let road_lanes: Vec<LaneId> = (0..town.map.lanes.len()).filter(|&l| !town.is_connector(l)).collect();
        for _ in 0..n {
            for _try in 0..30 {
                let lane = road_lanes[rng.random_range(0..road_lanes.len())];
                let len = town.map.lanes[lane].path.length();
                if len < 12.0 {
                    continue;
                }
                let s = rng.random_range(5.0..len - 5.0);
                if let Some(car) = self.try_place(town, lane, s, avoid, keep_clear, rng) {
                    self.cars.push(car);
                    break;
                }
            }
        }
        self.rebuild_lanes();
    }

    /// Adds a car standing still on `lane` at `s` (the "parked car ahead" obstacle).
    pub fn add_parked_on_lane(&mut self, town: &Town, lane: LaneId, s: f32) {
        let (pos, heading, segment) = town.map.lanes[lane].path.pose_at_hinted(s, 0);
        self.cars.push(TrafficCar {
            lane,
            s,
            speed: 0.0,
            desired_speed: 0.0,
            next: None,
            pos,
            heading,
            hold: None,
            requested_at: None,
            parked: true,
            active: true,
            forced_accel: None,
            lateral: 0.0,
            segment,
        });
        self.rebuild_lanes();
    }

    /// Adds a car driving on `lane` at `s` with `speed`, heading for `next` (a hazard's car).
    /// Returns its index.
    pub fn add_driving_on_lane(&mut self, town: &Town, lane: LaneId, s: f32, speed: f32, next: Option<LaneId>) -> usize {
        let (pos, heading, segment) = town.map.lanes[lane].path.pose_at_hinted(s, 0);
        self.cars.push(TrafficCar::driving(lane, s, speed, speed, next, (pos, heading, segment)));
        self.rebuild_lanes();
        self.cars.len() - 1
    }

    /// Takes car `i` off the map (it re-enters elsewhere, away from the ego, as at a dead end).
    pub fn remove(&mut self, i: usize) {
        self.cars[i].active = false;
        self.cars[i].hold = None;
        self.rebuild_lanes();
    }

    /// Moves car `i` onto `lane` at `s` with a sideways offset (a hazard's lane change).
    pub fn move_to_lane(&mut self, town: &Town, i: usize, lane: LaneId, s: f32, lateral: f32) {
        let c = &mut self.cars[i];
        c.lane = lane;
        c.s = s;
        c.segment = 0;
        c.lateral = lateral;
        c.next = town.map.lanes[lane].successors.first().copied();
        self.rebuild_lanes();
    }

    fn try_place(&self, town: &Town, lane: LaneId, s: f32, avoid: &[Vec2], keep_clear: f32, rng: &mut ChaCha8Rng) -> Option<TrafficCar> {
        let l = &town.map.lanes[lane];
        let (pos, heading, segment) = l.path.pose_at_hinted(s, 0);
        if avoid.iter().any(|a| a.distance(pos) < keep_clear) {
            return None;
        }
        if self.cars.iter().any(|c| c.active && c.pos.distance(pos) < SPAWN_SPACING) {
            return None;
        }
        let desired_speed = l.speed_limit * rng.random_range(0.8..1.0);
        let next = pick_successor(town, lane, rng);
        Some(TrafficCar::driving(lane, s, desired_speed * 0.5, desired_speed, next, (pos, heading, segment)))
    }

    /// The body of car `i`.
    #[must_use]
    pub fn body(&self, i: usize) -> Obb {
        let c = &self.cars[i];
        Obb::new(c.pos, self.params.half_extents(), c.heading)
    }

    /// Bodies of all active cars, with whether each is parked.
    pub fn bodies(&self) -> impl Iterator<Item = (Obb, bool)> + '_ {
        (0..self.cars.len()).filter(|&i| self.cars[i].active).map(|i| (self.body(i), self.cars[i].parked))
    }

    fn rebuild_lanes(&mut self) {
        for &l in &self.touched {
            self.lane_cars[l].clear();
        }
        self.touched.clear();
        for (i, c) in self.cars.iter().enumerate() {
            if c.active {
                if self.lane_cars[c.lane].is_empty() {
                    self.touched.push(c.lane);
                }
                self.lane_cars[c.lane].push(i as u32);
            }
        }
        let cars = &self.cars;
        for &l in &self.touched {
            self.lane_cars[l].sort_by(|&a, &b| cars[a as usize].s.total_cmp(&cars[b as usize].s).then(a.cmp(&b)));
        }
    }

    /// Smallest `s` of a car on `lane`, if any.
    fn first_on(&self, lane: LaneId) -> Option<&TrafficCar> {
        self.lane_cars[lane].first().map(|&i| &self.cars[i as usize])
    }

    /// Grants and releases junction reservations for this step. Returns whether the ego's request
    /// (if any) is granted.
    pub fn manage_junctions(&mut self, town: &Town, step: u64, ego_hold: Option<LaneId>, ego_request: Option<EgoRequest>) -> bool {
        // Release: cars whose rear has cleared their connector.
        for c in &mut self.cars {
            if let Some(h) = c.hold
                && (!c.active || (c.lane != h && c.next != Some(h) && c.s > RELEASE_DISTANCE))
            {
                c.hold = None;
            }
        }
        // Requests, oldest first; the ego's key sorts as car index usize::MAX on ties.
        let JunctionScratch { mut requests, mut held, mut denied } = std::mem::take(&mut self.junction_scratch);
        requests.clear();
        for (i, c) in self.cars.iter_mut().enumerate() {
            if !c.active || c.parked || c.hold.is_some() {
                continue;
            }
            match c.next {
                Some(n)
                    if town.is_connector(n)
                        && town.map.lanes[c.lane].path.length() - c.s - self.params.length / 2.0 < self.idm.request_distance(c.speed) =>
                {
                    let since = *c.requested_at.get_or_insert(step);
                    requests.push((since, i, n));
                }
                _ => c.requested_at = None,
            }
        }
        if let Some(r) = ego_request {
            requests.push((r.since, usize::MAX, r.connector));
        }
        let mut ego_granted = false;
        if !requests.is_empty() {
            requests.sort_unstable();
            held.clear();
            held.extend(self.cars.iter().filter_map(|c| c.hold));
            held.extend(ego_hold);
            denied.clear();
            ego_granted = self.grant(town, &requests, &mut held, &mut denied);
        }
        self.junction_scratch = JunctionScratch { requests, held, denied };
        ego_granted
    }

    /// Grants `requests` (sorted, oldest first) that conflict with no connector `held` or
    /// `denied` before them and whose exit lane has room; returns whether the ego's was granted.
    fn grant(&mut self, town: &Town, requests: &[(u64, usize, LaneId)], held: &mut Vec<LaneId>, denied: &mut Vec<LaneId>) -> bool {
        let mut ego_granted = false;
        for &(_, who, conn) in requests {
            let blocked = held.iter().chain(denied.iter()).any(|&h| town.connectors_conflict(conn, h));
            let exit = town.map.lanes[conn].successors[0];
            let room = self.first_on(exit).is_none_or(|c| c.s > self.params.length + self.idm.min_gap + 2.0);
            if blocked || !room {
                denied.push(conn);
                continue;
            }
            held.push(conn);
            if who == usize::MAX {
                ego_granted = true;
            } else {
                self.cars[who].hold = Some(conn);
                self.cars[who].requested_at = None;
            }
        }
        ego_granted
    }

    /// Advances all cars by `dt`: IDM accelerations from the current state, then motion along
    /// lanes. Cars reaching a dead end leave and re-enter elsewhere, away from the ego.
    pub fn step(&mut self, town: &Town, ego: &EgoView, dt: f32, rng: &mut ChaCha8Rng) {
        self.accel.clear();
        for i in 0..self.cars.len() {
            let c = &self.cars[i];
            let a = match c.forced_accel {
                Some(f) if c.active => f,
                _ if c.active && !c.parked => self.car_accel(town, i, ego),
                _ => 0.0,
            };
            self.accel.push(a);
        }
        for i in 0..self.cars.len() {
            if !self.cars[i].active {
                self.try_respawn(town, i, ego.body.centre, rng);
                continue;
            }
            if self.cars[i].parked {
                continue;
            }
            let a = self.accel[i];
            let c = &mut self.cars[i];
            c.speed = (c.speed + a * dt).max(0.0);
            c.s += c.speed * dt;
            loop {
                let len = town.map.lanes[c.lane].path.length();
                if c.s <= len {
                    break;
                }
                match c.next {
                    Some(n) if !town.is_connector(n) || c.hold == Some(n) => {
                        c.s -= len;
                        c.lane = n;
                        c.segment = 0;
                        c.next = pick_successor(town, n, rng);
                    }
                    Some(_) => {
                        // No reservation: never enter the junction.
                        c.s = len;
                        c.speed = 0.0;
                        break;
                    }
                    None => {
                        c.active = false;
                        c.hold = None;
                        break;
                    }
                }
            }
            if c.active {
                let (mut pos, heading, seg) = town.map.lanes[c.lane].path.pose_at_hinted(c.s, c.segment);
                if c.lateral != 0.0 {
                    pos += crate::math::left_normal(crate::math::dir(heading)) * c.lateral;
                }
                (c.pos, c.heading, c.segment) = (pos, heading, seg);
            }
        }
        self.rebuild_lanes();
    }

    fn try_respawn(&mut self, town: &Town, i: usize, ego: Vec2, rng: &mut ChaCha8Rng) {
        let lane = rng.random_range(0..town.map.lanes.len());
        if town.is_connector(lane) || town.map.lanes[lane].path.length() < 20.0 {
            return;
        }
        let clear = self.first_on(lane).is_none_or(|c| c.s > 5.0 + SPAWN_SPACING);
        if !clear {
            return;
        }
        if let Some(mut car) = self.try_place(town, lane, 5.0, &[ego], 50.0, rng) {
            car.desired_speed = self.cars[i].desired_speed.min(town.map.lanes[lane].speed_limit);
            self.cars[i] = car;
        }
    }

    /// IDM acceleration of car `i`: the nearest of the car ahead, the stop line of a junction it
    /// may not enter yet, and the ego vehicle if it stands in the car's path.
    fn car_accel(&self, town: &Town, i: usize, ego: &EgoView) -> f32 {
        let c = &self.cars[i];
        let half = self.params.length / 2.0;
        let lanes = &town.map.lanes;
        let mut v0 = c.desired_speed.min(town.curve_speed[c.lane]);
        let mut leader: Option<(f32, f32)> = None;
        let mut consider = |gap: f32, v: f32| {
            if leader.is_none_or(|(g, _)| gap < g) {
                leader = Some((gap, v));
            }
        };

        // Walk the lanes ahead: this one, then the planned next, then the one after a connector.
        let mut lane = c.lane;
        let mut offset = -c.s; // distance from the car to the start of `lane`
        let mut next = c.next;
        for depth in 0..3 {
            let list = &self.lane_cars[lane];
            let ahead = if depth == 0 {
                let k = list.iter().position(|&j| j as usize == i).expect("car listed on its lane");
                list.get(k + 1)
            } else {
                list.first()
            };
            if let Some(&j) = ahead {
                let o = &self.cars[j as usize];
                consider(offset + o.s - 2.0 * half, o.speed);
                break;
            }
            let len = lanes[lane].path.length();
            let Some(n) = next else { break };
            let to_end = offset + len;
            if to_end > LOOKAHEAD {
                break;
            }
            // Slow down ahead of a sharp connector or a slower road.
            let cap = lanes[n].speed_limit.min(town.curve_speed[n]);
            v0 = v0.min((cap * cap + 2.0 * self.idm.comfort_decel * to_end.max(0.0)).sqrt());
            if town.is_connector(n) && c.hold != Some(n) && depth == 0 {
                let gap = to_end - half - 0.5;
                if gap < self.idm.request_distance(c.speed) {
                    consider(gap, 0.0);
                }
                break;
            }
            lane = n;
            offset = to_end;
            next = if town.is_connector(n) { lanes[n].successors.first().copied() } else { None };
        }

        // The ego vehicle, when it stands in the lane ahead.
        let ego_pos = ego.body.centre;
        if c.pos.distance_squared(ego_pos) < LOOKAHEAD * LOOKAHEAD {
            let path = &lanes[c.lane].path;
            let p = path.project_range(ego_pos, c.segment, c.segment + LOOKAHEAD as usize);
            let corridor = lanes[c.lane].width / 2.0 + ego.body.half.y;
            if p.s > c.s && p.lateral.abs() < corridor {
                consider(p.s - c.s - half - ego.body.half.x, ego.speed);
            } else if let Some(n) = c.next.filter(|_| path.length() - c.s < LOOKAHEAD) {
                let p = lanes[n].path.project_range(ego_pos, 0, LOOKAHEAD as usize);
                if p.lateral.abs() < corridor
                    && p.distance < corridor
                    && (town.is_connector(n) && c.hold == Some(n) || !town.is_connector(n))
                {
                    consider(path.length() - c.s + p.s - half - ego.body.half.x, ego.speed);
                }
            }
        }
        // A hazard's walkers and closures standing in the lane ahead.
        for o in &self.yield_to {
            if c.pos.distance_squared(o.centre) > YIELD_LOOKAHEAD * YIELD_LOOKAHEAD {
                continue;
            }
            let path = &lanes[c.lane].path;
            let p = path.project_range(o.centre, c.segment, c.segment + YIELD_LOOKAHEAD as usize);
            // The distance to the lane, not the lateral offset: past the lane's end the offset is
            // from the last segment's line, and a closure beyond the junction would hold a car
            // (and its reservation) at the stop line for good.
            if p.s > c.s && p.distance < lanes[c.lane].width / 2.0 + o.half.length() {
                consider(p.s - c.s - half - o.half.length() - 1.0, 0.0);
            }
        }
        self.idm.accel(c.speed, v0, leader)
    }
}

/// A random lane to continue onto after `lane` (None at a dead end).
fn pick_successor(town: &Town, lane: LaneId, rng: &mut ChaCha8Rng) -> Option<LaneId> {
    let succ = &town.map.lanes[lane].successors;
    match succ.len() {
        0 => None,
        1 => Some(succ[0]),
        n => Some(succ[(rng.next_u32() as usize) % n]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn idm_free_road_accelerates_to_desired_speed() {
        let idm = IdmParams::default();
        assert!((idm.accel(0.0, 10.0, None) - 2.0).abs() < 1e-6);
        assert!(idm.accel(10.0, 10.0, None).abs() < 1e-6);
        // Closing fast on a stopped car 10 m ahead: brakes hard.
        assert!(idm.accel(10.0, 14.0, Some((10.0, 0.0))) < -5.0);
        // Well behind a car at the same speed: close to free road.
        assert!(idm.accel(10.0, 14.0, Some((200.0, 10.0))) > 1.0);
    }
}
