//! The `crossing` scene: the crossing of seed 002.

use super::routes::Network;
use super::*;

impl Scene {
    pub(super) fn crossing(config: &SimConfig) -> Scene {
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
}
