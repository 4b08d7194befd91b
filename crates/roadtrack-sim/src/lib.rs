//! Traffic simulator and renderer with ground truth (issue 3, `roadtrack simulate`).
//!
//! Scenes with known truth for every method of the project: seed 000's two-lane road seen
//! from above at 0.33 m/px (METHODS.md §1), seed 002's crossing seen from about 8 m
//! (METHODS.md §2), and a signalised intersection. See `docs/SIMULATOR.md` for the models.
//!
//! Entry points:
//! - [`simulate`] writes a MOTChallenge sequence folder (`img1/`, `seqinfo.ini`,
//!   `gt/gt.txt`, `det/det.txt`, `det/detections.csv`, `truth.csv`, `calibration.toml`,
//!   `simulation.toml`);
//! - [`simulate_from_trajectories`] renders trajectories made elsewhere (e.g. SUMO);
//! - [`write_pairs`] writes two-frame matching problems for `roadtrack sweep`;
//! - [`Simulation`] (an iterator of [`SimStep`]) and [`simulate_in_memory`] give the same
//!   data without touching the disk, for tests of the trackers;
//! - [`points`] simulates point measurements with known truth (for `roadtrack filter`);
//! - [`testkit`] (feature `testkit`): small generated scenes for other crates' tests and
//!   benchmarks.
//!
//! ```no_run
//! use roadtrack_sim::{SimConfig, SceneKind, ViewKind, simulate_in_memory};
//! let config = SimConfig { scene: SceneKind::Crossing, view: ViewKind::Oblique, frames: 50, ..SimConfig::default() };
//! let run = simulate_in_memory(&config, 7)?;
//! assert_eq!(run.frames.len(), 50);
//! # Ok::<(), roadtrack_core::Error>(())
//! ```

pub mod camera;
pub mod config;
pub mod external;
mod output;
mod pairs;
pub mod points;
mod raster;
pub mod render;
pub mod scene;
#[cfg(feature = "testkit")]
pub mod testkit;
pub mod traffic;

pub use config::{
    AerialConfig, CrossingConfig, DetectionNoiseConfig, ImageFormat, IntersectionConfig,
    ObliqueConfig, PedestrianConfig, RoadConfig, SceneKind, SimConfig, SimRenderConfig,
    VehicleConfig, ViewKind,
};
pub use external::ExternalTrajectories;
pub use output::{
    SimSummary, encode_frame, gt_rows, simulate, simulate_from_trajectories, write_truth_csv,
};
pub use pairs::{PairsConfig, PairsSummary, write_pairs};

use camera::Camera;
use rand::RngExt;
use rand_distr::StandardNormal;
use render::SceneRenderer;
use roadtrack_core::calibration::Calibration;
use roadtrack_core::class::ObjectClass;
use roadtrack_core::detection::Detection;
use roadtrack_core::error::{Error, Result};
use roadtrack_core::frame::Frame;
use roadtrack_core::geometry::{BBox, Point};
use roadtrack_core::rng::{Rng, Stream, rng, rng_for};
use roadtrack_core::track_point::{GroundState, TrackPoint};
use scene::Scene;
use traffic::{AgentState, Traffic};

/// The truth about one object in one frame (one row of `truth.csv`).
#[derive(Debug, Clone, PartialEq)]
pub struct TruthRow {
    /// 1-based frame number.
    pub frame: u32,
    /// Frame time, s: `(frame − 1) / fps`.
    pub time_s: f64,
    /// Object id, stable over the object's life.
    pub id: u64,
    /// Class.
    pub class: ObjectClass,
    /// Ground position of the footprint centre, m.
    pub x_m: f64,
    /// Ground position, m.
    pub y_m: f64,
    /// Image position of the ground point `(x_m, y_m, 0)` in this frame, px (equal to
    /// `calibration.image_from_ground(x_m, y_m)` when there is no camera jitter).
    pub x_px: f64,
    /// Image position, px.
    pub y_px: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Heading, degrees ccw from ground `+x`, in `(−180, 180]`.
    pub heading_deg: f64,
    /// Length, m.
    pub length_m: f64,
    /// Width, m.
    pub width_m: f64,
    /// Height, m.
    pub height_m: f64,
    /// Paint (vehicles) or top (pedestrians) colour before shading, 8-bit RGB.
    pub colour_rgb: [u8; 3],
    /// Fraction of the object's silhouette pixels inside the image not covered by nearer
    /// objects (what `truth.csv` writes; the frame's edge does not count).
    pub visibility: f64,
    /// Share of the object's projected outline inside the image (1 unless the frame's
    /// edge cuts it). `gt.txt` writes `visibility × in_frame`, MOT17's visibility.
    pub in_frame: f64,
    /// Box of the projected object, clipped to the image, px.
    pub bbox: BBox,
    /// Mean colour of the object's visible pixels in the frame (0 when none are visible).
    pub visible_rgb: [f64; 3],
}

impl TruthRow {
    /// The row as a [`TrackPoint`] with its ground state (for comparing with trackers).
    pub fn to_track_point(&self) -> TrackPoint {
        TrackPoint {
            frame: self.frame,
            time_s: self.time_s,
            id: self.id,
            class: self.class.clone(),
            bbox: self.bbox,
            score: 1.0,
            ground: Some(GroundState {
                x_m: self.x_m,
                y_m: self.y_m,
                speed_mps: self.speed_mps,
                heading_deg: self.heading_deg,
            }),
        }
    }
}

/// One simulated frame with its truth and simulated detections.
#[derive(Debug, Clone)]
pub struct SimStep {
    /// The rendered frame.
    pub frame: Frame,
    /// Every object with at least one pixel in the image, sorted by id.
    pub truth: Vec<TruthRow>,
    /// Simulated detections (misses, false positives, noise), in shuffled order.
    pub detections: Vec<Detection>,
}

/// A whole simulated sequence in memory.
#[derive(Debug, Clone)]
pub struct SimRun {
    /// Frames in order.
    pub frames: Vec<Frame>,
    /// Truth rows, by frame then id.
    pub truth: Vec<TruthRow>,
    /// Detections, by frame.
    pub detections: Vec<Detection>,
    /// The image ↔ ground calibration.
    pub calibration: Calibration,
}

enum Source {
    Traffic(Box<Traffic>),
    External(ExternalTrajectories),
}

/// A running simulation: an iterator over [`SimStep`]s, one per frame.
pub struct Simulation {
    config: SimConfig,
    seed: u64,
    source: Source,
    scene: Scene,
    camera: Camera,
    calibration: Calibration,
    renderer: SceneRenderer,
    next_frame: u32,
    n_frames: u32,
    steps_per_frame: u32,
    step_s: f64,
    det_rng: Rng,
    /// Ids of the agents of the last rendered frame, in render order.
    last_agent_ids: Vec<u64>,
}

impl std::fmt::Debug for Simulation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Simulation")
            .field("scene", &self.config.scene)
            .field("view", &self.config.view)
            .field("next_frame", &self.next_frame)
            .field("n_frames", &self.n_frames)
            .finish()
    }
}

impl Simulation {
    /// Builds the scene, warms the traffic up for `config.warmup_s` and renders the
    /// background. Frame 1 shows the traffic at the end of the warm-up.
    ///
    /// # Errors
    /// An invalid configuration.
    pub fn new(config: &SimConfig, seed: u64) -> Result<Self> {
        config.validate()?;
        let scene = Scene::build(config, rng(seed, Stream::Scenario).random::<f64>());
        let mut traffic = Traffic::new(scene.clone(), config, seed);
        let (steps_per_frame, step_s) = steps(config);
        let warm = (config.warmup_s / step_s).round() as u64;
        for _ in 0..warm {
            traffic.step(step_s);
        }
        Self::with_source(
            config,
            seed,
            scene,
            Source::Traffic(Box::new(traffic)),
            config.frames,
            steps_per_frame,
            step_s,
        )
    }

    /// Renders `trajectories` in `config.scene`'s setting and `config.view`: frame `k`
    /// shows time `t_first + (k − 1) / fps`; `frames` defaults to the whole span.
    ///
    /// # Errors
    /// An invalid configuration.
    pub fn from_trajectories(
        config: &SimConfig,
        seed: u64,
        trajectories: ExternalTrajectories,
        frames: Option<u32>,
    ) -> Result<Self> {
        config.validate()?;
        let scene = Scene::build(config, rng(seed, Stream::Scenario).random::<f64>());
        let n = frames.unwrap_or_else(|| trajectories.frames_spanned(config.fps));
        roadtrack_core::limits::at_most(n, roadtrack_core::limits::MAX_FRAME, "frames").map_err(
            |m| {
                Error::Invalid(format!(
                    "the trajectories at {} frames/s make {m}: give fewer frames or a lower \
                     frame rate",
                    config.fps
                ))
            },
        )?;
        let (spf, step_s) = steps(config);
        Self::with_source(
            config,
            seed,
            scene,
            Source::External(trajectories),
            n.max(1),
            spf,
            step_s,
        )
    }

    fn with_source(
        config: &SimConfig,
        seed: u64,
        scene: Scene,
        source: Source,
        n_frames: u32,
        steps_per_frame: u32,
        step_s: f64,
    ) -> Result<Self> {
        let camera = Camera::new(config, &scene, config.width, config.height)?;
        let calibration = camera.calibration()?;
        let renderer = SceneRenderer::new(&scene, &camera, config, seed)?;
        Ok(Self {
            config: config.clone(),
            seed,
            source,
            scene,
            camera,
            calibration,
            renderer,
            next_frame: 1,
            n_frames,
            steps_per_frame,
            step_s,
            det_rng: rng(seed, Stream::Detections),
            last_agent_ids: Vec::new(),
        })
    }

    /// The image ↔ ground calibration (without camera jitter).
    pub fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    /// The static scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The camera (without jitter).
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// Number of frames this simulation yields.
    pub fn n_frames(&self) -> u32 {
        self.n_frames
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Which object each pixel of the last frame shows (row-major, `None` = background),
    /// from the renderer's depth test: the visible pixel sets behind `visibility`. For
    /// measures that need where an object is visible (seed 002 Fig. 10).
    pub fn visible_object_ids(&self) -> Vec<Option<u64>> {
        self.renderer
            .owner()
            .iter()
            .map(|&o| self.last_agent_ids.get(o as usize).copied())
            .collect()
    }

    fn agents(&mut self, frame: u32) -> Vec<AgentState> {
        let t = f64::from(frame - 1) / self.config.fps;
        match &mut self.source {
            Source::Traffic(traffic) => {
                if frame > 1 {
                    for _ in 0..self.steps_per_frame {
                        traffic.step(self.step_s);
                    }
                }
                traffic.states()
            }
            Source::External(ext) => ext.states_at(t, &self.config, self.seed),
        }
    }

    fn step_frame(&mut self) -> SimStep {
        let frame = self.next_frame;
        self.next_frame += 1;
        let time_s = f64::from(frame - 1) / self.config.fps;
        let agents = self.agents(frame);
        let sigma = self.config.render.camera_jitter_px;
        let shift = if sigma > 0.0 {
            let mut r = rng_for(self.seed, Stream::Render, (1 << 40) | u64::from(frame));
            let lim = (sigma * 4.0).ceil();
            let mut d = || {
                let z: f64 = r.sample(StandardNormal);
                (z * sigma).round().clamp(-lim, lim) as i32
            };
            [d(), d()]
        } else {
            [0, 0]
        };
        let cam = self
            .camera
            .shifted([f64::from(shift[0]), f64::from(shift[1])]);
        let (image, pixels) = self.renderer.render(&cam, shift, &agents, frame, time_s);
        self.last_agent_ids = agents.iter().map(|a| a.id).collect();
        let mut truth = Vec::new();
        for (a, px) in agents.iter().zip(&pixels) {
            let Some(bbox) = px.bbox else { continue };
            if px.own_px == 0 {
                continue;
            }
            let (x_px, y_px) = cam
                .project([a.pos_m[0], a.pos_m[1], 0.0])
                .unwrap_or((f64::NAN, f64::NAN));
            let mut heading_deg = a.heading_rad.to_degrees();
            if heading_deg <= -180.0 {
                heading_deg += 360.0;
            } else if heading_deg > 180.0 {
                heading_deg -= 360.0;
            }
            truth.push(TruthRow {
                frame,
                time_s,
                id: a.id,
                class: a.class.clone(),
                x_m: a.pos_m[0],
                y_m: a.pos_m[1],
                x_px,
                y_px,
                speed_mps: a.speed_mps,
                heading_deg,
                length_m: a.length_m,
                width_m: a.width_m,
                height_m: a.height_m,
                colour_rgb: a.colour,
                visibility: px.visibility(),
                in_frame: px.in_frame,
                bbox,
                visible_rgb: px.mean_rgb,
            });
        }
        truth.sort_by_key(|t| t.id);
        let detections = self.detect(frame, &truth, &image);
        SimStep {
            frame: Frame {
                index: frame,
                time_s,
                image,
            },
            truth,
            detections,
        }
    }

    /// The simulated detector (`DetectionNoiseConfig`).
    fn detect(
        &mut self,
        frame: u32,
        truth: &[TruthRow],
        image: &image::RgbImage,
    ) -> Vec<Detection> {
        let d = self.config.detections.clone();
        let r = &mut self.det_rng;
        let mut out = Vec::new();
        let (w, h) = (f64::from(self.config.width), f64::from(self.config.height));
        for t in truth {
            if t.visibility < d.min_visibility || r.random::<f64>() < d.miss_prob {
                continue;
            }
            let n = |r: &mut Rng, sd: f64| -> f64 { sd * r.sample::<f64, _>(StandardNormal) };
            let c = t.bbox.centre();
            let cx = c.x + n(r, d.position_sd_px);
            let cy = c.y + n(r, d.position_sd_px);
            let bw = (t.bbox.width * (1.0 + n(r, d.size_sd))).max(1.0);
            let bh = (t.bbox.height * (1.0 + n(r, d.size_sd))).max(1.0);
            let score = (0.55 + 0.4 * t.visibility + n(r, 0.05)).clamp(0.01, 1.0);
            out.push(Detection {
                frame,
                id: 0,
                pos_px: Point::new(cx, cy),
                size_px: Some((bw, bh)),
                colour_rgb: Some(t.visible_rgb),
                class: Some(t.class.clone()),
                score: Some(score),
                area_px: None,
            });
        }
        let n_fp = traffic::poisson(r, d.false_positives_per_frame);
        for _ in 0..n_fp {
            let bw = r.random_range(6.0..40.0);
            let bh = r.random_range(6.0..40.0);
            let cx = r.random_range(bw / 2.0..(w - bw / 2.0).max(bw / 2.0 + 1.0));
            let cy = r.random_range(bh / 2.0..(h - bh / 2.0).max(bh / 2.0 + 1.0));
            let b = BBox::from_centre(Point::new(cx, cy), bw, bh);
            out.push(Detection {
                frame,
                id: 0,
                pos_px: Point::new(cx, cy),
                size_px: Some((bw, bh)),
                colour_rgb: Some(mean_colour(image, &b)),
                class: None,
                score: Some(r.random_range(0.2..0.7)),
                area_px: None,
            });
        }
        // Shuffle (Fisher–Yates) so the order says nothing about identity; ids 1..n.
        for i in (1..out.len()).rev() {
            let j = r.random_range(0..=i);
            out.swap(i, j);
        }
        for (k, det) in out.iter_mut().enumerate() {
            det.id = k as u64 + 1;
        }
        out
    }
}

fn steps(config: &SimConfig) -> (u32, f64) {
    let frame_s = 1.0 / config.fps;
    let n = (frame_s / config.max_step_s - 1e-9).ceil().max(1.0) as u32;
    (n, frame_s / f64::from(n))
}

fn mean_colour(image: &image::RgbImage, b: &BBox) -> [f64; 3] {
    let (w, h) = image.dimensions();
    let x0 = b.left.max(0.0) as u32;
    let y0 = b.top.max(0.0) as u32;
    let x1 = (b.right().min(f64::from(w))) as u32;
    let y1 = (b.bottom().min(f64::from(h))) as u32;
    let mut sum = [0.0; 3];
    let mut n = 0.0;
    for y in y0..y1 {
        for x in x0..x1 {
            let p = image.get_pixel(x, y).0;
            for k in 0..3 {
                sum[k] += f64::from(p[k]);
            }
            n += 1.0;
        }
    }
    if n > 0.0 { sum.map(|s| s / n) } else { sum }
}

impl Iterator for Simulation {
    type Item = Result<SimStep>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.next_frame > self.n_frames {
            return None;
        }
        Some(Ok(self.step_frame()))
    }
}

/// Runs a whole simulation in memory: frames, truth, detections and calibration.
///
/// # Errors
/// An invalid configuration.
pub fn simulate_in_memory(config: &SimConfig, seed: u64) -> Result<SimRun> {
    let sim = Simulation::new(config, seed)?;
    let calibration = sim.calibration().clone();
    let mut run = SimRun {
        frames: Vec::new(),
        truth: Vec::new(),
        detections: Vec::new(),
        calibration,
    };
    for step in sim {
        let step = step?;
        run.frames.push(step.frame);
        run.truth.extend(step.truth);
        run.detections.extend(step.detections);
    }
    Ok(run)
}

#[cfg(test)]
mod tests;
