//! The `road` scene: the two-lane road of seed 000.

use super::geometry::dashes;
use super::*;

impl Scene {
    pub(super) fn road(config: &SimConfig) -> Scene {
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
}
