//! Static scene geometry: road surfaces and markings, vehicle routes, pedestrian routes,
//! crosswalks and signal plans, on the ground plane in metres.

use super::config::{SceneKind, SimConfig};
use std::collections::BinaryHeap;

/// A ground point or vector `[x_m, y_m]`.
pub type Vec2 = [f64; 2];

fn sub(a: Vec2, b: Vec2) -> Vec2 {
    [a[0] - b[0], a[1] - b[1]]
}

fn norm(a: Vec2) -> f64 {
    a[0].hypot(a[1])
}

/// Rotates `p` by `k` quarter turns counter-clockwise.
fn rot(p: Vec2, k: usize) -> Vec2 {
    match k % 4 {
        0 => p,
        1 => [-p[1], p[0]],
        2 => [-p[0], -p[1]],
        _ => [p[1], -p[0]],
    }
}

/// A path on the ground, parametrised by arc length `s` from its first point.
#[derive(Debug, Clone, PartialEq)]
pub struct Polyline {
    points: Vec<Vec2>,
    cum_m: Vec<f64>,
}

impl Polyline {
    /// A path through `points` (consecutive duplicates are dropped).
    pub fn new(points: Vec<Vec2>) -> Self {
        let mut pts: Vec<Vec2> = Vec::with_capacity(points.len());
        for p in points {
            if pts.last().is_none_or(|q| norm(sub(p, *q)) > 1e-9) {
                pts.push(p);
            }
        }
        let mut cum_m = Vec::with_capacity(pts.len());
        let mut acc = 0.0;
        for (i, p) in pts.iter().enumerate() {
            if i > 0 {
                acc += norm(sub(*p, pts[i - 1]));
            }
            cum_m.push(acc);
        }
        Self { points: pts, cum_m }
    }

    /// The vertices.
    pub fn points(&self) -> &[Vec2] {
        &self.points
    }

    /// Total length, m.
    pub fn length_m(&self) -> f64 {
        self.cum_m.last().copied().unwrap_or(0.0)
    }

    /// Arc length of vertex `i`, m.
    pub fn vertex_s(&self, i: usize) -> f64 {
        self.cum_m.get(i).copied().unwrap_or(0.0)
    }

    /// Position and heading (radians, ccw from `+x`) at arc length `s` (clamped to the
    /// path; beyond the ends the path is extended straight).
    pub fn at(&self, s: f64) -> (Vec2, f64) {
        let n = self.points.len();
        if n < 2 {
            return (self.points.first().copied().unwrap_or([0.0, 0.0]), 0.0);
        }
        let i = match self.cum_m.partition_point(|&c| c <= s) {
            0 => 0,
            k if k >= n => n - 2,
            k => k - 1,
        };
        let (a, b) = (self.points[i], self.points[i + 1]);
        let d = sub(b, a);
        let len = norm(d);
        let t = (s - self.cum_m[i]) / len;
        ([a[0] + d[0] * t, a[1] + d[1] * t], d[1].atan2(d[0]))
    }

    /// The path shifted `d` metres to its left (negative: right), with mitred corners so
    /// the shifted path stays parallel to every leg.
    pub fn offset(&self, d: f64) -> Polyline {
        let n = self.points.len();
        if n < 2 || d == 0.0 {
            return self.clone();
        }
        let normal = |i: usize| {
            let v = sub(self.points[i + 1], self.points[i]);
            let l = norm(v);
            [-v[1] / l, v[0] / l]
        };
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let m = if i == 0 {
                normal(0)
            } else if i == n - 1 {
                normal(n - 2)
            } else {
                let (a, b) = (normal(i - 1), normal(i));
                let s = [a[0] + b[0], a[1] + b[1]];
                let dot = 1.0 + a[0] * b[0] + a[1] * b[1];
                if dot < 1e-6 {
                    a
                } else {
                    [s[0] / dot, s[1] / dot]
                }
            };
            out.push([self.points[i][0] + m[0] * d, self.points[i][1] + m[1] * d]);
        }
        Polyline::new(out)
    }
}

/// What a patch of ground is, for the renderer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Surface {
    /// Road surface.
    Asphalt,
    /// Paved footway.
    Sidewalk,
    /// Concrete kerb line.
    Kerb,
    /// White paint (lane lines, stop lines, zebra stripes).
    WhitePaint,
    /// Bare ground / gravel verge.
    Verge,
    /// Lawn or field.
    Grass,
    /// A flat-roofed building lot, seen as plain concrete.
    Lot,
}

/// A convex ground polygon of one surface. Later areas are painted over earlier ones.
#[derive(Debug, Clone, PartialEq)]
pub struct Area {
    /// Vertices, counter-clockwise or clockwise, convex.
    pub polygon: Vec<Vec2>,
    /// Surface.
    pub surface: Surface,
    /// Bounding box `[xmin, ymin, xmax, ymax]`.
    pub bbox: [f64; 4],
}

impl Area {
    fn new(polygon: Vec<Vec2>, surface: Surface) -> Self {
        let mut bbox = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for p in &polygon {
            bbox[0] = bbox[0].min(p[0]);
            bbox[1] = bbox[1].min(p[1]);
            bbox[2] = bbox[2].max(p[0]);
            bbox[3] = bbox[3].max(p[1]);
        }
        Self {
            polygon,
            surface,
            bbox,
        }
    }

    /// An axis-aligned rectangle.
    fn rect(x0: f64, y0: f64, x1: f64, y1: f64, surface: Surface) -> Self {
        let (x0, x1) = (x0.min(x1), x0.max(x1));
        let (y0, y1) = (y0.min(y1), y0.max(y1));
        Self::new(vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]], surface)
    }

    /// Whether `p` is inside (boundary included).
    pub fn contains(&self, p: Vec2) -> bool {
        p[0] >= self.bbox[0]
            && p[0] <= self.bbox[2]
            && p[1] >= self.bbox[1]
            && p[1] <= self.bbox[3]
            && convex_contains(&self.polygon, p)
    }
}

/// Whether convex polygon `poly` contains `p` (boundary included).
pub fn convex_contains(poly: &[Vec2], p: Vec2) -> bool {
    let n = poly.len();
    let mut sign = 0.0f64;
    for i in 0..n {
        let a = poly[i];
        let b = poly[(i + 1) % n];
        let c = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        if c.abs() < 1e-12 {
            continue;
        }
        if sign == 0.0 {
            sign = c.signum();
        } else if c.signum() != sign {
            return false;
        }
    }
    true
}

/// A traffic light state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Light {
    /// Go.
    Green,
    /// Stop if you can (pedestrians: do not start crossing).
    Yellow,
    /// Stop.
    Red,
}

/// One phase of a fixed-time plan: the signal groups that are green.
#[derive(Debug, Clone, PartialEq)]
pub struct Phase {
    /// Groups green in this phase.
    pub groups: Vec<u8>,
    /// Green time, s.
    pub green_s: f64,
    /// Yellow time, s.
    pub yellow_s: f64,
    /// All-red time after the yellow, s.
    pub all_red_s: f64,
}

/// A fixed-time signal plan that cycles through its phases.
#[derive(Debug, Clone, PartialEq)]
pub struct SignalPlan {
    /// Phases in order.
    pub phases: Vec<Phase>,
    /// Time into the cycle at `t = 0`, s (drawn from the seed).
    pub offset_s: f64,
}

impl SignalPlan {
    /// Cycle length, s.
    pub fn cycle_s(&self) -> f64 {
        self.phases
            .iter()
            .map(|p| p.green_s + p.yellow_s + p.all_red_s)
            .sum()
    }

    /// The light of `group` at time `t_s`.
    pub fn light(&self, group: u8, t_s: f64) -> Light {
        let cycle = self.cycle_s();
        if cycle <= 0.0 {
            return Light::Green;
        }
        let mut t = (t_s + self.offset_s).rem_euclid(cycle);
        for p in &self.phases {
            let len = p.green_s + p.yellow_s + p.all_red_s;
            if t < len {
                if !p.groups.contains(&group) {
                    return Light::Red;
                }
                return if t < p.green_s {
                    Light::Green
                } else if t < p.green_s + p.yellow_s {
                    Light::Yellow
                } else {
                    Light::Red
                };
            }
            t -= len;
        }
        Light::Red
    }
}

/// A stretch of a route shared with other routes (a lane between junctions); vehicles
/// look for their leader segment by segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoutePart {
    /// Segment id (shared by every route that uses the same lane stretch).
    pub segment: usize,
    /// Route arc length where the part starts, m.
    pub start_s: f64,
    /// Route arc length where it ends, m.
    pub end_s: f64,
}

/// A path vehicles follow from an entry to an exit.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleRoute {
    /// The centre line.
    pub path: Polyline,
    /// Its lane stretches, in order, covering `[0, length]`.
    pub parts: Vec<RoutePart>,
    /// Stop line (arc length the front must not pass on red) and its signal group.
    pub stop: Option<(f64, u8)>,
    /// Turn: `[start_s, end_s, max_speed_mps]`, driven at most at that speed.
    pub turn: Option<[f64; 3]>,
    /// Lane index on a multi-lane road where lane changes are allowed (0 = outer/right).
    pub lane: Option<usize>,
    /// Speed limit, m/s.
    pub speed_limit_mps: f64,
}

impl VehicleRoute {
    /// The part containing arc length `s` (the last one beyond the end).
    pub fn part_index(&self, s: f64) -> usize {
        self.parts
            .iter()
            .position(|p| s < p.end_s)
            .unwrap_or(self.parts.len().saturating_sub(1))
    }
}

/// Where vehicles arrive: a Poisson stream split over routes.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleEntry {
    /// Mean arrivals, vehicles/s.
    pub rate_per_s: f64,
    /// Routes and their weights.
    pub routes: Vec<(usize, f64)>,
}

/// A crosswalk on a pedestrian route: between these arc lengths the route is on the
/// crosswalk and needs the given signal group (when the scene has signals).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RouteCrossing {
    /// Index of the kerb vertex of the route's path (the same on every offset copy).
    pub kerb_vertex: usize,
    /// Arc length of the kerb node where pedestrians wait, m.
    pub kerb_s: f64,
    /// Arc length of the far kerb node, m.
    pub far_s: f64,
    /// Signal group.
    pub group: u8,
}

/// A walking route (centre line; each walker keeps a lateral offset).
#[derive(Debug, Clone, PartialEq)]
pub struct PedestrianRoute {
    /// Centre line.
    pub path: Polyline,
    /// Crosswalks on it, in order.
    pub crossings: Vec<RouteCrossing>,
}

/// Where pedestrian groups arrive.
#[derive(Debug, Clone, PartialEq)]
pub struct PedestrianEntry {
    /// Mean group arrivals, groups/s.
    pub rate_per_s: f64,
    /// Routes and their weights.
    pub routes: Vec<(usize, f64)>,
}

/// Default placement of the oblique camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPlacement {
    /// Ground position, m.
    pub position_m: Vec2,
    /// Viewing direction, degrees ccw from `+x`.
    pub yaw_deg: f64,
    /// Tilt below horizontal, degrees.
    pub tilt_deg: f64,
}

/// A complete static scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Which scene.
    pub kind: SceneKind,
    /// Ground surfaces, painted in order over grass.
    pub areas: Vec<Area>,
    /// Vehicle routes.
    pub routes: Vec<VehicleRoute>,
    /// Number of distinct route segments.
    pub n_segments: usize,
    /// Vehicle entries.
    pub entries: Vec<VehicleEntry>,
    /// For lane changes: `lanes[i]` is the route of lane `i` (roads only).
    pub lane_routes: Vec<usize>,
    /// Pedestrian routes.
    pub pedestrian_routes: Vec<PedestrianRoute>,
    /// Pedestrian entries.
    pub pedestrian_entries: Vec<PedestrianEntry>,
    /// Largest lateral offset a walker may keep from a route's centre line, m.
    pub pedestrian_max_offset_m: f64,
    /// The signal plan, if any.
    pub signal: Option<SignalPlan>,
    /// Carriageway polygons (where vehicles drive).
    pub carriageway: Vec<Vec<Vec2>>,
    /// Crosswalk polygons (the only places pedestrians may be on the carriageway).
    pub crosswalks: Vec<Vec<Vec2>>,
    /// Centre of interest, m (default aerial centre).
    pub centre_m: Vec2,
    /// Extent of the scene `[xmin, ymin, xmax, ymax]`, m.
    pub extent_m: [f64; 4],
    /// Default oblique camera.
    pub camera: CameraPlacement,
}

/// Signal group ids of the intersection.
const NS_THROUGH: u8 = 0;
const NS_LEFT: u8 = 1;
const EW_THROUGH: u8 = 2;
const EW_LEFT: u8 = 3;
/// Pedestrian signal group (all scenes).
pub const PEDESTRIANS: u8 = 4;
/// Vehicle signal group of the crossing scene.
const CROSSING_VEHICLES: u8 = 5;

/// Dashed line along `x` from `x0` to `x1` at `y`, `width` wide.
fn dashes(areas: &mut Vec<Area>, x0: f64, x1: f64, y: f64, width: f64, dash: f64, gap: f64) {
    let mut x = x0;
    while x < x1 {
        let e = (x + dash).min(x1);
        areas.push(Area::rect(
            x,
            y - width / 2.0,
            e,
            y + width / 2.0,
            Surface::WhitePaint,
        ));
        x += dash + gap;
    }
}

impl Scene {
    /// Builds the scene `config.scene` (the signal offset comes from `signal_offset_u`, a
    /// uniform draw in `[0, 1)`).
    pub fn build(config: &SimConfig, signal_offset_u: f64) -> Scene {
        let mut scene = match config.scene {
            SceneKind::Road => Self::road(config),
            SceneKind::Intersection => Self::intersection(config),
            SceneKind::Crossing => Self::crossing(config),
        };
        if let Some(plan) = scene.signal.as_mut() {
            plan.offset_s = signal_offset_u * plan.cycle_s();
        }
        scene
    }

    fn road(config: &SimConfig) -> Scene {
        let r = &config.road;
        let n = r.lanes as usize;
        let lw = r.lane_width_m;
        let half = n as f64 * lw / 2.0;
        let (x0, x1) = (-150.0, r.length_m + 150.0);
        let mut areas = vec![
            Area::rect(x0, -half - 4.0, x1, half + 4.0, Surface::Verge),
            Area::rect(x0, -half - 1.2, x1, half + 1.2, Surface::Asphalt),
        ];
        // Grass fields and lots alongside, for texture.
        let mut x = x0;
        let mut k = 0;
        while x < x1 {
            let w = 40.0 + 25.0 * ((k * 7 % 5) as f64);
            let surface = if k % 3 == 2 {
                Surface::Lot
            } else {
                Surface::Grass
            };
            areas.push(Area::rect(
                x + 2.0,
                half + 8.0,
                x + w,
                half + 30.0 + 10.0 * (k % 4) as f64,
                surface,
            ));
            areas.push(Area::rect(
                x + 6.0,
                -half - 8.0,
                x + w - 3.0,
                -half - 28.0 - 8.0 * (k % 3) as f64,
                Surface::Grass,
            ));
            x += w + 6.0;
            k += 1;
        }
        areas.push(Area::rect(
            x0,
            half - 0.35,
            x1,
            half - 0.2,
            Surface::WhitePaint,
        ));
        areas.push(Area::rect(
            x0,
            -half + 0.2,
            x1,
            -half + 0.35,
            Surface::WhitePaint,
        ));
        for i in 1..n {
            dashes(&mut areas, x0, x1, -half + i as f64 * lw, 0.15, 6.0, 9.0);
        }
        let mut routes = Vec::new();
        for i in 0..n {
            let y = -half + (i as f64 + 0.5) * lw;
            routes.push(VehicleRoute {
                path: Polyline::new(vec![[0.0, y], [r.length_m, y]]),
                parts: vec![RoutePart {
                    segment: i,
                    start_s: 0.0,
                    end_s: r.length_m,
                }],
                stop: None,
                turn: None,
                lane: Some(i),
                speed_limit_mps: r.speed_limit_mps,
            });
        }
        let entries = vec![VehicleEntry {
            rate_per_s: r.inflow_veh_per_h / 3600.0,
            routes: (0..n).map(|i| (i, 1.0)).collect(),
        }];
        let mid = r.length_m / 2.0;
        Scene {
            kind: SceneKind::Road,
            areas,
            routes,
            n_segments: n,
            entries,
            lane_routes: (0..n).collect(),
            pedestrian_routes: vec![],
            pedestrian_entries: vec![],
            pedestrian_max_offset_m: 0.0,
            signal: None,
            carriageway: vec![vec![
                [0.0, -half],
                [r.length_m, -half],
                [r.length_m, half],
                [0.0, half],
            ]],
            crosswalks: vec![],
            centre_m: [mid, 0.0],
            extent_m: [0.0, -half - 30.0, r.length_m, half + 30.0],
            camera: CameraPlacement {
                position_m: [mid - 40.0, -half - 12.0],
                yaw_deg: 18.0,
                tilt_deg: 13.0,
            },
        }
    }

    fn intersection(config: &SimConfig) -> Scene {
        let c = &config.intersection;
        let lw = c.lane_width_m;
        let w = 2.0 * lw; // half width of each road
        let sw = c.sidewalk_width_m;
        let cw = c.crosswalk_width_m;
        let a = c.arm_length_m;
        let reach = a + 40.0;
        let mut areas = Vec::new();
        // Lots in the four quadrants, then sidewalks, then carriageways.
        for q in 0..4 {
            let p0 = rot([w + sw + 1.0, w + sw + 1.0], q);
            let p1 = rot([reach, reach], q);
            areas.push(Area::rect(p0[0], p0[1], p1[0], p1[1], Surface::Grass));
            let l0 = rot([w + sw + 6.0, w + sw + 6.0], q);
            let l1 = rot([w + sw + 36.0, w + sw + 30.0], q);
            areas.push(Area::rect(l0[0], l0[1], l1[0], l1[1], Surface::Lot));
        }
        for k in 0..2 {
            let q = k;
            for side in [1.0, -1.0] {
                let p0 = rot([-reach, side * w], q);
                let p1 = rot([reach, side * (w + sw)], q);
                areas.push(Area::rect(p0[0], p0[1], p1[0], p1[1], Surface::Sidewalk));
                let k0 = rot([-reach, side * w], q);
                let k1 = rot([reach, side * (w + 0.25)], q);
                areas.push(Area::rect(k0[0], k0[1], k1[0], k1[1], Surface::Kerb));
            }
        }
        let corner = 3.0;
        for q in 0..2 {
            let p0 = rot([-reach, -w], q);
            let p1 = rot([reach, w], q);
            areas.push(Area::rect(p0[0], p0[1], p1[0], p1[1], Surface::Asphalt));
        }
        for q in 0..4 {
            // Chamfered kerb corners so right turns do not clip the footway.
            areas.push(Area::new(
                vec![
                    rot([w, w], q),
                    rot([w + corner, w], q),
                    rot([w, w + corner], q),
                ],
                Surface::Asphalt,
            ));
        }
        let mut crosswalks = Vec::new();
        let x_cross0 = w + 1.0;
        let x_stop = w + 1.0 + cw + 1.0;
        for m in 0..4 {
            // Centre line (solid, outside the junction) and lane dividers.
            let seg = |areas: &mut Vec<Area>, x0: f64, x1: f64, y0: f64, y1: f64| {
                let p0 = rot([x0, y0], m);
                let p1 = rot([x1, y1], m);
                areas.push(Area::rect(p0[0], p0[1], p1[0], p1[1], Surface::WhitePaint));
            };
            seg(&mut areas, x_stop, reach, -0.08, 0.08);
            let mut x = x_stop + 1.0;
            while x < reach {
                seg(&mut areas, x, x + 3.0, lw - 0.06, lw + 0.06);
                seg(&mut areas, x, x + 3.0, -lw - 0.06, -lw + 0.06);
                x += 8.0;
            }
            // Stop line across the inbound lanes (left of the centre line in arm frame).
            seg(&mut areas, x_stop, x_stop + 0.45, 0.0, w);
            // Zebra stripes across the whole road.
            let mut y = -w + 0.3;
            while y + 0.45 < w {
                seg(&mut areas, x_cross0, x_cross0 + cw, y, y + 0.45);
                y += 0.9;
            }
            crosswalks.push(
                [
                    [x_cross0, -w],
                    [x_cross0 + cw, -w],
                    [x_cross0 + cw, w],
                    [x_cross0, w],
                ]
                .map(|p| rot(p, m))
                .to_vec(),
            );
        }
        // Vehicle routes. Segments: inbound (arm m, lane j) = 2m + j; outbound = 8 + 2m + j;
        // connectors 16 + 3m + movement.
        let turn_start = w + corner;
        let mut routes = Vec::new();
        let mut entries = Vec::new();
        let arc = |centre: Vec2, r: f64, a0: f64, a1: f64| -> Vec<Vec2> {
            (0..=16)
                .map(|i| {
                    let t = a0 + (a1 - a0) * f64::from(i) / 16.0;
                    [centre[0] + r * t.cos(), centre[1] + r * t.sin()]
                })
                .collect()
        };
        let a_lat = 2.5;
        let left = c.left_turn_share;
        let right = c.right_turn_share;
        for m in 0..4 {
            let group = if m % 2 == 1 { NS_THROUGH } else { EW_THROUGH };
            let left_group = if m % 2 == 1 { NS_LEFT } else { EW_LEFT };
            let in_len = a - turn_start;
            let mut add = |lane: usize,
                           exit_arm: usize,
                           exit_lane: usize,
                           mid: Vec<Vec2>,
                           turn_r: Option<f64>,
                           group: u8| {
                let y_in = (lane as f64 + 0.5) * lw;
                let y_out = (exit_lane as f64 + 0.5) * lw;
                let mut pts = vec![[a, y_in]];
                pts.extend(mid);
                // Outbound lane in the exit arm's frame, mapped back into the approach frame.
                let k = (exit_arm + 4 - m) % 4;
                pts.push(rot([a, -y_out], k));
                let pts: Vec<Vec2> = pts.into_iter().map(|p| rot(p, m)).collect();
                let path = Polyline::new(pts);
                let total = path.length_m();
                let conn_end = total - (a - turn_start);
                let movement = match (exit_arm + 4 - m) % 4 {
                    2 => 0,
                    1 => 1,
                    _ => 2,
                };
                routes.push(VehicleRoute {
                    parts: vec![
                        RoutePart {
                            segment: 2 * m + lane,
                            start_s: 0.0,
                            end_s: in_len,
                        },
                        RoutePart {
                            segment: 16 + 3 * m + movement,
                            start_s: in_len,
                            end_s: conn_end,
                        },
                        RoutePart {
                            segment: 8 + 2 * exit_arm + exit_lane,
                            start_s: conn_end,
                            end_s: total,
                        },
                    ],
                    path,
                    stop: Some((a - x_stop, group)),
                    turn: turn_r.map(|r| [in_len, conn_end, (a_lat * r).sqrt().max(3.0)]),
                    lane: None,
                    speed_limit_mps: c.speed_limit_mps,
                });
                routes.len() - 1
            };
            let straight = add(
                1,
                (m + 2) % 4,
                1,
                vec![[turn_start, 1.5 * lw], [-turn_start, 1.5 * lw]],
                None,
                group,
            );
            let r_right = turn_start - 1.5 * lw;
            let centre_r = [turn_start, turn_start];
            let right_route = add(
                1,
                (m + 1) % 4,
                1,
                arc(
                    centre_r,
                    r_right,
                    -std::f64::consts::FRAC_PI_2,
                    -std::f64::consts::PI,
                ),
                Some(r_right),
                group,
            );
            let r_left = w + 0.5 * lw;
            let mut mid = vec![[turn_start, 0.5 * lw]];
            mid.extend(arc(
                [w, -w],
                r_left,
                std::f64::consts::FRAC_PI_2,
                std::f64::consts::PI,
            ));
            mid.push([-0.5 * lw, -turn_start]);
            let left_route = add(0, (m + 3) % 4, 0, mid, Some(r_left), left_group);
            entries.push(VehicleEntry {
                rate_per_s: c.inflow_veh_per_h_per_approach / 3600.0,
                routes: vec![
                    (straight, 1.0 - left - right),
                    (right_route, right),
                    (left_route, left),
                ],
            });
        }
        // Pedestrian network (global coordinates): sidewalk centre lines at ±cc.
        let cc = w + sw / 2.0;
        let xc = x_cross0 + cw / 2.0;
        let mut net = Network::default();
        let mut ends = Vec::new();
        for m in 0..4 {
            for side in [1.0, -1.0] {
                let e = net.node(rot([a, side * cc], m));
                let x = net.node(rot([xc, side * cc], m));
                let k = net.node(rot([cc, side * cc], m));
                net.edge(e, x, None);
                net.edge(x, k, None);
                ends.push(e);
            }
            let xp = net.node(rot([xc, cc], m));
            let xm = net.node(rot([xc, -cc], m));
            net.edge(xp, xm, Some(PEDESTRIANS));
        }
        let (pedestrian_routes, pedestrian_entries) = net.routes(
            &ends,
            c.pedestrian_groups_per_min_per_entry / 60.0,
            |_, _| 1.0,
        );
        let cycle = &c.signal;
        let phase = |groups: Vec<u8>, g: f64| Phase {
            groups,
            green_s: g,
            yellow_s: cycle.yellow_s,
            all_red_s: cycle.all_red_s,
        };
        let signal = SignalPlan {
            phases: vec![
                phase(vec![NS_THROUGH], cycle.through_green_s),
                phase(vec![NS_LEFT], cycle.left_green_s),
                phase(vec![EW_THROUGH], cycle.through_green_s),
                phase(vec![EW_LEFT], cycle.left_green_s),
                phase(vec![PEDESTRIANS], cycle.pedestrian_green_s),
            ],
            offset_s: 0.0,
        };
        Scene {
            kind: SceneKind::Intersection,
            areas,
            routes,
            n_segments: 28,
            entries,
            lane_routes: vec![],
            pedestrian_routes,
            pedestrian_entries,
            pedestrian_max_offset_m: (sw.min(cw) / 2.0 - 0.35).max(0.0),
            signal: Some(signal),
            carriageway: vec![
                vec![[-reach, -w], [reach, -w], [reach, w], [-reach, w]],
                vec![[-w, -reach], [w, -reach], [w, reach], [-w, reach]],
            ],
            crosswalks,
            centre_m: [0.0, 0.0],
            extent_m: [-a, -a, a, a],
            camera: CameraPlacement {
                position_m: [-w - sw - 14.0, -w - sw - 8.0],
                yaw_deg: 38.0,
                tilt_deg: 20.0,
            },
        }
    }

    fn crossing(config: &SimConfig) -> Scene {
        let c = &config.crossing;
        let lw = c.lane_width_m;
        let sw = c.sidewalk_width_m;
        let cw = c.crosswalk_width_m;
        let h = c.half_length_m;
        let reach = h + 40.0;
        let mut areas = vec![
            Area::rect(-reach, lw + sw + 1.5, reach, lw + sw + 40.0, Surface::Lot),
            Area::rect(
                -reach,
                -lw - sw - 1.5,
                reach,
                -lw - sw - 40.0,
                Surface::Grass,
            ),
            Area::rect(-reach, -lw - sw, reach, lw + sw, Surface::Sidewalk),
            Area::rect(-reach, -lw - 0.25, reach, lw + 0.25, Surface::Kerb),
            Area::rect(-reach, -lw, reach, lw, Surface::Asphalt),
        ];
        // Tiles of the plaza and planted strips.
        let mut x = -reach;
        while x < reach {
            areas.push(Area::rect(
                x,
                lw + sw + 1.5,
                x + 6.0,
                lw + sw + 4.0,
                Surface::Grass,
            ));
            x += 14.0;
        }
        let stop = cw / 2.0 + 2.0;
        // Centre line, edge lines, stop lines, zebra.
        areas.push(Area::rect(-reach, -0.08, -stop, 0.08, Surface::WhitePaint));
        areas.push(Area::rect(stop, -0.08, reach, 0.08, Surface::WhitePaint));
        areas.push(Area::rect(
            -reach,
            lw - 0.4,
            reach,
            lw - 0.28,
            Surface::WhitePaint,
        ));
        areas.push(Area::rect(
            -reach,
            -lw + 0.28,
            reach,
            -lw + 0.4,
            Surface::WhitePaint,
        ));
        areas.push(Area::rect(
            -stop - 0.45,
            -lw,
            -stop,
            0.0,
            Surface::WhitePaint,
        ));
        areas.push(Area::rect(stop, 0.0, stop + 0.45, lw, Surface::WhitePaint));
        let mut y = -lw + 0.3;
        while y + 0.45 < lw {
            areas.push(Area::rect(
                -cw / 2.0,
                y,
                cw / 2.0,
                y + 0.45,
                Surface::WhitePaint,
            ));
            y += 0.9;
        }
        let route = |from: Vec2, to: Vec2, stop_s: f64| VehicleRoute {
            path: Polyline::new(vec![from, to]),
            parts: vec![],
            stop: Some((stop_s, CROSSING_VEHICLES)),
            turn: None,
            lane: None,
            speed_limit_mps: c.speed_limit_mps,
        };
        let mut east = route([-h, -lw / 2.0], [h, -lw / 2.0], h - stop);
        let mut west = route([h, lw / 2.0], [-h, lw / 2.0], h - stop);
        east.parts = vec![RoutePart {
            segment: 0,
            start_s: 0.0,
            end_s: 2.0 * h,
        }];
        west.parts = vec![RoutePart {
            segment: 1,
            start_s: 0.0,
            end_s: 2.0 * h,
        }];
        let rate = c.inflow_veh_per_h_per_direction / 3600.0;
        let entries = vec![
            VehicleEntry {
                rate_per_s: rate,
                routes: vec![(0, 1.0)],
            },
            VehicleEntry {
                rate_per_s: rate,
                routes: vec![(1, 1.0)],
            },
        ];
        let cc = lw + sw / 2.0;
        let mut net = Network::default();
        let mut ends = Vec::new();
        for side in [1.0, -1.0] {
            let w_end = net.node([-h, side * cc]);
            let x = net.node([0.0, side * cc]);
            let e_end = net.node([h, side * cc]);
            net.edge(w_end, x, None);
            net.edge(x, e_end, None);
            ends.push(w_end);
            ends.push(e_end);
        }
        let xp = net.node([0.0, cc]);
        let xm = net.node([0.0, -cc]);
        net.edge(xp, xm, Some(PEDESTRIANS));
        let share = c.crossing_share;
        let (pedestrian_routes, pedestrian_entries) = net.routes(
            &ends,
            c.pedestrian_groups_per_min_per_entry / 60.0,
            |from: Vec2, to: Vec2| {
                if from[1].signum() == to[1].signum() {
                    1.0 - share
                } else {
                    share / 2.0
                }
            },
        );
        let signal = SignalPlan {
            phases: vec![
                Phase {
                    groups: vec![CROSSING_VEHICLES],
                    green_s: c.vehicle_green_s,
                    yellow_s: c.yellow_s,
                    all_red_s: c.all_red_s,
                },
                Phase {
                    groups: vec![PEDESTRIANS],
                    green_s: c.pedestrian_green_s,
                    yellow_s: c.yellow_s,
                    all_red_s: c.all_red_s,
                },
            ],
            offset_s: 0.0,
        };
        Scene {
            kind: SceneKind::Crossing,
            areas,
            routes: vec![east, west],
            n_segments: 2,
            entries,
            lane_routes: vec![],
            pedestrian_routes,
            pedestrian_entries,
            pedestrian_max_offset_m: (sw.min(cw) / 2.0 - 0.35).max(0.0),
            signal: Some(signal),
            carriageway: vec![vec![[-reach, -lw], [reach, -lw], [reach, lw], [-reach, lw]]],
            crosswalks: vec![vec![
                [-cw / 2.0, -lw],
                [cw / 2.0, -lw],
                [cw / 2.0, lw],
                [-cw / 2.0, lw],
            ]],
            centre_m: [0.0, 0.0],
            extent_m: [-h, -lw - sw - 20.0, h, lw + sw + 20.0],
            camera: CameraPlacement {
                position_m: [-7.0, -lw - sw - 7.0],
                yaw_deg: 62.0,
                tilt_deg: 26.0,
            },
        }
    }

    /// Whether a ground point is on the carriageway.
    pub fn on_carriageway(&self, p: Vec2) -> bool {
        self.carriageway.iter().any(|q| convex_contains(q, p))
    }

    /// Whether a ground point is on a crosswalk.
    pub fn on_crosswalk(&self, p: Vec2) -> bool {
        self.crosswalks.iter().any(|q| convex_contains(q, p))
    }
}

/// A small walking network for building pedestrian routes by shortest paths.
#[derive(Default)]
struct Network {
    nodes: Vec<Vec2>,
    edges: Vec<Vec<(usize, Option<u8>)>>,
}

impl Network {
    fn node(&mut self, p: Vec2) -> usize {
        if let Some(i) = self.nodes.iter().position(|q| norm(sub(*q, p)) < 1e-6) {
            return i;
        }
        self.nodes.push(p);
        self.edges.push(Vec::new());
        self.nodes.len() - 1
    }

    fn edge(&mut self, a: usize, b: usize, group: Option<u8>) {
        if !self.edges[a].iter().any(|e| e.0 == b) {
            self.edges[a].push((b, group));
            self.edges[b].push((a, group));
        }
    }

    /// Shortest path (Dijkstra) between two nodes as node indices.
    fn path(&self, from: usize, to: usize) -> Option<Vec<usize>> {
        #[derive(PartialEq)]
        struct Item(f64, usize);
        impl Eq for Item {}
        impl PartialOrd for Item {
            fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
                Some(self.cmp(o))
            }
        }
        impl Ord for Item {
            fn cmp(&self, o: &Self) -> std::cmp::Ordering {
                o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
            }
        }
        let n = self.nodes.len();
        let mut dist = vec![f64::INFINITY; n];
        let mut prev = vec![usize::MAX; n];
        let mut heap = BinaryHeap::new();
        dist[from] = 0.0;
        heap.push(Item(0.0, from));
        while let Some(Item(d, u)) = heap.pop() {
            if d > dist[u] {
                continue;
            }
            for &(v, _) in &self.edges[u] {
                let nd = d + norm(sub(self.nodes[u], self.nodes[v]));
                if nd < dist[v] {
                    dist[v] = nd;
                    prev[v] = u;
                    heap.push(Item(nd, v));
                }
            }
        }
        if !dist[to].is_finite() {
            return None;
        }
        let mut out = vec![to];
        let mut u = to;
        while u != from {
            u = prev[u];
            out.push(u);
        }
        out.reverse();
        Some(out)
    }

    /// One route per ordered pair of distinct ends, with entry weights from `weight`.
    fn routes(
        &self,
        ends: &[usize],
        rate_per_s: f64,
        weight: impl Fn(Vec2, Vec2) -> f64,
    ) -> (Vec<PedestrianRoute>, Vec<PedestrianEntry>) {
        let mut routes = Vec::new();
        let mut entries = Vec::new();
        for &from in ends {
            let mut entry = PedestrianEntry {
                rate_per_s,
                routes: Vec::new(),
            };
            for &to in ends {
                if to == from {
                    continue;
                }
                let Some(nodes) = self.path(from, to) else {
                    continue;
                };
                let path = Polyline::new(nodes.iter().map(|&i| self.nodes[i]).collect());
                let mut crossings = Vec::new();
                for (k, pair) in nodes.windows(2).enumerate() {
                    let group = self.edges[pair[0]]
                        .iter()
                        .find(|e| e.0 == pair[1])
                        .and_then(|e| e.1);
                    if let Some(g) = group {
                        crossings.push(RouteCrossing {
                            kerb_vertex: k,
                            kerb_s: path.vertex_s(k),
                            far_s: path.vertex_s(k + 1),
                            group: g,
                        });
                    }
                }
                let w = weight(self.nodes[from], self.nodes[to]);
                routes.push(PedestrianRoute { path, crossings });
                entry.routes.push((routes.len() - 1, w));
            }
            entries.push(entry);
        }
        (routes, entries)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polyline_positions_and_mitred_offsets() {
        let p = Polyline::new(vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]]);
        assert_eq!(p.length_m(), 20.0);
        let (q, h) = p.at(15.0);
        assert!((q[0] - 10.0).abs() < 1e-12 && (q[1] - 5.0).abs() < 1e-12);
        assert!((h - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        // Left offset of a left turn: the inner corner moves diagonally inwards.
        let o = p.offset(1.0);
        assert_eq!(o.points()[1], [9.0, 1.0]);
        assert_eq!(o.points()[0], [0.0, 1.0]);
    }

    #[test]
    fn signal_cycles_through_green_yellow_red() {
        let plan = SignalPlan {
            phases: vec![
                Phase {
                    groups: vec![0],
                    green_s: 10.0,
                    yellow_s: 2.0,
                    all_red_s: 1.0,
                },
                Phase {
                    groups: vec![1],
                    green_s: 5.0,
                    yellow_s: 2.0,
                    all_red_s: 1.0,
                },
            ],
            offset_s: 0.0,
        };
        assert_eq!(plan.cycle_s(), 21.0);
        assert_eq!(plan.light(0, 5.0), Light::Green);
        assert_eq!(plan.light(0, 11.0), Light::Yellow);
        assert_eq!(plan.light(0, 12.5), Light::Red);
        assert_eq!(plan.light(1, 14.0), Light::Green);
        assert_eq!(plan.light(0, 21.0 + 5.0), Light::Green);
    }

    #[test]
    fn intersection_routes_start_and_end_on_the_carriageway() {
        let cfg = SimConfig {
            scene: SceneKind::Intersection,
            ..SimConfig::default()
        };
        let s = Scene::build(&cfg, 0.0);
        assert_eq!(s.routes.len(), 12);
        for r in &s.routes {
            for p in r.path.points() {
                assert!(s.on_carriageway(*p), "{p:?}");
            }
            assert!((r.parts.last().map_or(0.0, |p| p.end_s) - r.path.length_m()).abs() < 1e-9);
        }
        // Pedestrian routes touch the carriageway only on crosswalks.
        for r in &s.pedestrian_routes {
            let n = (r.path.length_m() / 0.2) as usize;
            for i in 0..=n {
                let (p, _) = r.path.at(i as f64 * 0.2);
                assert!(!s.on_carriageway(p) || s.on_crosswalk(p), "{p:?}");
            }
        }
    }
}
