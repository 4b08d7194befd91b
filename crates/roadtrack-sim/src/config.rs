//! Simulator configuration (`roadtrack simulate --config F.toml`).
//!
//! Every struct has `Default` = the documented scenario and accepts partial TOML
//! (`#[serde(default, deny_unknown_fields)]`): a file that sets one field keeps every other
//! default, and a misspelt key is an error. The defaults follow seed 000's experiment
//! (a 700 m, two-lane, one-way road seen at 0.33 m/px, METHODS.md §1) and seed 002's
//! camera (about 8 m above a crossing, METHODS.md §2); the rest are ordinary traffic
//! engineering values, marked `Choice:` where the papers are silent.

use roadtrack_core::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Which scenario to simulate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum SceneKind {
    /// A straight one-way road (seed 000's setting).
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "Straight one-way road, 700 m, 2 lanes (seed 000)")
    )]
    Road,
    /// A signalised four-way crossing with pedestrians.
    #[cfg_attr(
        feature = "clap",
        value(help = "Signalised 4-way intersection with pedestrians")
    )]
    Intersection,
    /// A busy signalised mid-block crosswalk (seed 002's scene).
    #[cfg_attr(
        feature = "clap",
        value(help = "Busy crosswalk, groups of pedestrians (seed 002)")
    )]
    Crossing,
}

/// How the camera sees the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum ViewKind {
    /// Straight down, orthographic, fixed metres per pixel (seed 000).
    #[default]
    #[cfg_attr(feature = "clap", value(help = "Nadir, 0.33 m/px"))]
    Aerial,
    /// A pinhole camera on a pole, tilted down (seed 002).
    #[cfg_attr(
        feature = "clap",
        value(help = "Pinhole camera on a pole, about 8 m up")
    )]
    Oblique,
}

/// Image file format of `img1/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum ImageFormat {
    /// JPEG (MOTChallenge's format; about 15× smaller than PNG on noisy frames).
    #[default]
    #[cfg_attr(feature = "clap", value(help = "JPEG (MOTChallenge's format)"))]
    Jpeg,
    /// Lossless PNG.
    Png,
}

impl std::str::FromStr for SceneKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "road" => Ok(Self::Road),
            "intersection" => Ok(Self::Intersection),
            "crossing" => Ok(Self::Crossing),
            _ => Err(Error::Invalid(format!(
                "unknown scene {s:?}: expected road, intersection or crossing"
            ))),
        }
    }
}

impl std::str::FromStr for ViewKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "aerial" => Ok(Self::Aerial),
            "oblique" => Ok(Self::Oblique),
            _ => Err(Error::Invalid(format!(
                "unknown view {s:?}: expected aerial or oblique"
            ))),
        }
    }
}

/// Everything `roadtrack simulate` needs besides the seed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// Scenario. Default `road`.
    pub scene: SceneKind,
    /// Camera. Default `aerial`.
    pub view: ViewKind,
    /// Number of frames written. Default 300.
    pub frames: u32,
    /// Frame rate, frames/s. Default 10 (issue 3).
    pub fps: f64,
    /// Image width, px. Default 640.
    pub width: u32,
    /// Image height, px. Default 480.
    pub height: u32,
    /// Traffic simulated before frame 1 so the scene starts populated, s. Default 60.
    pub warmup_s: f64,
    /// Traffic time step, s; each frame interval is split into whole steps no longer
    /// than this. Default 0.1.
    pub max_step_s: f64,
    /// Image format of `img1/`. Default `jpeg`.
    pub image_format: ImageFormat,
    /// JPEG quality 1–100. Default 92.
    pub jpeg_quality: u8,
    /// The `road` scene.
    pub road: RoadConfig,
    /// The `intersection` scene.
    pub intersection: IntersectionConfig,
    /// The `crossing` scene.
    pub crossing: CrossingConfig,
    /// Vehicle classes, sizes, colours and driver models.
    pub vehicles: VehicleConfig,
    /// Pedestrian sizes, speeds and groups.
    pub pedestrians: PedestrianConfig,
    /// The `aerial` view.
    pub aerial: AerialConfig,
    /// The `oblique` view.
    pub oblique: ObliqueConfig,
    /// Sensor, illumination, shadows, jitter.
    pub render: SimRenderConfig,
    /// Simulated detector (`det/det.txt`, `det/detections.csv`).
    pub detections: DetectionNoiseConfig,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            scene: SceneKind::Road,
            view: ViewKind::Aerial,
            frames: 300,
            fps: 10.0,
            width: 640,
            height: 480,
            warmup_s: 60.0,
            max_step_s: 0.1,
            image_format: ImageFormat::Jpeg,
            jpeg_quality: 92,
            road: RoadConfig::default(),
            intersection: IntersectionConfig::default(),
            crossing: CrossingConfig::default(),
            vehicles: VehicleConfig::default(),
            pedestrians: PedestrianConfig::default(),
            aerial: AerialConfig::default(),
            oblique: ObliqueConfig::default(),
            render: SimRenderConfig::default(),
            detections: DetectionNoiseConfig::default(),
        }
    }
}

/// The `road` scene: a straight one-way road along ground `+x` from `x = 0`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RoadConfig {
    /// Length, m. Default 700 (seed 000: "about 700 m, one direction, 2 lanes").
    pub length_m: f64,
    /// Lanes, all in one direction. Default 2 (seed 000).
    pub lanes: u32,
    /// Lane width, m. Default 3.5.
    pub lane_width_m: f64,
    /// Mean arrivals at the upstream end (Poisson), vehicles/h over all lanes. Default 3 000,
    /// which keeps about 48 vehicles on the 700 m (seed 000's frames had 47 and 48).
    pub inflow_veh_per_h: f64,
    /// Speed limit, m/s; drivers' desired speeds scatter around it. Default 16.7 (60 km/h).
    pub speed_limit_mps: f64,
    /// Optional slow zone (works, a sag, a tunnel) that makes congestion: `[start_m, end_m,
    /// speed_mps]`. Default none.
    pub slow_zone: Option<[f64; 3]>,
}

impl Default for RoadConfig {
    fn default() -> Self {
        Self {
            length_m: 700.0,
            lanes: 2,
            lane_width_m: 3.5,
            inflow_veh_per_h: 3000.0,
            speed_limit_mps: 16.7,
            slow_zone: None,
        }
    }
}

/// The `intersection` scene: two crossing four-lane roads (2 lanes per approach) with a
/// fixed-time signal and an exclusive pedestrian phase.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IntersectionConfig {
    /// Length of each arm from the centre, m. Default 120.
    pub arm_length_m: f64,
    /// Lane width, m. Default 3.25.
    pub lane_width_m: f64,
    /// Sidewalk width, m. Default 3.
    pub sidewalk_width_m: f64,
    /// Crosswalk width (along the road), m. Default 4.
    pub crosswalk_width_m: f64,
    /// Mean arrivals per approach (Poisson), vehicles/h. Default 360.
    pub inflow_veh_per_h_per_approach: f64,
    /// Speed limit, m/s. Default 13.9 (50 km/h).
    pub speed_limit_mps: f64,
    /// Share of arrivals turning left (inner lane). Default 0.2.
    pub left_turn_share: f64,
    /// Share of arrivals turning right (outer lane, with straight-on traffic). Default 0.2.
    pub right_turn_share: f64,
    /// Pedestrian groups arriving per minute at each of the 8 sidewalk ends. Default 2.
    pub pedestrian_groups_per_min_per_entry: f64,
    /// Signal timing.
    pub signal: IntersectionSignalConfig,
}

impl Default for IntersectionConfig {
    fn default() -> Self {
        Self {
            arm_length_m: 120.0,
            lane_width_m: 3.25,
            sidewalk_width_m: 3.0,
            crosswalk_width_m: 4.0,
            inflow_veh_per_h_per_approach: 360.0,
            speed_limit_mps: 13.9,
            left_turn_share: 0.2,
            right_turn_share: 0.2,
            pedestrian_groups_per_min_per_entry: 2.0,
            signal: IntersectionSignalConfig::default(),
        }
    }
}

/// Fixed-time signal plan of the intersection: N–S through and right, N–S left, E–W
/// through and right, E–W left, pedestrians (all crosswalks), each followed by yellow and
/// all-red.
// Choice: protected left turns and an exclusive pedestrian phase (as at Japanese scramble
// crossings) mean no movement ever has to yield, so the simulator needs no gap-acceptance
// model and crossing paths never meet.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IntersectionSignalConfig {
    /// Green of each through-and-right phase, s. Default 24.
    pub through_green_s: f64,
    /// Green of each protected left-turn phase, s. Default 8.
    pub left_green_s: f64,
    /// Walk time of the pedestrian phase, s. Default 15.
    pub pedestrian_green_s: f64,
    /// Yellow (flashing for pedestrians) after each green, s. Default 3.
    pub yellow_s: f64,
    /// All-red after each yellow, s. Default 2.
    pub all_red_s: f64,
}

impl Default for IntersectionSignalConfig {
    fn default() -> Self {
        Self {
            through_green_s: 24.0,
            left_green_s: 8.0,
            pedestrian_green_s: 15.0,
            yellow_s: 3.0,
            all_red_s: 2.0,
        }
    }
}

/// The `crossing` scene: a two-way road (one lane each way) along ground `x`, centred on a
/// wide signalised crosswalk at `x = 0` with busy sidewalks (seed 002's Fig. 7 setting).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CrossingConfig {
    /// Half length of the road, m (the road spans `−half … +half`). Default 60.
    pub half_length_m: f64,
    /// Lane width, m. Default 3.5.
    pub lane_width_m: f64,
    /// Sidewalk width, m. Default 4.
    pub sidewalk_width_m: f64,
    /// Crosswalk width (along the road), m. Default 6.
    pub crosswalk_width_m: f64,
    /// Mean vehicle arrivals per direction (Poisson), vehicles/h. Default 500.
    pub inflow_veh_per_h_per_direction: f64,
    /// Speed limit, m/s. Default 11.1 (40 km/h).
    pub speed_limit_mps: f64,
    /// Pedestrian groups arriving per minute at each of the 4 sidewalk ends. Default 8.
    pub pedestrian_groups_per_min_per_entry: f64,
    /// Share of pedestrians who use the crosswalk (the rest walk along). Default 0.75.
    pub crossing_share: f64,
    /// Vehicle green, s. Default 25.
    pub vehicle_green_s: f64,
    /// Pedestrian walk time, s. Default 18.
    pub pedestrian_green_s: f64,
    /// Yellow after each green, s. Default 3.
    pub yellow_s: f64,
    /// All-red after each yellow, s. Default 2.
    pub all_red_s: f64,
}

impl Default for CrossingConfig {
    fn default() -> Self {
        Self {
            half_length_m: 60.0,
            lane_width_m: 3.5,
            sidewalk_width_m: 4.0,
            crosswalk_width_m: 6.0,
            inflow_veh_per_h_per_direction: 500.0,
            speed_limit_mps: 11.1,
            pedestrian_groups_per_min_per_entry: 8.0,
            crossing_share: 0.75,
            vehicle_green_s: 25.0,
            pedestrian_green_s: 18.0,
            yellow_s: 3.0,
            all_red_s: 2.0,
        }
    }
}

/// Size and behaviour of one vehicle class.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleClassConfig {
    /// Share of arrivals (normalised over the classes).
    pub share: f64,
    /// Length `[mean, sd]`, m (normal, truncated at ±2.5 sd).
    pub length_m: [f64; 2],
    /// Width `[mean, sd]`, m.
    pub width_m: [f64; 2],
    /// Height, m.
    pub height_m: f64,
    /// Desired speed relative to the speed limit (mean).
    pub speed_factor: f64,
    /// IDM maximum acceleration `a`, m/s².
    pub max_accel_mps2: f64,
}

impl Default for VehicleClassConfig {
    fn default() -> Self {
        Self {
            share: 1.0,
            length_m: [4.5, 0.35],
            width_m: [1.78, 0.07],
            height_m: 1.45,
            speed_factor: 1.0,
            max_accel_mps2: 1.5,
        }
    }
}

/// One entry of the fleet colour distribution.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FleetColour {
    /// Name, for documentation.
    pub name: String,
    /// Share of the fleet.
    pub share: f64,
    /// Paint colour, 8-bit RGB.
    pub rgb: [u8; 3],
}

/// Vehicle classes, the fleet's colours and the driver models (IDM and MOBIL).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleConfig {
    /// Passenger cars: share 0.80, 4.5 ± 0.35 m × 1.78 ± 0.07 m, 1.45 m high.
    pub car: VehicleClassConfig,
    /// Lorries: share 0.08, 9 ± 1.8 m × 2.45 ± 0.05 m, 3.3 m high, 0.9 × limit, a = 0.8.
    pub truck: VehicleClassConfig,
    /// Buses: share 0.04, 11 ± 0.6 m × 2.5 m, 3.1 m high, 0.9 × limit, a = 0.9.
    pub bus: VehicleClassConfig,
    /// Motorcycles: share 0.08, 2.1 ± 0.12 m × 0.8 m, 1.5 m high with rider, a = 2.5.
    pub motorcycle: VehicleClassConfig,
    /// Fleet colours. Default: a typical modern fleet — white 30 %, black 19 %, grey 17 %,
    /// silver 12 %, blue 8 %, red 8 %, beige/brown 2 %, green 2 %, yellow/orange 2 %.
    pub colours: Vec<FleetColour>,
    /// Relative spread (sd) of desired speeds around `speed_factor × limit`. Default 0.1.
    pub desired_speed_sd: f64,
    /// IDM safe time headway `T`, s. Default 1.4.
    pub time_headway_s: f64,
    /// IDM minimum gap `s0`, m. Default 2.
    pub min_gap_m: f64,
    /// IDM comfortable deceleration `b`, m/s². Default 2.
    pub comfort_decel_mps2: f64,
    /// Largest deceleration any vehicle applies, m/s². Default 9.
    pub max_decel_mps2: f64,
    /// MOBIL politeness `p`. Default 0.3.
    pub politeness: f64,
    /// MOBIL switching threshold `Δa_th`, m/s². Default 0.2.
    pub lane_change_threshold_mps2: f64,
    /// MOBIL bias towards the outer (right) lane, m/s². Default 0.3.
    pub keep_right_bias_mps2: f64,
    /// MOBIL safe braking limit `b_safe` for the new follower, m/s². Default 4.
    pub safe_decel_mps2: f64,
    /// Duration of the lateral move of a lane change, s. Default 3.
    pub lane_change_duration_s: f64,
}

impl Default for VehicleConfig {
    fn default() -> Self {
        let colour = |name: &str, share: f64, rgb: [u8; 3]| FleetColour {
            name: name.into(),
            share,
            rgb,
        };
        Self {
            car: VehicleClassConfig {
                share: 0.80,
                ..VehicleClassConfig::default()
            },
            truck: VehicleClassConfig {
                share: 0.08,
                length_m: [9.0, 1.8],
                width_m: [2.45, 0.05],
                height_m: 3.3,
                speed_factor: 0.9,
                max_accel_mps2: 0.8,
            },
            bus: VehicleClassConfig {
                share: 0.04,
                length_m: [11.0, 0.6],
                width_m: [2.5, 0.02],
                height_m: 3.1,
                speed_factor: 0.9,
                max_accel_mps2: 0.9,
            },
            motorcycle: VehicleClassConfig {
                share: 0.08,
                length_m: [2.1, 0.12],
                width_m: [0.8, 0.05],
                height_m: 1.5,
                speed_factor: 1.05,
                max_accel_mps2: 2.5,
            },
            colours: vec![
                colour("white", 0.30, [236, 236, 232]),
                colour("black", 0.19, [22, 22, 26]),
                colour("grey", 0.17, [105, 108, 112]),
                colour("silver", 0.12, [176, 180, 184]),
                colour("blue", 0.08, [30, 62, 130]),
                colour("red", 0.08, [165, 24, 28]),
                colour("beige", 0.02, [178, 152, 112]),
                colour("green", 0.02, [34, 92, 56]),
                colour("yellow", 0.02, [222, 170, 30]),
            ],
            desired_speed_sd: 0.1,
            time_headway_s: 1.4,
            min_gap_m: 2.0,
            comfort_decel_mps2: 2.0,
            max_decel_mps2: 9.0,
            politeness: 0.3,
            lane_change_threshold_mps2: 0.2,
            keep_right_bias_mps2: 0.3,
            safe_decel_mps2: 4.0,
            lane_change_duration_s: 3.0,
        }
    }
}

/// Pedestrians.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PedestrianConfig {
    /// Walking speed `[mean, sd]`, m/s. Default [1.35, 0.2].
    pub speed_mps: [f64; 2],
    /// Height `[mean, sd]`, m. Default [1.68, 0.08].
    pub height_m: [f64; 2],
    /// Shoulder width, m. Default 0.46.
    pub shoulder_width_m: f64,
    /// Mean number of companions of each arriving pedestrian (Poisson). Default 1.
    pub mean_companions: f64,
}

impl Default for PedestrianConfig {
    fn default() -> Self {
        Self {
            speed_mps: [1.35, 0.2],
            height_m: [1.68, 0.08],
            shoulder_width_m: 0.46,
            mean_companions: 1.0,
        }
    }
}

/// The nadir view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AerialConfig {
    /// Ground sample distance, m/px. Default 0.33 (seed 000).
    pub metres_per_pixel: f64,
    /// Ground point at the image centre, m. Default: the scene's centre (for `road`, the
    /// middle of the road: a 640 px frame at 0.33 m/px shows 211 m of the 700 m; use
    /// `width = 2140` or `--pairs` for the whole road).
    pub centre_m: Option<[f64; 2]>,
    /// Ground direction of the image's `+x` axis, degrees. Default 0 (north up).
    pub rotation_deg: f64,
}

impl Default for AerialConfig {
    fn default() -> Self {
        Self {
            metres_per_pixel: 0.33,
            centre_m: None,
            rotation_deg: 0.0,
        }
    }
}

/// The oblique pinhole view. Unset fields take the scene's default placement
/// (documented in `docs/SIMULATOR.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ObliqueConfig {
    /// Camera height above the road, m. Default 8 (seed 002: "about 8 m").
    pub height_m: f64,
    /// Camera ground position `[x_m, y_m]`. Default: per scene.
    pub position_m: Option<[f64; 2]>,
    /// Viewing direction, degrees ccw from ground `+x`. Default: per scene.
    pub yaw_deg: Option<f64>,
    /// Downward tilt of the optical axis below the horizontal, degrees. Default: per scene.
    pub tilt_deg: Option<f64>,
    /// Focal length, px (square pixels, principal point at the image centre). Default:
    /// 0.8 × image width (a 64° horizontal field of view).
    pub focal_px: Option<f64>,
}

impl Default for ObliqueConfig {
    fn default() -> Self {
        Self {
            height_m: 8.0,
            position_m: None,
            yaw_deg: None,
            tilt_deg: None,
            focal_px: None,
        }
    }
}

/// Image formation: sensor noise, illumination, shadows, jitter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimRenderConfig {
    /// Sensor noise, sd in 8-bit grey levels per channel (Gaussian approximation). Default 3.
    pub noise_sd: f64,
    /// Amplitude of the slow global illumination drift (relative gain). Default 0.06.
    pub illumination_drift: f64,
    /// Period of the illumination drift, s. Default 90.
    pub illumination_period_s: f64,
    /// Cast shadows on the ground. Default true.
    pub shadows: bool,
    /// Sun azimuth, degrees ccw from ground `+x`. Default 120.
    pub sun_azimuth_deg: f64,
    /// Sun elevation above the horizon, degrees. Default 55.
    pub sun_elevation_deg: f64,
    /// Camera shake: sd of the per-frame image shift, px (0 = steady). Default 0.
    pub camera_jitter_px: f64,
    /// An object in the image whose faces cover no pixel centre (a walker under 1 px wide
    /// seen from above, between two pixel centres) still draws the pixel under the
    /// centroid of its largest visible face. Default true; false renders as before
    /// 2026-11-30, when such an object vanished from the frame, the truth and `det/`.
    // Choice: a camera integrates light over each pixel, so an object a pixel wide always
    // changes at least one pixel; point sampling made 9 % of the aerial walkers' frames
    // empty (docs/SIMULATOR.md "Objects under a pixel").
    pub min_one_pixel: bool,
}

impl Default for SimRenderConfig {
    fn default() -> Self {
        Self {
            noise_sd: 3.0,
            illumination_drift: 0.06,
            illumination_period_s: 90.0,
            shadows: true,
            sun_azimuth_deg: 120.0,
            sun_elevation_deg: 55.0,
            camera_jitter_px: 0.0,
            min_one_pixel: true,
        }
    }
}

/// The simulated detector that writes `det/`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectionNoiseConfig {
    /// Probability that a visible object is missed in a frame. Default 0.05.
    pub miss_prob: f64,
    /// Objects less visible than this are never detected. Default 0.3.
    pub min_visibility: f64,
    /// Mean false positives per frame (Poisson, uniform over the image). Default 0.5.
    pub false_positives_per_frame: f64,
    /// Sd of the centre's position noise, px. Default 1.
    pub position_sd_px: f64,
    /// Relative sd of the box size noise. Default 0.05.
    pub size_sd: f64,
}

impl Default for DetectionNoiseConfig {
    fn default() -> Self {
        Self {
            miss_prob: 0.05,
            min_visibility: 0.3,
            false_positives_per_frame: 0.5,
            position_sd_px: 1.0,
            size_sd: 0.05,
        }
    }
}

fn check(ok: bool, config: &'static str, field: &'static str, reason: &str) -> Result<()> {
    if ok {
        return Ok(());
    }
    // The field as the file spells it: `road.length_m`, not `RoadConfig.length_m`.
    let table = match config {
        "RoadConfig" => Some("road"),
        "IntersectionConfig" => Some("intersection"),
        "IntersectionSignalConfig" => Some("intersection.signal"),
        "CrossingConfig" => Some("crossing"),
        "VehicleConfig" => Some("vehicles"),
        "PedestrianConfig" => Some("pedestrians"),
        "AerialConfig" => Some("aerial"),
        "ObliqueConfig" => Some("oblique"),
        "SimRenderConfig" => Some("render"),
        "DetectionNoiseConfig" => Some("detections"),
        _ => None,
    };
    let e = Error::config(config, field, reason);
    Err(match table {
        Some(t) => e.in_table(t),
        None => e,
    })
}

fn pos(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

fn nonneg(x: f64) -> bool {
    x.is_finite() && x >= 0.0
}

fn prob(x: f64) -> bool {
    (0.0..=1.0).contains(&x)
}

impl roadtrack_core::config::Validate for SimConfig {
    fn validate(&self) -> Result<()> {
        SimConfig::validate(self)
    }
}

impl SimConfig {
    /// Parses TOML text (partial files keep the defaults); `path` names the source in errors.
    ///
    /// # Errors
    /// Bad TOML, unknown keys, values [`SimConfig::validate`] rejects.
    pub fn from_toml_str(text: &str, path: &std::path::Path) -> Result<Self> {
        let c: Self = toml::from_str(text).map_err(|e| Error::Toml {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        c.validate().map_err(|e| e.in_file(path))?;
        Ok(c)
    }

    /// The configuration as TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }

    /// Checks every value is in range (NaN and ±∞ are out of every range).
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        const C: &str = "SimConfig";
        check(self.frames >= 1, C, "frames", "must be at least 1")?;
        check(pos(self.fps), C, "fps", "must be positive")?;
        check(
            (16..=8192).contains(&self.width) && (16..=8192).contains(&self.height),
            C,
            "width",
            "image size must be 16–8192 px",
        )?;
        check(nonneg(self.warmup_s), C, "warmup_s", "must be ≥ 0")?;
        check(
            pos(self.max_step_s) && self.max_step_s <= 1.0,
            C,
            "max_step_s",
            "must be in (0, 1] s",
        )?;
        // Bounds (docs/FORMATS.md, Limits): the frames, the simulated time and the traffic
        // steps it takes, checked before the warm-up loop starts.
        use roadtrack_core::limits::{MAX_DURATION_S, MAX_FPS, MAX_FRAME, MAX_SIM_STEPS, at_most};
        let limit =
            |r: std::result::Result<(), String>, field| r.map_err(|m| Error::config(C, field, m));
        limit(at_most(self.frames, MAX_FRAME, "frames"), "frames")?;
        limit(at_most(self.fps, MAX_FPS, "frames/s"), "fps")?;
        limit(at_most(self.warmup_s, MAX_DURATION_S, "s"), "warmup_s")?;
        let span_s = self.warmup_s + f64::from(self.frames) / self.fps;
        limit(
            at_most(
                span_s,
                MAX_DURATION_S,
                "simulated s: warmup_s + frames / fps",
            ),
            "frames",
        )?;
        let steps = span_s / self.max_step_s + f64::from(self.frames);
        limit(
            at_most(
                steps.ceil(),
                MAX_SIM_STEPS,
                "traffic steps: (warmup_s + frames / fps) / max_step_s",
            ),
            "max_step_s",
        )?;
        check(
            (1..=100).contains(&self.jpeg_quality),
            C,
            "jpeg_quality",
            "must be 1–100",
        )?;
        let r = &self.road;
        check(
            pos(r.length_m),
            "RoadConfig",
            "length_m",
            "must be positive",
        )?;
        check(
            (1..=6).contains(&r.lanes),
            "RoadConfig",
            "lanes",
            "must be 1–6",
        )?;
        check(
            pos(r.lane_width_m),
            "RoadConfig",
            "lane_width_m",
            "must be positive",
        )?;
        check(
            nonneg(r.inflow_veh_per_h),
            "RoadConfig",
            "inflow_veh_per_h",
            "must be ≥ 0",
        )?;
        check(
            pos(r.speed_limit_mps),
            "RoadConfig",
            "speed_limit_mps",
            "must be positive",
        )?;
        if let Some([a, b, v]) = r.slow_zone {
            check(
                a.is_finite() && b > a && pos(v),
                "RoadConfig",
                "slow_zone",
                "must be [start_m, end_m > start_m, speed_mps > 0]",
            )?;
        }
        let i = &self.intersection;
        const I: &str = "IntersectionConfig";
        check(
            pos(i.lane_width_m) && pos(i.sidewalk_width_m) && pos(i.crosswalk_width_m),
            I,
            "lane_width_m",
            "widths must be positive",
        )?;
        check(
            pos(i.arm_length_m)
                && i.arm_length_m > 4.0 * i.lane_width_m + i.crosswalk_width_m + 20.0,
            I,
            "arm_length_m",
            "too short for the lanes and crosswalk",
        )?;
        check(
            nonneg(i.inflow_veh_per_h_per_approach),
            I,
            "inflow_veh_per_h_per_approach",
            "must be ≥ 0",
        )?;
        check(
            pos(i.speed_limit_mps),
            I,
            "speed_limit_mps",
            "must be positive",
        )?;
        check(
            prob(i.left_turn_share)
                && prob(i.right_turn_share)
                && i.left_turn_share + i.right_turn_share <= 1.0,
            I,
            "left_turn_share",
            "turn shares must be in [0, 1] and sum to at most 1",
        )?;
        check(
            nonneg(i.pedestrian_groups_per_min_per_entry),
            I,
            "pedestrian_groups_per_min_per_entry",
            "must be ≥ 0",
        )?;
        let s = &i.signal;
        check(
            pos(s.through_green_s)
                && pos(s.left_green_s)
                && pos(s.pedestrian_green_s)
                && nonneg(s.yellow_s)
                && nonneg(s.all_red_s),
            "IntersectionSignalConfig",
            "through_green_s",
            "greens must be positive, yellow and all-red ≥ 0",
        )?;
        let c = &self.crossing;
        const X: &str = "CrossingConfig";
        check(
            pos(c.lane_width_m) && pos(c.sidewalk_width_m) && pos(c.crosswalk_width_m),
            X,
            "lane_width_m",
            "widths must be positive",
        )?;
        check(
            pos(c.half_length_m) && c.half_length_m > c.crosswalk_width_m + 20.0,
            X,
            "half_length_m",
            "too short for the crosswalk",
        )?;
        check(
            nonneg(c.inflow_veh_per_h_per_direction)
                && nonneg(c.pedestrian_groups_per_min_per_entry),
            X,
            "inflow_veh_per_h_per_direction",
            "rates must be ≥ 0",
        )?;
        check(
            pos(c.speed_limit_mps),
            X,
            "speed_limit_mps",
            "must be positive",
        )?;
        check(
            prob(c.crossing_share),
            X,
            "crossing_share",
            "must be in [0, 1]",
        )?;
        check(
            pos(c.vehicle_green_s)
                && pos(c.pedestrian_green_s)
                && nonneg(c.yellow_s)
                && nonneg(c.all_red_s),
            X,
            "vehicle_green_s",
            "greens must be positive, yellow and all-red ≥ 0",
        )?;
        let v = &self.vehicles;
        const V: &str = "VehicleConfig";
        let classes = [&v.car, &v.truck, &v.bus, &v.motorcycle];
        for k in classes {
            check(
                nonneg(k.share)
                    && pos(k.length_m[0])
                    && nonneg(k.length_m[1])
                    && pos(k.width_m[0])
                    && nonneg(k.width_m[1])
                    && pos(k.height_m)
                    && pos(k.speed_factor)
                    && pos(k.max_accel_mps2),
                V,
                "car",
                "class sizes, speed factor and acceleration must be positive, share ≥ 0",
            )?;
        }
        check(
            classes.iter().map(|k| k.share).sum::<f64>() > 0.0,
            V,
            "car",
            "class shares sum to 0",
        )?;
        check(
            !v.colours.is_empty()
                && v.colours.iter().all(|c| nonneg(c.share))
                && v.colours.iter().map(|c| c.share).sum::<f64>() > 0.0,
            V,
            "colours",
            "need at least one colour with a positive share",
        )?;
        check(
            nonneg(v.desired_speed_sd) && v.desired_speed_sd < 0.5,
            V,
            "desired_speed_sd",
            "must be in [0, 0.5)",
        )?;
        check(
            pos(v.time_headway_s)
                && pos(v.min_gap_m)
                && pos(v.comfort_decel_mps2)
                && pos(v.max_decel_mps2)
                && v.max_decel_mps2 >= v.comfort_decel_mps2,
            V,
            "time_headway_s",
            "IDM T, s0, b must be positive and max_decel ≥ b",
        )?;
        check(
            nonneg(v.politeness)
                && nonneg(v.lane_change_threshold_mps2)
                && v.keep_right_bias_mps2.is_finite()
                && pos(v.safe_decel_mps2)
                && pos(v.lane_change_duration_s),
            V,
            "politeness",
            "MOBIL parameters out of range",
        )?;
        let p = &self.pedestrians;
        check(
            pos(p.speed_mps[0])
                && nonneg(p.speed_mps[1])
                && pos(p.height_m[0])
                && nonneg(p.height_m[1])
                && pos(p.shoulder_width_m)
                && nonneg(p.mean_companions),
            "PedestrianConfig",
            "speed_mps",
            "sizes and speeds must be positive",
        )?;
        let a = &self.aerial;
        check(
            pos(a.metres_per_pixel) && a.rotation_deg.is_finite(),
            "AerialConfig",
            "metres_per_pixel",
            "must be positive",
        )?;
        let o = &self.oblique;
        check(
            pos(o.height_m),
            "ObliqueConfig",
            "height_m",
            "must be positive",
        )?;
        check(
            o.tilt_deg.is_none_or(|t| t > 0.0 && t < 90.0),
            "ObliqueConfig",
            "tilt_deg",
            "must be in (0, 90) degrees",
        )?;
        check(
            o.focal_px.is_none_or(pos),
            "ObliqueConfig",
            "focal_px",
            "must be positive",
        )?;
        let r = &self.render;
        check(
            nonneg(r.noise_sd)
                && (0.0..0.5).contains(&r.illumination_drift)
                && pos(r.illumination_period_s)
                && nonneg(r.camera_jitter_px)
                && r.sun_elevation_deg > 0.0
                && r.sun_elevation_deg <= 90.0,
            "SimRenderConfig",
            "noise_sd",
            "noise, drift (< 0.5), period, jitter and sun elevation (0, 90] out of range",
        )?;
        check(
            r.sun_azimuth_deg.is_finite(),
            "SimRenderConfig",
            "sun_azimuth_deg",
            "must be finite",
        )?;
        let d = &self.detections;
        check(
            prob(d.miss_prob)
                && prob(d.min_visibility)
                && nonneg(d.false_positives_per_frame)
                && nonneg(d.position_sd_px)
                && nonneg(d.size_sd),
            "DetectionNoiseConfig",
            "miss_prob",
            "probabilities in [0, 1], rates and sds ≥ 0",
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests;
