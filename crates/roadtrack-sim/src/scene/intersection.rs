//! The `intersection` scene: the signalised intersection.

use super::geometry::rot;
use super::routes::Network;
use super::*;

impl Scene {
    pub(super) fn intersection(config: &SimConfig) -> Scene {
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
}
