//! The basic particle filter tracker (METHODS.md §3 "Basic method", seed 004 §3): `ρ`
//! particles per object, predict by the constant-velocity model → weight by `h(y | x)` →
//! resample; the estimate is the weighted mean.
//!
//! Objects start from detections (the paper's CNN doubles as the detector; here any
//! [`Detection`] source, e.g. foreground extraction). The paper gives no rule for ending a
//! track; this one ends when its likelihood stays low or it leaves the image (see the
//! `Choice:` notes).

use super::FilterStageTimes;
use super::detections::{BoxMeasurement, DetectionLikelihoodConfig, assign_closest};
use super::motion::ConstantVelocity;
use super::resample::{ResamplingScheme, resample};
use super::{Particles, SurveillanceRegion};
use crate::class::ObjectClass;
use crate::detection::Detection;
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::geometry::{BBox, Point};
use crate::likelihood::Likelihood;
use crate::rng::{Rng, Stream, rng_for};
use crate::track_point::TrackPoint;
use image::RgbImage;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Parameters of the basic particle filter. `Default` is the paper's vehicle setting
/// (Table 5: `ρ = 100`, `σ_x = σ_y = 10` px); pedestrians used `σ = 0.2·|v|` (Table 7).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ParticleFilterConfig {
    /// `ρ`: particles per object. Default 100.
    pub particles_per_object: usize,
    /// System model. Default absolute `σ = 10` px/frame.
    pub motion: ConstantVelocity,
    /// Spread of the initial particles around a detection, px. Default 4.
    pub initial_spread_px: f64,
    /// Spread of the initial velocities, px/frame. Default 2.
    // Choice: a detection carries no velocity; objects start at rest with this spread.
    pub initial_speed_sigma: f64,
    /// A detection farther than this from every tracked object starts a new one, px.
    /// Default 30.
    // Choice: the paper starts objects from its detector without stating the rule.
    pub new_object_gate_px: f64,
    /// A frame where the object's mean `h` is below this counts as lost. Default 0.05
    /// (the PHD filter's `β_likelihood`).
    pub lost_likelihood: f64,
    /// An object lost for more consecutive frames than this ends. Default 5.
    pub max_lost_frames: u32,
    /// Resampling scheme. Default stratified.
    pub resampling: ResamplingScheme,
    /// Box width written for each estimate when the detection gave none, px. Default 32.
    pub object_width_px: f64,
    /// Box height written for each estimate when the detection gave none, px. Default 32.
    pub object_height_px: f64,
    /// Class written when the detection gave none. Default unknown.
    pub class: ObjectClass,
    /// With detections as measurements (ours): an object whose last detection was a
    /// pedestrian never takes a car, lorry or bus detection, nor the reverse
    /// ([`ObjectClass::may_be_same_object`]). Default true.
    pub keep_classes_apart: bool,
}

impl Default for ParticleFilterConfig {
    fn default() -> Self {
        Self {
            particles_per_object: 100,
            motion: ConstantVelocity::absolute(10.0),
            initial_spread_px: 4.0,
            initial_speed_sigma: 2.0,
            new_object_gate_px: 30.0,
            lost_likelihood: 0.05,
            max_lost_frames: 5,
            resampling: ResamplingScheme::Stratified,
            object_width_px: 32.0,
            object_height_px: 32.0,
            class: ObjectClass::Unknown,
            keep_classes_apart: true,
        }
    }
}

impl ParticleFilterConfig {
    /// Checks every range.
    pub fn validate(&self) -> Result<()> {
        let c = "ParticleFilterConfig";
        if self.particles_per_object == 0 {
            return Err(Error::config(c, "particles_per_object", "must be ≥ 1"));
        }
        crate::limits::at_most(
            self.particles_per_object,
            crate::limits::MAX_PARTICLES_PER_OBJECT,
            "particles per object",
        )
        .map_err(|m| Error::config(c, "particles_per_object", m))?;
        self.motion.validate(c)?;
        for (v, f) in [
            (self.initial_spread_px, "initial_spread_px"),
            (self.initial_speed_sigma, "initial_speed_sigma"),
            (self.new_object_gate_px, "new_object_gate_px"),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::config(
                    c,
                    f,
                    format!("must be finite and ≥ 0, got {v}"),
                ));
            }
        }
        if !(0.0..=1.0).contains(&self.lost_likelihood) {
            return Err(Error::config(c, "lost_likelihood", "must be in [0, 1]"));
        }
        for (v, f) in [
            (self.object_width_px, "object_width_px"),
            (self.object_height_px, "object_height_px"),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::config(
                    c,
                    f,
                    format!("must be finite and > 0, got {v}"),
                ));
            }
        }
        Ok(())
    }
}

/// `h` clamped to `[0, 1]`, 0 when not finite.
fn finite_unit(h: f64) -> f64 {
    if h.is_finite() {
        h.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Equal-weight mean position of `p` and its variance per axis (after resampling the
/// weights are equal).
fn mean_and_variance(p: &Particles) -> (Point, Point) {
    let n = p.len().max(1) as f64;
    let mx = p.x.iter().sum::<f64>() / n;
    let my = p.y.iter().sum::<f64>() / n;
    let vx = p.x.iter().map(|x| (x - mx).powi(2)).sum::<f64>() / n;
    let vy = p.y.iter().map(|y| (y - my).powi(2)).sum::<f64>() / n;
    (Point::new(mx, my), Point::new(vx, vy))
}

/// Builds an object's own likelihood from the frame and detection that start it (e.g. a
/// colour likelihood whose reference is the detection's histogram).
pub type LikelihoodFactory =
    Box<dyn Fn(&RgbImage, &Detection) -> Result<Box<dyn Likelihood>> + Send + Sync>;

/// Where the tracker's likelihood comes from.
enum Source {
    /// One likelihood for every object (a class likelihood such as a CNN), scored in one
    /// batch per frame.
    Shared(Box<dyn Likelihood>),
    /// One likelihood per object, made when the object starts.
    PerObject(LikelihoodFactory),
}

/// One tracked object: its particles and its own random stream.
struct Object {
    id: u64,
    particles: Particles,
    rng: Rng,
    lost_frames: u32,
    /// Frames with a detection (detection measurements only).
    hits: u32,
    likelihood: Option<Box<dyn Likelihood>>,
    size_px: (f64, f64),
    class: ObjectClass,
    estimate: (Point, Point, f64),
    /// The centre of the detection it took this frame, when that is what is written
    /// ([`DetectionLikelihoodConfig::pf_write_detection_centre`]).
    written_centre: Option<Point>,
}

impl Object {
    /// The weighted mean as the estimate, then `rho` particles resampled with equal weights
    /// (the end of both updates, image and detections).
    fn estimate_and_resample(&mut self, scheme: ResamplingScheme, rho: usize) {
        let p = &mut self.particles;
        if let Some(e) = p.weighted_mean(0..p.len()) {
            self.estimate = e;
        }
        let mut anc = Vec::with_capacity(rho);
        resample(scheme, &p.w, rho, &mut self.rng, &mut anc);
        if anc.len() == rho {
            p.select(&anc, 1.0 / rho as f64);
        }
    }
}

/// The basic particle filter over frames.
pub struct ParticleFilterTracker {
    config: ParticleFilterConfig,
    seed: u64,
    source: Source,
    objects: Vec<Object>,
    next_id: u64,
    times: FilterStageTimes,
    positions: Vec<Point>,
    h: Vec<f64>,
}

impl std::fmt::Debug for ParticleFilterTracker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ParticleFilterTracker")
            .field("config", &self.config)
            .field("seed", &self.seed)
            .field("objects", &self.objects.len())
            .finish_non_exhaustive()
    }
}

impl ParticleFilterTracker {
    /// A tracker whose objects share one likelihood.
    ///
    /// # Errors
    /// When the config is invalid.
    pub fn new(
        config: ParticleFilterConfig,
        likelihood: Box<dyn Likelihood>,
        seed: u64,
    ) -> Result<Self> {
        Self::with_source(config, Source::Shared(likelihood), seed)
    }

    /// A tracker where each object gets its own likelihood from `factory` when it starts.
    ///
    /// # Errors
    /// When the config is invalid.
    pub fn with_object_likelihoods(
        config: ParticleFilterConfig,
        factory: LikelihoodFactory,
        seed: u64,
    ) -> Result<Self> {
        Self::with_source(config, Source::PerObject(factory), seed)
    }

    fn with_source(config: ParticleFilterConfig, source: Source, seed: u64) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config,
            seed,
            source,
            objects: Vec::new(),
            next_id: 1,
            times: FilterStageTimes::default(),
            positions: Vec::new(),
            h: Vec::new(),
        })
    }

    /// Wall time per stage so far (`labels` holds track start and end).
    pub fn stage_times(&self) -> FilterStageTimes {
        self.times
    }

    /// Number of objects being tracked.
    pub fn n_objects(&self) -> usize {
        self.objects.len()
    }

    /// Ends the objects with these ids (e.g. tracks no detection has supported for a while).
    pub fn end_objects(&mut self, ids: &[u64]) {
        self.objects.retain(|o| !ids.contains(&o.id));
    }

    /// Moves every object's particles one frame by the motion model, each object with its
    /// own random stream (parallel, thread-count independent).
    fn predict_objects(&mut self) {
        let motion = self.config.motion;
        self.objects.par_iter_mut().for_each(|o| {
            let p = &mut o.particles;
            for i in 0..p.len() {
                let mut s = [p.x[i], p.y[i], p.vx[i], p.vy[i]];
                motion.propagate_one(&mut s, 1.0, &mut o.rng);
                [p.x[i], p.y[i], p.vx[i], p.vy[i]] = s;
            }
        });
    }

    /// Advances by one frame with this frame's detections (may be empty); returns every
    /// tracked object, sorted by id.
    ///
    /// # Errors
    /// When a likelihood fails.
    pub fn step(&mut self, frame: &Frame, detections: &[Detection]) -> Result<Vec<TrackPoint>> {
        let image = &frame.image;
        let rho = self.config.particles_per_object;

        let t0 = Instant::now();
        self.predict_objects();
        self.times.predict += t0.elapsed();

        // Likelihood: one batch for a shared likelihood, one per object otherwise.
        let t0 = Instant::now();
        self.evaluate_image(image)?;
        self.times.likelihood += t0.elapsed();

        // Weight (w ∝ h after equal-weight resampling), estimate, resample.
        let t0 = Instant::now();
        let cfg = &self.config;
        self.objects.par_iter_mut().for_each(|o| {
            let p = &mut o.particles;
            let mut mean_h = 0.0;
            for i in 0..p.len() {
                let h = if p.h[i].is_finite() {
                    p.h[i].clamp(0.0, 1.0)
                } else {
                    0.0
                };
                p.w[i] = h;
                mean_h += h;
            }
            mean_h /= p.len().max(1) as f64;
            if mean_h < cfg.lost_likelihood {
                o.lost_frames += 1;
            } else {
                o.lost_frames = 0;
            }
            if p.total_weight() <= 0.0 {
                // Choice: with no support anywhere, coast on the prediction (equal weights).
                p.w.iter_mut().for_each(|w| *w = 1.0);
            }
            o.estimate_and_resample(cfg.resampling, rho);
        });
        self.times.resample += t0.elapsed();

        // End lost objects and those whose estimate left the image; start new ones.
        let t0 = Instant::now();
        let region = SurveillanceRegion::image(image.width(), image.height());
        let max_lost = self.config.max_lost_frames;
        self.objects
            .retain(|o| o.lost_frames <= max_lost && region.contains(o.estimate.0));
        for d in detections {
            let near = self
                .objects
                .iter()
                .any(|o| o.estimate.0.distance(d.pos_px) <= self.config.new_object_gate_px);
            if !near {
                self.start_object(image, d)?;
            }
        }
        self.times.labels += t0.elapsed();
        self.times.steps += 1;
        Ok(self.points(frame))
    }

    /// Advances by one frame with the detections as measurements
    /// ([`super::detections`]): predict → each object takes the closest free detection
    /// within [`DetectionLikelihoodConfig::pf_gate_sigmas`] of its prediction (one-to-one,
    /// closest pairs first) → weights `(1 − p_D)·κ + p_D·N(z; x_i, σ²)` (times the image
    /// likelihood when `with_image`; equal weights without a detection) → estimate →
    /// resample → objects without a detection for more than
    /// [`ParticleFilterConfig::max_lost_frames`] frames or outside the image end → every
    /// detection no object took starts one. `detections[j]` is the source of
    /// `measurements[j]`. Returns every object, sorted by id.
    ///
    /// # Errors
    /// When a likelihood fails.
    pub fn step_with_detections(
        &mut self,
        frame: &Frame,
        detections: &[Detection],
        measurements: &[BoxMeasurement],
        model: &DetectionLikelihoodConfig,
        with_image: bool,
    ) -> Result<Vec<TrackPoint>> {
        let image = &frame.image;
        let rho = self.config.particles_per_object;
        let t0 = Instant::now();
        self.predict_objects();
        self.times.predict += t0.elapsed();

        let t0 = Instant::now();
        if with_image {
            self.evaluate_image(image)?;
        }
        self.times.likelihood += t0.elapsed();

        let t0 = Instant::now();
        let predicted: Vec<(Point, Point)> = self
            .objects
            .iter()
            .map(|o| mean_and_variance(&o.particles))
            .collect();
        let gate_classes = self.config.keep_classes_apart;
        let objects = &self.objects;
        let allowed = |i: usize, j: usize| {
            !gate_classes
                || ObjectClass::may_be_same_object_if_known(
                    detections.get(j).and_then(|d| d.class.as_ref()),
                    objects.get(i).map(|o| &o.class),
                )
        };
        let assigned = assign_closest(&predicted, measurements, model.pf_gate_sigmas, &allowed);
        let (pd, kappa) = (
            model.detection_prob,
            model.clutter_per_frame
                / (f64::from(image.width().max(1)) * f64::from(image.height().max(1))),
        );
        let cfg = &self.config;
        self.objects
            .par_iter_mut()
            .zip(assigned.par_iter())
            .for_each(|(o, a)| {
                let p = &mut o.particles;
                let z = a.map(|j| &measurements[j]);
                for i in 0..p.len() {
                    let img = if with_image { finite_unit(p.h[i]) } else { 1.0 };
                    match z {
                        Some(z) => {
                            p.w[i] = ((1.0 - pd) * kappa + pd * z.density(p.x[i], p.y[i])) * img;
                            p.h[i] = z.kernel(p.x[i], p.y[i]) * img;
                        }
                        None => {
                            p.w[i] = 1.0;
                            p.h[i] = 0.0;
                        }
                    }
                }
                if z.is_some() {
                    o.lost_frames = 0;
                    o.hits = o.hits.saturating_add(1);
                } else if o.hits < model.pf_tentative_detections {
                    // A tentative object does not coast.
                    o.lost_frames = u32::MAX;
                } else {
                    o.lost_frames += 1;
                }
                if p.total_weight() <= 0.0 || !p.total_weight().is_finite() {
                    p.w.iter_mut().for_each(|w| *w = 1.0);
                }
                o.estimate_and_resample(cfg.resampling, rho);
            });
        self.times.update += t0.elapsed();

        let t0 = Instant::now();
        let region = SurveillanceRegion::image(image.width(), image.height());
        let max_lost = self.config.max_lost_frames;
        let mut taken = vec![false; measurements.len()];
        for (o, a) in self.objects.iter_mut().zip(&assigned) {
            o.written_centre = a
                .filter(|_| model.pf_write_detection_centre)
                .and_then(|j| detections.get(j))
                .map(|d| d.pos_px);
            if let Some(j) = *a {
                taken[j] = true;
                // The detection's box and class describe the object from now on.
                if let Some(size) = detections.get(j).and_then(|d| d.size_px) {
                    o.size_px = size;
                }
                if let Some(class) = detections.get(j).and_then(|d| d.class.clone()) {
                    o.class = class;
                }
            }
        }
        self.objects
            .retain(|o| o.lost_frames <= max_lost && region.contains(o.estimate.0));
        for (j, d) in detections.iter().enumerate() {
            if !taken.get(j).copied().unwrap_or(true) {
                self.start_object(image, d)?;
            }
        }
        self.times.labels += t0.elapsed();
        self.times.steps += 1;
        Ok(self.points(frame))
    }

    /// The image likelihood of every object's particles into their `h`.
    fn evaluate_image(&mut self, image: &RgbImage) -> Result<()> {
        match &mut self.source {
            Source::Shared(lik) => {
                lik.begin_frame(image)?;
                self.positions.clear();
                for o in &self.objects {
                    let p = &o.particles;
                    self.positions
                        .extend(p.x.iter().zip(&p.y).map(|(&x, &y)| Point::new(x, y)));
                }
                self.h.clear();
                self.h.resize(self.positions.len(), 0.0);
                lik.evaluate(image, &self.positions, &mut self.h)?;
                let mut k = 0;
                for o in &mut self.objects {
                    let n = o.particles.len();
                    o.particles.h.copy_from_slice(&self.h[k..k + n]);
                    k += n;
                }
            }
            Source::PerObject(_) => {
                for o in &mut self.objects {
                    if let Some(lik) = o.likelihood.as_mut() {
                        lik.begin_frame(image)?;
                        o.particles.positions_into(&mut self.positions);
                        lik.evaluate(image, &self.positions, &mut o.particles.h)?;
                    }
                }
            }
        }
        Ok(())
    }

    /// Every object as a track point, sorted by id.
    fn points(&self, frame: &Frame) -> Vec<TrackPoint> {
        self.objects
            .iter()
            .map(|o| TrackPoint {
                frame: frame.index,
                time_s: frame.time_s,
                id: o.id,
                class: o.class.clone(),
                bbox: BBox::from_centre(
                    o.written_centre.unwrap_or(o.estimate.0),
                    o.size_px.0,
                    o.size_px.1,
                ),
                score: o.particles.h.iter().sum::<f64>() / o.particles.len().max(1) as f64,
                ground: None,
            })
            .collect()
    }

    fn start_object(&mut self, image: &RgbImage, d: &Detection) -> Result<()> {
        let id = self.next_id;
        self.next_id += 1;
        let mut rng = rng_for(self.seed, Stream::ParticleFilter, id);
        let rho = self.config.particles_per_object;
        let mut particles = Particles::with_capacity(rho);
        let (s, sv) = (
            self.config.initial_spread_px,
            self.config.initial_speed_sigma,
        );
        for _ in 0..rho {
            let n: [f64; 4] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
            particles.push(
                Point::new(d.pos_px.x + s * n[0], d.pos_px.y + s * n[1]),
                Point::new(sv * n[2], sv * n[3]),
                1.0 / rho as f64,
                0,
            );
        }
        // A detection is the likelihood's evidence at its start.
        particles.h.iter_mut().for_each(|h| *h = 1.0);
        let likelihood = match &self.source {
            Source::Shared(_) => None,
            Source::PerObject(factory) => Some(factory(image, d)?),
        };
        self.objects.push(Object {
            id,
            particles,
            rng,
            lost_frames: 0,
            hits: 1,
            likelihood,
            size_px: d
                .size_px
                .unwrap_or((self.config.object_width_px, self.config.object_height_px)),
            class: d.class.clone().unwrap_or_else(|| self.config.class.clone()),
            estimate: (d.pos_px, Point::default(), 1.0),
            written_centre: None,
        });
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::likelihood::{BorderPolicy, ColourLikelihood, ColourLikelihoodConfig, Window};
    use roadtrack_sim::testkit::{SquareSceneConfig, square_scene};

    fn colour_cfg() -> ColourLikelihoodConfig {
        ColourLikelihoodConfig {
            window: Window::new(24, 24, BorderPolicy::Clamp),
            sharpness: 5.0,
            ..Default::default()
        }
    }

    fn scene() -> (Vec<Frame>, Vec<Detection>) {
        square_scene(&SquareSceneConfig {
            width: 320,
            height: 240,
            targets: 3,
            frames: 15,
            ..Default::default()
        })
    }

    fn run(
        tracker: &mut ParticleFilterTracker,
        frames: &[Frame],
        dets: &[Detection],
    ) -> Result<Vec<TrackPoint>> {
        let mut out = Vec::new();
        for f in frames {
            let d = if f.index == 1 { dets } else { &[] };
            out.extend(tracker.step(f, d)?);
        }
        Ok(out)
    }

    #[test]
    fn with_detections_a_walker_never_takes_a_car_detection() -> Result<()> {
        // A pedestrian is born in frame 1; in frame 2 only a car is detected 2 px away.
        let image = RgbImage::new(320, 240);
        let frame = |index: u32| Frame {
            index,
            time_s: f64::from(index - 1) / 10.0,
            image: image.clone(),
        };
        let det = |f: u32, x: f64, class: ObjectClass| Detection {
            class: Some(class),
            size_px: Some((12.0, 30.0)),
            ..Detection::at(f, 1, Point::new(x, 100.0))
        };
        let model = DetectionLikelihoodConfig::default();
        let ids = |gate: bool| -> Result<Vec<Vec<u64>>> {
            let b = BBox::from_centre(Point::new(100.0, 100.0), 20.0, 20.0);
            let shared = ColourLikelihood::from_boxes(colour_cfg(), &image, &[b])?;
            let cfg = ParticleFilterConfig {
                keep_classes_apart: gate,
                ..Default::default()
            };
            let mut t = ParticleFilterTracker::new(cfg, Box::new(shared), 1)?;
            let mut out = Vec::new();
            for (f, class, x) in [
                (1, ObjectClass::Pedestrian, 100.0),
                (2, ObjectClass::Car, 102.0),
            ] {
                let d = [det(f, x, class)];
                let z = model.measurements(&d);
                let pts = t.step_with_detections(&frame(f), &d, &z, &model, false)?;
                out.push(pts.iter().map(|p| p.id).collect());
            }
            Ok(out)
        };
        // Without the gate the walker's object takes the car; with it the car is born as
        // object 2 (the walker's object, left without a detection, is not in the output).
        assert_eq!(ids(false)?, vec![vec![1], vec![1]]);
        assert_eq!(ids(true)?, vec![vec![1], vec![2]]);
        Ok(())
    }

    #[test]
    fn particle_filter_keeps_every_object_with_a_shared_or_per_object_likelihood() -> Result<()> {
        let (frames, dets) = scene();
        let inner: Vec<BBox> = dets
            .iter()
            .map(|d| BBox::from_centre(d.pos_px, 20.0, 20.0))
            .collect();
        let shared = ColourLikelihood::from_boxes(colour_cfg(), &frames[0].image, &inner)?;
        let cfg = ParticleFilterConfig {
            motion: ConstantVelocity::absolute(1.0),
            ..Default::default()
        };
        let mut a = ParticleFilterTracker::new(cfg.clone(), Box::new(shared), 1)?;
        let factory: LikelihoodFactory = Box::new(|img: &RgbImage, d: &Detection| {
            let b = BBox::from_centre(d.pos_px, 20.0, 20.0);
            Ok(
                Box::new(ColourLikelihood::from_boxes(colour_cfg(), img, &[b])?)
                    as Box<dyn Likelihood>,
            )
        });
        let mut b = ParticleFilterTracker::with_object_likelihoods(cfg, factory, 1)?;
        for t in [&mut a, &mut b] {
            let out = run(t, &frames, &dets)?;
            let last: Vec<u64> = out.iter().filter(|p| p.frame == 15).map(|p| p.id).collect();
            assert_eq!(last, vec![1, 2, 3]);
            // Each track moves smoothly (≤ 3 px/frame per axis in the scene, plus noise).
            for id in 1..=3 {
                let c: Vec<Point> = out
                    .iter()
                    .filter(|p| p.id == id)
                    .map(|p| p.bbox.centre())
                    .collect();
                assert!(
                    c.windows(2).all(|w| w[0].distance(w[1]) < 12.0),
                    "track {id} jumps: {c:?}"
                );
            }
        }
        Ok(())
    }

    #[test]
    fn particle_filter_is_deterministic_at_any_thread_count() -> Result<()> {
        let (frames, dets) = scene();
        let inner: Vec<BBox> = dets
            .iter()
            .map(|d| BBox::from_centre(d.pos_px, 20.0, 20.0))
            .collect();
        let lik = ColourLikelihood::from_boxes(colour_cfg(), &frames[0].image, &inner)?;
        let go = |threads: usize| -> Result<Vec<TrackPoint>> {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| Error::Invalid(e.to_string()))?;
            pool.install(|| {
                let mut t = ParticleFilterTracker::new(
                    ParticleFilterConfig::default(),
                    Box::new(lik.clone()),
                    9,
                )?;
                run(&mut t, &frames, &dets)
            })
        };
        assert_eq!(go(1)?, go(4)?);
        Ok(())
    }
}
