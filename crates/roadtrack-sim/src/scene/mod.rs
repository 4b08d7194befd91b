//! Static scene geometry: road surfaces and markings, vehicle routes, pedestrian routes,
//! crosswalks and signal plans, on the ground plane in metres.
//!
//! Files: `geometry.rs` (polylines, areas), `signals.rs`, `routes.rs` (routes, entries and
//! the walking network), one file per scene layout (`road.rs`, `intersection.rs`,
//! `crossing.rs`), `tests.rs`.

mod crossing;
mod geometry;
mod intersection;
mod road;
mod routes;
mod signals;
#[cfg(test)]
mod tests;

pub use geometry::{Area, Polyline, Surface, Vec2, convex_contains};
pub use routes::{
    PedestrianEntry, PedestrianRoute, RouteCrossing, RoutePart, VehicleEntry, VehicleRoute,
};
pub use signals::{Light, Phase, SignalPlan};

use super::config::{SceneKind, SimConfig};

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
    /// Whether a ground point is on the carriageway.
    pub fn on_carriageway(&self, p: Vec2) -> bool {
        self.carriageway.iter().any(|q| convex_contains(q, p))
    }

    /// Whether a ground point is on a crosswalk.
    pub fn on_crosswalk(&self, p: Vec2) -> bool {
        self.crosswalks.iter().any(|q| convex_contains(q, p))
    }
}
