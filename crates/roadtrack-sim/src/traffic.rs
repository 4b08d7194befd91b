//! Microscopic traffic: vehicles with the Intelligent Driver Model (IDM) and MOBIL lane
//! changes, fixed-time signals, and pedestrians walking routes with crosswalks.
//!
//! IDM (Treiber, Hennecke & Helbing 2000), acceleration of a vehicle at speed `v` with
//! desired speed `v0`, gap `s` to its leader and approach rate `Δv = v − v_leader`:
//!
//! ```text
//! a_IDM = a · [1 − (v/v0)^4 − (s*(v, Δv)/s)^2],   s* = s0 + max(0, v·T + v·Δv / (2·√(a·b)))
//! ```
//!
//! MOBIL (Kesting, Treiber & Helbing 2007): change lane when it is safe for the new
//! follower (`ã_new_follower ≥ −b_safe`) and
//! `ã_self − a_self + p·(ã_new_follower − a_new_follower + ã_old_follower − a_old_follower)
//! ± bias > Δa_th`. Positions are integrated ballistically with the scene's time step.
//! A vehicle never moves closer than 0.2 m to the rear of its leader's position at the
//! start of the step (a collision guard: with IDM's parameters it almost never acts), so
//! vehicles in the same lane never overlap.

use super::config::{SimConfig, VehicleClassConfig};
use super::scene::{Light, Polyline, RouteCrossing, Scene, Vec2};
use rand::RngExt;
use rand_distr::StandardNormal;
use roadtrack_core::class::ObjectClass;
use roadtrack_core::rng::{Rng, Stream, rng, rng_for};

/// What one object is doing at one instant (the simulator's truth before projection).
#[derive(Debug, Clone, PartialEq)]
pub struct AgentState {
    /// Object id (unique over the run, from 1).
    pub id: u64,
    /// Class.
    pub class: ObjectClass,
    /// Ground position of the footprint's centre, m.
    pub pos_m: Vec2,
    /// Heading, radians ccw from ground `+x`.
    pub heading_rad: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Length (along the heading), m.
    pub length_m: f64,
    /// Width, m.
    pub width_m: f64,
    /// Height, m.
    pub height_m: f64,
    /// Main colour: vehicle paint or a pedestrian's top.
    pub colour: [u8; 3],
    /// Second colour: a lorry's cargo box or a pedestrian's trousers.
    pub secondary: [u8; 3],
}

#[derive(Debug, Clone)]
struct Vehicle {
    state: AgentState,
    route: usize,
    s: f64,
    v: f64,
    v0: f64,
    a_max: f64,
    /// Previous lane route and the seconds the lateral move has left.
    lane_change: Option<(usize, f64)>,
    next_lane_check_s: f64,
}

#[derive(Debug, Clone)]
struct Pedestrian {
    state: AgentState,
    path: Polyline,
    crossings: Vec<RouteCrossing>,
    s: f64,
    v0: f64,
    wait_back_m: f64,
}

#[derive(Debug, Clone)]
struct PendingVehicle {
    route: usize,
    class: ObjectClass,
}

/// The running traffic of one scene.
#[derive(Debug, Clone)]
pub struct Traffic {
    scene: Scene,
    config: SimConfig,
    seed: u64,
    rng: Rng,
    time_s: f64,
    next_id: u64,
    vehicles: Vec<Vehicle>,
    pedestrians: Vec<Pedestrian>,
    next_vehicle_s: Vec<f64>,
    pending: Vec<Vec<PendingVehicle>>,
    next_group_s: Vec<f64>,
    occ: Vec<Vec<(f64, usize)>>,
}

/// Draws from a Poisson distribution with mean `lambda` (Knuth's product method; the
/// means used here are small).
pub(crate) fn poisson(rng: &mut Rng, lambda: f64) -> u32 {
    if lambda <= 0.0 {
        return 0;
    }
    if lambda > 30.0 {
        let z: f64 = rng.sample(StandardNormal);
        return (lambda + lambda.sqrt() * z).round().max(0.0) as u32;
    }
    let limit = (-lambda).exp();
    let mut k = 0;
    let mut p: f64 = rng.random();
    while p > limit {
        k += 1;
        p *= rng.random::<f64>();
    }
    k
}

fn exp_draw(rng: &mut Rng, rate: f64) -> f64 {
    if rate <= 0.0 {
        return f64::INFINITY;
    }
    let u: f64 = rng.random();
    -(1.0 - u).ln() / rate
}

fn normal(rng: &mut Rng, mean: f64, sd: f64) -> f64 {
    let z: f64 = rng.sample(StandardNormal);
    mean + sd * z.clamp(-2.5, 2.5)
}

fn pick(rng: &mut Rng, weights: impl Iterator<Item = f64> + Clone) -> usize {
    let total: f64 = weights.clone().sum();
    let mut u = rng.random::<f64>() * total;
    let mut last = 0;
    for (i, w) in weights.enumerate() {
        if w > 0.0 {
            last = i;
            if u < w {
                return i;
            }
            u -= w;
        }
    }
    last
}

fn jitter_colour(rng: &mut Rng, rgb: [u8; 3], sd: f64) -> [u8; 3] {
    let k = normal(rng, 1.0, sd);
    rgb.map(|c| (f64::from(c) * k + normal(rng, 0.0, 3.0)).clamp(0.0, 255.0) as u8)
}

/// IDM acceleration (module doc), with `gap = None` on a free road.
fn idm(v: f64, v0: f64, gap_and_dv: Option<(f64, f64)>, a: f64, c: &SimConfig) -> f64 {
    let vc = &c.vehicles;
    let free = 1.0 - (v / v0.max(0.1)).powi(4);
    let acc = match gap_and_dv {
        None => a * free,
        Some((gap, dv)) => {
            let s_star = vc.min_gap_m
                + (v * vc.time_headway_s + v * dv / (2.0 * (a * vc.comfort_decel_mps2).sqrt()))
                    .max(0.0);
            a * (free - (s_star / gap.max(0.05)).powi(2))
        }
    };
    acc.clamp(-vc.max_decel_mps2, a)
}

/// Pedestrian shirt colours (muted, with a few bright ones).
const TOPS: [[u8; 3]; 12] = [
    [28, 30, 38],
    [60, 62, 70],
    [200, 200, 196],
    [150, 40, 40],
    [40, 60, 120],
    [120, 120, 125],
    [190, 170, 130],
    [60, 90, 60],
    [230, 230, 225],
    [90, 50, 80],
    [210, 120, 40],
    [70, 110, 160],
];

/// Trouser colours.
const BOTTOMS: [[u8; 3]; 5] = [
    [30, 32, 40],
    [50, 55, 75],
    [80, 80, 85],
    [120, 105, 80],
    [20, 20, 22],
];

impl Traffic {
    /// Starts empty traffic on `scene` under `seed` (draws on [`Stream::Scenario`]).
    pub fn new(scene: Scene, config: &SimConfig, seed: u64) -> Self {
        let mut rng = rng(seed, Stream::Scenario);
        let next_vehicle_s = scene
            .entries
            .iter()
            .map(|e| exp_draw(&mut rng, e.rate_per_s))
            .collect();
        let next_group_s = scene
            .pedestrian_entries
            .iter()
            .map(|e| exp_draw(&mut rng, e.rate_per_s))
            .collect();
        let pending = vec![Vec::new(); scene.entries.len()];
        Self {
            scene,
            config: config.clone(),
            seed,
            rng,
            time_s: 0.0,
            next_id: 1,
            vehicles: Vec::new(),
            pedestrians: Vec::new(),
            next_vehicle_s,
            pending,
            next_group_s,
            occ: Vec::new(),
        }
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Every object now, vehicles then pedestrians, each sorted by id.
    pub fn states(&self) -> Vec<AgentState> {
        let mut out: Vec<AgentState> = self.vehicles.iter().map(|v| v.state.clone()).collect();
        out.extend(self.pedestrians.iter().map(|p| p.state.clone()));
        out.sort_by_key(|a| a.id);
        out
    }

    /// The lane route index of each vehicle (for tests of lane discipline):
    /// `(id, route, s, length, lane change in progress)`.
    pub fn vehicle_lanes(&self) -> Vec<(u64, usize, f64, f64, Option<usize>)> {
        self.vehicles
            .iter()
            .map(|v| {
                (
                    v.state.id,
                    v.route,
                    v.s,
                    v.state.length_m,
                    v.lane_change.map(|l| l.0),
                )
            })
            .collect()
    }

    /// Advances by `dt_s`.
    pub fn step(&mut self, dt_s: f64) {
        self.index();
        self.arrivals();
        self.index();
        self.move_vehicles(dt_s);
        self.index();
        self.lane_changes();
        self.move_pedestrians(dt_s);
        self.time_s += dt_s;
        self.update_states();
    }

    fn class_config(&self, class: &ObjectClass) -> &VehicleClassConfig {
        let v = &self.config.vehicles;
        match class {
            ObjectClass::Truck => &v.truck,
            ObjectClass::Bus => &v.bus,
            ObjectClass::Motorcycle => &v.motorcycle,
            _ => &v.car,
        }
    }

    fn arrivals(&mut self) {
        let t = self.time_s;
        for e in 0..self.scene.entries.len() {
            while self.next_vehicle_s[e] <= t {
                let entry = &self.scene.entries[e];
                let r = pick(&mut self.rng, entry.routes.iter().map(|x| x.1));
                let route = entry.routes[r].0;
                let v = &self.config.vehicles;
                let shares = [v.car.share, v.truck.share, v.bus.share, v.motorcycle.share];
                let class = match pick(&mut self.rng, shares.into_iter()) {
                    1 => ObjectClass::Truck,
                    2 => ObjectClass::Bus,
                    3 => ObjectClass::Motorcycle,
                    _ => ObjectClass::Car,
                };
                self.pending[e].push(PendingVehicle { route, class });
                let rate = self.scene.entries[e].rate_per_s;
                self.next_vehicle_s[e] += exp_draw(&mut self.rng, rate);
            }
            self.try_spawn(e);
        }
        for e in 0..self.scene.pedestrian_entries.len() {
            while self.next_group_s[e] <= t {
                self.spawn_group(e);
                let rate = self.scene.pedestrian_entries[e].rate_per_s;
                self.next_group_s[e] += exp_draw(&mut self.rng, rate);
            }
        }
    }

    /// Rebuilds the per-segment occupancy lists (sorted by position along the segment).
    fn index(&mut self) {
        let mut occ = vec![Vec::new(); self.scene.n_segments];
        for (j, v) in self.vehicles.iter().enumerate() {
            for (route, s) in v.occupied() {
                let r = &self.scene.routes[route];
                if let Some(part) = r.parts.get(r.part_index(s))
                    && let Some(list) = occ.get_mut(part.segment)
                {
                    list.push((s - part.start_s, j));
                }
            }
        }
        for list in &mut occ {
            list.sort_by(|a: &(f64, usize), b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        }
        self.occ = occ;
    }

    /// Nearest vehicle ahead of route position `s` on `route` (excluding `me`):
    /// `(gap_m, leader index)`, gap from my front to its rear. Uses the occupancy index.
    fn leader(&self, me: usize, route: usize, s: f64, length: f64) -> Option<(f64, usize)> {
        let r = &self.scene.routes[route];
        let k = r.part_index(s);
        for (n, part) in r.parts[k..].iter().enumerate() {
            if part.start_s - s > 200.0 {
                break;
            }
            let Some(list) = self.occ.get(part.segment) else {
                continue;
            };
            let local = s - part.start_s;
            let from = if n == 0 {
                list.partition_point(|e| e.0 <= local)
            } else {
                0
            };
            if let Some(&(ol, j)) = list[from..].iter().find(|e| e.1 != me) {
                let gap = part.start_s + ol - s - (length + self.vehicles[j].state.length_m) / 2.0;
                return Some((gap, j));
            }
        }
        None
    }

    /// Nearest vehicle behind route position `s` on the lane `route` (first part only).
    fn follower(&self, me: usize, route: usize, s: f64, length: f64) -> Option<(f64, usize)> {
        let r = &self.scene.routes[route];
        let part = r.parts.get(r.part_index(s))?;
        let list = self.occ.get(part.segment)?;
        let local = s - part.start_s;
        let to = list.partition_point(|e| e.0 < local);
        let &(ol, j) = list[..to].iter().rev().find(|e| e.1 != me)?;
        let gap = local - ol - (length + self.vehicles[j].state.length_m) / 2.0;
        Some((gap, j))
    }

    fn try_spawn(&mut self, e: usize) {
        while let Some(p) = self.pending[e].first().cloned() {
            // Lanes of a multi-lane road are interchangeable at the entry: take the one with
            // the most room if the drawn one is blocked.
            let mut candidates = vec![p.route];
            if let Some(_lane) = self.scene.routes[p.route].lane {
                for &r in &self.scene.lane_routes {
                    if r != p.route {
                        candidates.push(r);
                    }
                }
            }
            let id = self.next_id;
            let mut arng = rng_for(self.seed, Stream::Scenario, id);
            let cc = self.class_config(&p.class).clone();
            let length = normal(&mut arng, cc.length_m[0], cc.length_m[1]).max(0.5);
            let width = normal(&mut arng, cc.width_m[0], cc.width_m[1]).max(0.3);
            let vc = &self.config.vehicles;
            let mut placed = None;
            for route in candidates {
                let s = length / 2.0;
                if self.follower(usize::MAX, route, s, length).is_some() {
                    continue;
                }
                // Insert at the leader's speed (capped by the limit) when the gap is at
                // least IDM's equilibrium gap s0 + v·T for that speed.
                let limit = self.scene.routes[route].speed_limit_mps;
                match self.leader(usize::MAX, route, s, length) {
                    None => {
                        placed = Some((route, f64::INFINITY, limit));
                        break;
                    }
                    Some((gap, j)) => {
                        let v = self.vehicles[j].v.min(limit);
                        if gap >= vc.min_gap_m + v * vc.time_headway_s {
                            placed = Some((route, gap, v));
                            break;
                        }
                    }
                }
            }
            let Some((route, gap, v_lead)) = placed else {
                return;
            };
            self.pending[e].remove(0);
            self.next_id += 1;
            let vc = &self.config.vehicles;
            let limit = self.scene.routes[route].speed_limit_mps;
            let v0 = limit * normal(&mut arng, cc.speed_factor, vc.desired_speed_sd);
            let v = if gap.is_finite() { v0.min(v_lead) } else { v0 };
            let colour_idx = pick(&mut arng, vc.colours.iter().map(|c| c.share));
            let colour = jitter_colour(&mut arng, vc.colours[colour_idx].rgb, 0.04);
            let secondary = if arng.random::<f64>() < 0.7 {
                jitter_colour(&mut arng, [225, 225, 220], 0.03)
            } else {
                jitter_colour(&mut arng, [170, 174, 178], 0.05)
            };
            let height = cc.height_m * normal(&mut arng, 1.0, 0.03);
            let (pos, heading) = self.scene.routes[route].path.at(length / 2.0);
            self.vehicles.push(Vehicle {
                state: AgentState {
                    id,
                    class: p.class.clone(),
                    pos_m: pos,
                    heading_rad: heading,
                    speed_mps: v,
                    length_m: length,
                    width_m: width,
                    height_m: height,
                    colour,
                    secondary,
                },
                route,
                s: length / 2.0,
                v,
                v0,
                a_max: cc.max_accel_mps2,
                lane_change: None,
                next_lane_check_s: self.time_s + 5.0 + arng.random::<f64>(),
            });
            self.index();
        }
    }

    fn spawn_group(&mut self, e: usize) {
        let entry = &self.scene.pedestrian_entries[e];
        if entry.routes.is_empty() {
            return;
        }
        let r = pick(&mut self.rng, entry.routes.iter().map(|x| x.1));
        let route = self.scene.pedestrian_routes[entry.routes[r].0].clone();
        let pc = self.config.pedestrians.clone();
        let n = 1 + poisson(&mut self.rng, pc.mean_companions);
        let speed = normal(&mut self.rng, pc.speed_mps[0], pc.speed_mps[1]).clamp(0.6, 2.2);
        let max_off = self.scene.pedestrian_max_offset_m;
        let centre = (self.rng.random::<f64>() * 2.0 - 1.0) * max_off * 0.6;
        for k in 0..n {
            let id = self.next_id;
            self.next_id += 1;
            let mut prng = rng_for(self.seed, Stream::Scenario, id);
            let lateral = (centre + (f64::from(k % 3) - 1.0) * 0.65 + normal(&mut prng, 0.0, 0.1))
                .clamp(-max_off, max_off);
            let path = route.path.offset(lateral);
            let crossings = route
                .crossings
                .iter()
                .map(|c| RouteCrossing {
                    kerb_s: path.vertex_s(c.kerb_vertex),
                    far_s: path.vertex_s(c.kerb_vertex + 1),
                    ..*c
                })
                .collect();
            let s = -(f64::from(k / 3) * 0.9) - prng.random::<f64>() * 0.3;
            let height = normal(&mut prng, pc.height_m[0], pc.height_m[1]);
            let (pos, heading) = path.at(s);
            let top_idx = prng.random_range(0..TOPS.len());
            let top = jitter_colour(&mut prng, TOPS[top_idx], 0.06);
            let bottom = BOTTOMS[prng.random_range(0..BOTTOMS.len())];
            self.pedestrians.push(Pedestrian {
                state: AgentState {
                    id,
                    class: ObjectClass::Pedestrian,
                    pos_m: pos,
                    heading_rad: heading,
                    speed_mps: 0.0,
                    length_m: 0.3 * height / 1.68,
                    width_m: pc.shoulder_width_m * height / 1.68,
                    height_m: height,
                    colour: top,
                    secondary: bottom,
                },
                path,
                crossings,
                s,
                v0: speed * normal(&mut prng, 1.0, 0.03),
                wait_back_m: 0.2 + prng.random::<f64>() * 2.2,
            });
        }
    }

    fn desired_speed(&self, v: &Vehicle) -> f64 {
        let route = &self.scene.routes[v.route];
        let b = self.config.vehicles.comfort_decel_mps2;
        let front = v.s + v.state.length_m / 2.0;
        let mut v0 = v.v0;
        let mut cap = |start: f64, end: f64, vmax: f64| {
            if v.s - v.state.length_m / 2.0 < end {
                let d = (start - front).max(0.0);
                v0 = v0.min((vmax * vmax + 2.0 * b * d).sqrt());
            }
        };
        if let Some([start, end, vmax]) = route.turn {
            cap(start, end, vmax);
        }
        if route.lane.is_some()
            && let Some([start, end, vmax]) = self.config.road.slow_zone
        {
            cap(start, end, vmax);
        }
        v0
    }

    /// The acceleration of vehicle `i` on `route` at `s` with leader data.
    fn accel(&self, i: usize, leader: Option<(f64, usize)>) -> f64 {
        let v = &self.vehicles[i];
        let v0 = self.desired_speed(v);
        let mut obstacle = leader.map(|(g, j)| (g, v.v - self.vehicles[j].v));
        if let (Some((stop_s, group)), Some(plan)) =
            (self.scene.routes[v.route].stop, self.scene.signal.as_ref())
        {
            let front = v.s + v.state.length_m / 2.0;
            let d = stop_s - front;
            if d > -0.5 {
                let needed = v.v * v.v / (2.0 * d.max(0.01));
                let vc = &self.config.vehicles;
                let stop = match plan.light(group, self.time_s) {
                    Light::Green => false,
                    Light::Yellow => needed <= vc.comfort_decel_mps2 * 1.5,
                    Light::Red => needed <= vc.max_decel_mps2,
                };
                if stop && obstacle.is_none_or(|(g, _)| d.max(0.01) < g) {
                    obstacle = Some((d.max(0.01), v.v));
                }
            }
        }
        idm(v.v, v0, obstacle, v.a_max, &self.config)
    }

    fn move_vehicles(&mut self, dt: f64) {
        let n = self.vehicles.len();
        let mut updates = Vec::with_capacity(n);
        for i in 0..n {
            let v = &self.vehicles[i];
            let leader = self.leader(i, v.route, v.s, v.state.length_m);
            // A vehicle still moving across also watches the lane it is leaving.
            let old_leader = v
                .lane_change
                .and_then(|(from, _)| self.leader(i, from, v.s, v.state.length_m));
            let leader = match (leader, old_leader) {
                (Some(a), Some(b)) => Some(if a.0 <= b.0 { a } else { b }),
                (a, b) => a.or(b),
            };
            let acc = self.accel(i, leader);
            let mut v_new = v.v + acc * dt;
            let mut ds = if v_new < 0.0 {
                v_new = 0.0;
                if acc < 0.0 {
                    -v.v * v.v / (2.0 * acc)
                } else {
                    0.0
                }
            } else {
                v.v * dt + 0.5 * acc * dt * dt
            };
            if let Some((gap, _)) = leader {
                // Collision guard (module doc).
                let allowed = (gap - 0.2).max(0.0);
                if ds > allowed {
                    ds = allowed;
                    v_new = v_new.min(allowed / dt);
                }
            }
            updates.push((ds.max(0.0), v_new));
        }
        for (v, (ds, v_new)) in self.vehicles.iter_mut().zip(updates) {
            v.s += ds;
            v.v = v_new;
            if let Some((from, left)) = v.lane_change {
                let left = left - dt;
                v.lane_change = if left <= 0.0 {
                    None
                } else {
                    Some((from, left))
                };
            }
        }
        let routes = &self.scene.routes;
        self.vehicles
            .retain(|v| v.s - v.state.length_m / 2.0 < routes[v.route].path.length_m() + 25.0);
    }

    fn lane_changes(&mut self) {
        if self.scene.lane_routes.len() < 2 {
            return;
        }
        let vc = self.config.vehicles.clone();
        let road_len = self.config.road.length_m;
        let n = self.vehicles.len();
        for i in 0..n {
            let v = &self.vehicles[i];
            if v.lane_change.is_some()
                || self.time_s < v.next_lane_check_s
                || v.s < 30.0
                || v.s > road_len - 40.0
            {
                continue;
            }
            let Some(lane) = self.scene.routes[v.route].lane else {
                continue;
            };
            let (s, len) = (v.s, v.state.length_m);
            let leader = self.leader(i, v.route, s, len);
            let a_old = self.accel(i, leader);
            let old_follower = self.follower(i, v.route, s, len);
            let mut best: Option<(f64, usize)> = None;
            for target in [lane.wrapping_sub(1), lane + 1] {
                let Some(&troute) = self.scene.lane_routes.get(target) else {
                    continue;
                };
                let new_leader = self.leader(i, troute, s, len);
                let new_follower = self.follower(i, troute, s, len);
                if new_leader.is_some_and(|(g, _)| g < vc.min_gap_m)
                    || new_follower.is_some_and(|(g, _)| g < vc.min_gap_m)
                {
                    continue;
                }
                let mut tmp = self.vehicles[i].clone();
                tmp.route = troute;
                let a_new = {
                    let v0 = self.desired_speed(&tmp);
                    idm(
                        tmp.v,
                        v0,
                        new_leader.map(|(g, j)| (g, tmp.v - self.vehicles[j].v)),
                        tmp.a_max,
                        &self.config,
                    )
                };
                let mut followers_gain = 0.0;
                if let Some((g, j)) = new_follower {
                    let f = &self.vehicles[j];
                    let fv0 = self.desired_speed(f);
                    let before = self.accel(j, self.leader(j, f.route, f.s, f.state.length_m));
                    let after = idm(f.v, fv0, Some((g, f.v - tmp.v)), f.a_max, &self.config);
                    if after < -vc.safe_decel_mps2 {
                        continue;
                    }
                    followers_gain += after - before;
                }
                if let Some((g, j)) = old_follower {
                    let f = &self.vehicles[j];
                    let fv0 = self.desired_speed(f);
                    let before = self.accel(j, Some((g, i)));
                    let after_gap = leader.map(|(lg, l)| (g + len + lg, f.v - self.vehicles[l].v));
                    let after = idm(f.v, fv0, after_gap, f.a_max, &self.config);
                    followers_gain += after - before;
                }
                let bias = if target < lane {
                    vc.keep_right_bias_mps2
                } else {
                    -vc.keep_right_bias_mps2
                };
                let incentive = a_new - a_old + vc.politeness * followers_gain + bias;
                if incentive > vc.lane_change_threshold_mps2 && best.is_none_or(|b| incentive > b.0)
                {
                    best = Some((incentive, troute));
                }
            }
            let t = self.time_s;
            let v = &mut self.vehicles[i];
            v.next_lane_check_s = t + 1.0;
            if let Some((_, troute)) = best {
                v.lane_change = Some((v.route, vc.lane_change_duration_s));
                v.route = troute;
                v.next_lane_check_s = t + vc.lane_change_duration_s + 2.0;
                self.index();
            }
        }
    }

    fn move_pedestrians(&mut self, dt: f64) {
        let t = self.time_s;
        let plan = self.scene.signal.clone();
        for p in &mut self.pedestrians {
            let mut target = f64::INFINITY;
            let mut speed = p.v0;
            for c in &p.crossings {
                if p.s < c.kerb_s {
                    let light = plan
                        .as_ref()
                        .map_or(Light::Green, |pl| pl.light(c.group, t));
                    if light != Light::Green {
                        target = c.kerb_s - p.wait_back_m;
                    }
                    break;
                }
                if p.s < c.far_s {
                    // On the crosswalk: hurry if the walk signal has ended.
                    let light = plan
                        .as_ref()
                        .map_or(Light::Green, |pl| pl.light(c.group, t));
                    if light != Light::Green {
                        speed *= 1.3;
                    }
                    break;
                }
            }
            let next = p.s + speed * dt;
            let new_s = if p.s >= target { p.s } else { next.min(target) };
            p.state.speed_mps = (new_s - p.s) / dt;
            p.s = new_s;
        }
        self.pedestrians.retain(|p| p.s < p.path.length_m() + 1.0);
    }

    fn update_states(&mut self) {
        let dur = self.config.vehicles.lane_change_duration_s;
        for v in &mut self.vehicles {
            let route = &self.scene.routes[v.route];
            let (mut pos, mut heading) = route.path.at(v.s);
            if let Some((from, left)) = v.lane_change {
                let (p_from, _) = self.scene.routes[from].path.at(v.s);
                // Smoothstep lateral move from the old lane (u = 0) to the new (u = 1).
                let u = (1.0 - left / dur).clamp(0.0, 1.0);
                let w = u * u * (3.0 - 2.0 * u);
                let dw = 6.0 * u * (1.0 - u) / dur;
                let d = [pos[0] - p_from[0], pos[1] - p_from[1]];
                pos = [p_from[0] + d[0] * w, p_from[1] + d[1] * w];
                let lateral_speed = (d[0] * -heading.sin() + d[1] * heading.cos()) * dw;
                heading += lateral_speed.atan2(v.v.max(0.5));
            }
            v.state.pos_m = pos;
            v.state.heading_rad = heading;
            v.state.speed_mps = v.v;
        }
        for p in &mut self.pedestrians {
            let (pos, heading) = p.path.at(p.s);
            p.state.pos_m = pos;
            p.state.heading_rad = heading;
        }
    }
}

impl Vehicle {
    /// The lanes (route, arc length) this vehicle occupies: its own, and during a lane
    /// change also the one it is leaving.
    fn occupied(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        std::iter::once((self.route, self.s))
            .chain(self.lane_change.map(|(from, _)| (from, self.s)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SceneKind;

    fn run(cfg: &SimConfig, seed: u64, seconds: f64, mut check: impl FnMut(&Traffic)) {
        let scene = Scene::build(cfg, 0.3);
        let mut t = Traffic::new(scene, cfg, seed);
        let steps = (seconds / 0.1) as usize;
        for _ in 0..steps {
            t.step(0.1);
            check(&t);
        }
    }

    #[test]
    fn idm_accelerates_on_a_free_road_and_brakes_behind_a_stopped_car() {
        let c = SimConfig::default();
        assert!(idm(10.0, 16.0, None, 1.5, &c) > 0.0);
        assert!(idm(10.0, 16.0, Some((5.0, 10.0)), 1.5, &c) < -2.0);
        // Equilibrium: at v0 with a large gap the acceleration is about 0.
        assert!(idm(16.0, 16.0, Some((1e6, 0.0)), 1.5, &c).abs() < 1e-6);
    }

    #[test]
    fn vehicles_never_overlap_in_the_same_lane() {
        let cfg = SimConfig {
            road: crate::config::RoadConfig {
                inflow_veh_per_h: 2600.0,
                slow_zone: Some([400.0, 500.0, 4.0]),
                ..Default::default()
            },
            ..SimConfig::default()
        };
        let mut max_seen = 0;
        let mut changes = 0;
        run(&cfg, 3, 150.0, |t| {
            let lanes = t.vehicle_lanes();
            max_seen = max_seen.max(lanes.len());
            changes += lanes.iter().filter(|l| l.4.is_some()).count();
            for lane in 0..2usize {
                let mut occ: Vec<(f64, f64, u64)> = lanes
                    .iter()
                    .filter(|l| l.1 == lane || l.4 == Some(lane))
                    .map(|l| (l.2, l.3, l.0))
                    .collect();
                occ.sort_by(|a, b| a.0.total_cmp(&b.0));
                for w in occ.windows(2) {
                    let gap = w[1].0 - w[0].0 - (w[0].1 + w[1].1) / 2.0;
                    assert!(
                        gap >= 0.0,
                        "vehicles {} and {} overlap by {gap} m in lane {lane} at t = {}",
                        w[0].2,
                        w[1].2,
                        t.time_s()
                    );
                }
            }
        });
        assert!(max_seen > 40, "too few vehicles: {max_seen}");
        assert!(changes > 0, "no lane changes happened");
    }

    #[test]
    fn pedestrians_are_on_the_carriageway_only_on_crosswalks() {
        for scene in [SceneKind::Crossing, SceneKind::Intersection] {
            let cfg = SimConfig {
                scene,
                ..SimConfig::default()
            };
            let mut crossed = 0;
            run(&cfg, 5, 200.0, |t| {
                for a in t
                    .states()
                    .iter()
                    .filter(|a| a.class == ObjectClass::Pedestrian)
                {
                    let on_road = t.scene().on_carriageway(a.pos_m);
                    if on_road {
                        crossed += 1;
                        assert!(
                            t.scene().on_crosswalk(a.pos_m),
                            "pedestrian {} at {:?} off the crosswalk",
                            a.id,
                            a.pos_m
                        );
                    }
                }
            });
            assert!(crossed > 100, "{scene:?}: nobody crossed ({crossed})");
        }
    }

    #[test]
    fn pedestrians_do_not_start_crossing_on_red() {
        let cfg = SimConfig {
            scene: SceneKind::Crossing,
            ..SimConfig::default()
        };
        let scene = Scene::build(&cfg, 0.3);
        let plan = scene.signal.clone().expect("crossing has a signal");
        let mut t = Traffic::new(scene, &cfg, 9);
        let mut prev: std::collections::HashMap<u64, Vec2> = Default::default();
        for _ in 0..1500 {
            t.step(0.1);
            let light = plan.light(super::super::scene::PEDESTRIANS, t.time_s() - 0.1);
            for a in t
                .states()
                .iter()
                .filter(|a| a.class == ObjectClass::Pedestrian)
            {
                let was_on = prev
                    .get(&a.id)
                    .is_some_and(|p| t.scene().on_carriageway(*p));
                if t.scene().on_carriageway(a.pos_m) && !was_on && prev.contains_key(&a.id) {
                    assert_eq!(
                        light,
                        Light::Green,
                        "pedestrian {} stepped onto the road on {light:?}",
                        a.id
                    );
                }
            }
            prev = t.states().iter().map(|a| (a.id, a.pos_m)).collect();
        }
    }
}
