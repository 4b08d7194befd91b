//! The image filters as a [`Tracker`] (`roadtrack track --method pf|phd`): the particle
//! filter or the labelled SMC-PHD filter (METHODS.md §3) over a detector's output, with the
//! colour-histogram likelihood or a network (a CNN classifier or the SSD pedestrian
//! detector, loaded by `roadtrack-cnn`), per particle window or in dense mode.
//!
//! Per frame: filter step (PF: start objects at detections no object explains; PHD: birth
//! particles around detections no label explains — [`BirthGate`]) → end tracks that no
//! detection has supported for a while ([`SupportDeleter`]) → give each estimate the box of
//! its nearest detection ([`BoxFromDetections`]).
//!
//! A shared likelihood (PHD, or a PF with a shared reference or a network) needs the colour
//! reference and window size of the first [`TrackLikelihoodConfig::reference_frames`]
//! frames with detections: those frames are held back and tracked once it is complete, so
//! the tracker returns them late, together.

use super::config::{BirthSource, ColourReference, FilterMethod, FilterTrackConfig};
use super::config::{LikelihoodKind, TrackLikelihoodConfig};
use super::detections::Measurements;
use super::particle::{LikelihoodFactory, ParticleFilterTracker};
use super::phd::{ExistenceSmoother, FilterStageTimes, LabelWeights, PhdTracker};
use crate::detect::FrameDetections;
use crate::detection::Detection;
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::geometry::{BBox, Point};
use crate::likelihood::foreground::{SharedMask, with_foreground};
use crate::likelihood::{
    ColourHistogram, ColourLikelihood, DenseLikelihood, GridScorer, Likelihood,
};
use crate::track::lifecycle::{BirthGate, BoxFromDetections, SupportDeleter};
use crate::track::{FramePoints, Tracker};
use crate::track_point::TrackPoint;
use image::{GrayImage, RgbImage};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Per-frame counts of a run ([`FilterTracker::record_counts`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrameCount {
    /// Frame number.
    pub frame: u32,
    /// Expected number of objects: the PHD filter's weight sum, the PF's object count.
    pub expected: f64,
    /// The most probable number of objects ([`crate::track::filter::phd::map_cardinality`]
    /// of the labels' weights); the PF's object count.
    pub most_probable: usize,
    /// The PHD's count smoothed over the next
    /// [`FilterTrackConfig::count_lag_frames`] frames: Σ of the labels' existence given
    /// those frames ([`super::phd::ExistenceSmoother`]); `expected` when that is 0, and the
    /// PF's object count. Filled in once the later frames are tracked (at the end of the
    /// run for the last ones).
    pub smoothed: f64,
    /// The mode of the smoothed existences ([`super::phd::map_cardinality`]).
    pub smoothed_most_probable: usize,
    /// Tracks reported in the frame.
    pub reported: usize,
    /// Detections in the frame.
    pub detections: usize,
}

/// Frames held back for the shared reference, at most.
// Choice: a video that starts with a long empty stretch would otherwise hold every frame
// until `reference_frames` frames with detections came; after 250 frames (25 s at 10 fps)
// the reference is made from what there is, as at the end of a short input.
pub const MAX_PENDING_FRAMES: usize = 250;

/// One frame waiting for the shared reference.
type Pending = (Frame, Vec<Detection>, Option<GrayImage>);

/// The PF or PHD filter with its track management, as a [`Tracker`].
pub struct FilterTracker {
    method: FilterMethod,
    cfg: FilterTrackConfig,
    seed: u64,
    shared: bool,
    model: Option<Box<dyn Likelihood>>,
    pending: Vec<Pending>,
    reference_frames: u32,
    runner: Option<Runner>,
    counts: Option<Vec<FrameCount>>,
    /// The PHD's count smoother (with [`FilterTracker::record_counts`]).
    smoother: Option<ExistenceSmoother>,
}

impl std::fmt::Debug for FilterTracker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FilterTracker")
            .field("method", &self.method)
            .field("pending", &self.pending.len())
            .field("started", &self.runner.is_some())
            .finish_non_exhaustive()
    }
}

impl FilterTracker {
    /// A tracker with `model` (a network likelihood, e.g. from `roadtrack-cnn`) as the
    /// class likelihood instead of the colour histogram, when given: one likelihood shared
    /// by every object (PF and PHD). [`TrackLikelihoodConfig::kind`] still applies
    /// (`foreground` ignores the model; `colour_foreground` multiplies the model by the
    /// foreground fraction); the window and box sizes stay the median detection box of the
    /// reference frames. A model with [`Measurements::Detections`] (the default) weighs
    /// by the image instead ([`Measurements::Image`]): a network is an image likelihood.
    ///
    /// # Errors
    /// An invalid config.
    pub fn new(
        method: FilterMethod,
        cfg: &FilterTrackConfig,
        seed: u64,
        model: Option<Box<dyn Likelihood>>,
    ) -> Result<Self> {
        cfg.validate()?;
        let mut cfg = cfg.clone();
        if model.is_some() && cfg.measurements == Measurements::Detections {
            cfg.measurements = Measurements::Image;
        }
        // With the detections alone nothing reads the image: no reference to wait for.
        let shared = cfg.measurements.uses_image()
            && (method == FilterMethod::Phd
                || cfg.likelihood.reference == ColourReference::Shared
                || model.is_some());
        Ok(Self {
            method,
            cfg,
            seed,
            shared,
            model,
            pending: Vec::new(),
            reference_frames: 0,
            runner: None,
            counts: None,
            smoother: None,
        })
    }

    /// Keeps a [`FrameCount`] per frame from now on ([`FilterTracker::counts`]).
    pub fn record_counts(&mut self) {
        self.counts.get_or_insert_with(Vec::new);
        if self.method == FilterMethod::Phd && self.cfg.count_lag_frames > 0 {
            let lag = self.cfg.count_lag_frames as usize;
            self.smoother
                .get_or_insert_with(|| ExistenceSmoother::new(lag, self.cfg.phd.survival_prob));
        }
    }

    /// Records a frame's count, and the smoothed count of the frame the smoother returns.
    fn push_count(&mut self, count: FrameCount, labels: LabelWeights) {
        let Some(counts) = self.counts.as_mut() else {
            return;
        };
        counts.push(count);
        if let Some(s) = self.smoother.as_mut()
            && let Some(w) = s.push(labels)
        {
            let k = counts.len() - 1 - self.cfg.count_lag_frames as usize;
            set_smoothed(&mut counts[k], &w);
        }
    }

    /// The counts recorded so far (empty unless [`FilterTracker::record_counts`]).
    pub fn counts(&self) -> &[FrameCount] {
        self.counts.as_deref().unwrap_or(&[])
    }

    /// Wall time per filter stage so far (detection not included).
    pub fn stage_times(&self) -> FilterStageTimes {
        self.runner
            .as_ref()
            .map_or_else(FilterStageTimes::default, Runner::stage_times)
    }

    /// The shared likelihood's window, px, once it is made (`None` with per-object PF
    /// likelihoods).
    pub fn window_px(&self) -> Option<(u32, u32)> {
        self.runner.as_ref().and_then(|r| r.window_px)
    }

    /// Every PHD label's estimate, reported or not (empty for the PF or before the
    /// first step); for diagnostics in tests.
    #[cfg(test)]
    pub(super) fn phd_labels(&self) -> Vec<super::phd::LabelEstimate> {
        match self.runner.as_ref().map(|r| &r.filter) {
            Some(Filter::Phd(t)) => t.filter().map_or_else(Vec::new, |f| f.all_estimates()),
            _ => Vec::new(),
        }
    }

    /// [`super::phd::PhdTracker::detected_labels`] of the last frame (empty for the PF or
    /// before the first step); for diagnostics in tests.
    #[cfg(test)]
    pub(super) fn phd_detected_labels(&self) -> std::collections::BTreeSet<u32> {
        match self.runner.as_ref().map(|r| &r.filter) {
            Some(Filter::Phd(t)) => t.detected_labels().clone(),
            _ => std::collections::BTreeSet::new(),
        }
    }

    /// Makes the runner from the pending frames and tracks them.
    fn start(&mut self) -> Result<Vec<FramePoints>> {
        let runner = Runner::new(
            self.method,
            &self.cfg,
            &self.pending,
            self.seed,
            self.shared,
            self.model.take(),
        )?;
        self.runner = Some(runner);
        let mut out = Vec::with_capacity(self.pending.len());
        let pending = std::mem::take(&mut self.pending);
        for (f, d, m) in pending {
            let Some(r) = self.runner.as_mut() else {
                break;
            };
            let (points, count, labels) = r.step(&f, &d, m.as_ref())?;
            self.push_count(count, labels);
            out.push(FramePoints::new(&f, points));
        }
        Ok(out)
    }
}

impl Tracker for FilterTracker {
    fn step(&mut self, frame: &Frame, detections: &FrameDetections) -> Result<Vec<FramePoints>> {
        if self.cfg.measurements.uses_image()
            && self.cfg.likelihood.kind != LikelihoodKind::Colour
            && detections.foreground.is_none()
        {
            return Err(Error::Invalid(format!(
                "frame {}: the {:?} likelihood needs a detector with a foreground mask",
                frame.index, self.cfg.likelihood.kind
            )));
        }
        if let Some(r) = self.runner.as_mut() {
            let (points, count, labels) = r.step(
                frame,
                &detections.detections,
                detections.foreground.as_ref(),
            )?;
            self.push_count(count, labels);
            return Ok(vec![FramePoints::new(frame, points)]);
        }
        if !detections.detections.is_empty() {
            self.reference_frames += 1;
        }
        self.pending.push((
            frame.clone(),
            detections.detections.clone(),
            detections.foreground.clone(),
        ));
        if !self.shared
            || self.reference_frames >= self.cfg.likelihood.reference_frames
            || self.pending.len() >= MAX_PENDING_FRAMES
        {
            return self.start();
        }
        Ok(Vec::new())
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        let out = if self.runner.is_none() && !self.pending.is_empty() {
            // Fewer frames with detections than `reference_frames`: use what there is.
            self.start()?
        } else {
            Vec::new()
        };
        if let (Some(s), Some(counts)) = (self.smoother.as_mut(), self.counts.as_mut()) {
            let rest = s.finish();
            let first = counts.len() - rest.len();
            for (c, w) in counts[first..].iter_mut().zip(&rest) {
                set_smoothed(c, w);
            }
        }
        Ok(out)
    }
}

enum Filter {
    Pf(Box<ParticleFilterTracker>),
    Phd(Box<PhdTracker>),
}

/// One run's filter with its bookkeeping.
struct Runner {
    cfg: FilterTrackConfig,
    filter: Filter,
    /// The current frame's foreground mask, read by foreground likelihoods.
    mask: SharedMask,
    window_px: Option<(u32, u32)>,
    deleter: SupportDeleter,
    sizer: BoxFromDetections,
    /// The PF's estimates of the last frame.
    last_pf: Vec<Point>,
}

impl Runner {
    fn new(
        method: FilterMethod,
        cfg: &FilterTrackConfig,
        pending: &[Pending],
        seed: u64,
        shared: bool,
        model: Option<Box<dyn Likelihood>>,
    ) -> Result<Self> {
        let lc = cfg.likelihood;
        let mask: SharedMask = Arc::default();
        let (likelihood, window_px) = if shared {
            let (lik, win) = shared_likelihood(&lc, pending, &mask, model)?;
            (Some(lik), Some(win))
        } else if !cfg.measurements.uses_image() {
            // Never evaluated: the detections are the only measurements.
            let none: Box<dyn Likelihood> = Box::new(|_: &RgbImage, _: Point| 1.0);
            (Some(none), None)
        } else {
            (None, None)
        };
        let default_size = window_px.map_or(
            (cfg.pf.object_width_px, cfg.pf.object_height_px),
            |(w, h)| (f64::from(w), f64::from(h)),
        );
        let filter = match method {
            FilterMethod::Pf => {
                let pf = match likelihood {
                    Some(lik) => ParticleFilterTracker::new(cfg.pf.clone(), lik, seed)?,
                    None => {
                        let mask = Arc::clone(&mask);
                        let factory: LikelihoodFactory =
                            Box::new(move |img: &RgbImage, d: &Detection| {
                                let size = d.size_px.unwrap_or((32.0, 32.0));
                                let b = BBox::from_centre(d.pos_px, size.0, size.1);
                                let colour = lc.colour(size);
                                let lik = ColourLikelihood::from_boxes(colour, img, &[b])?;
                                Ok(with_foreground(
                                    lc.kind,
                                    lc.foreground_full,
                                    Box::new(lik),
                                    colour.window,
                                    &mask,
                                ))
                            });
                        ParticleFilterTracker::with_object_likelihoods(
                            cfg.pf.clone(),
                            factory,
                            seed,
                        )?
                    }
                };
                Filter::Pf(Box::new(pf))
            }
            FilterMethod::Phd => {
                let lik = likelihood
                    .ok_or_else(|| Error::Invalid("PHD filter: no shared likelihood".to_owned()))?;
                let mut phd_cfg = cfg.phd.clone();
                phd_cfg.object_width_px = default_size.0;
                phd_cfg.object_height_px = default_size.1;
                if cfg.measurements.uses_detections() {
                    phd_cfg.merge_distance = cfg.detections.merge_distance_px;
                }
                let mut t = PhdTracker::new(phd_cfg, lik, seed)?;
                t.set_grid_births(matches!(cfg.births, BirthSource::Grid | BirthSource::Both));
                Filter::Phd(Box::new(t))
            }
        };
        Ok(Self {
            cfg: cfg.clone(),
            filter,
            mask,
            window_px,
            deleter: SupportDeleter::new(cfg.support_gate_px, cfg.max_frames_without_detection),
            sizer: BoxFromDetections::new(cfg.support_gate_px, default_size),
            last_pf: Vec::new(),
        })
    }

    fn stage_times(&self) -> FilterStageTimes {
        match &self.filter {
            Filter::Pf(t) => t.stage_times(),
            Filter::Phd(t) => t.stage_times(),
        }
    }

    /// Tracks one frame: its points (sorted by id), counts, and every PHD label's weight
    /// (empty for the PF).
    fn step(
        &mut self,
        frame: &Frame,
        dets: &[Detection],
        mask: Option<&GrayImage>,
    ) -> Result<(Vec<TrackPoint>, FrameCount, LabelWeights)> {
        if self.cfg.likelihood.kind != LikelihoodKind::Colour
            && let Some(mask) = mask
        {
            let mut m = self
                .mask
                .write()
                .map_err(|_| Error::Invalid("foreground mask lock poisoned".to_owned()))?;
            m.set(mask);
        }
        let cfg = &self.cfg;
        let with_image = cfg.measurements.uses_image();
        let (mut points, expected, tracked, labels) = match &mut self.filter {
            Filter::Pf(t) if cfg.measurements.uses_detections() => {
                let dets = finite(dets);
                let z = cfg.detections.measurements(&dets);
                let pts = t.step_with_detections(frame, &dets, &z, &cfg.detections, with_image)?;
                let tracked: Vec<(u64, Point)> =
                    pts.iter().map(|p| (p.id, p.bbox.centre())).collect();
                let n = t.n_objects() as f64;
                (pts, n, tracked, LabelWeights::new())
            }
            Filter::Phd(t) if cfg.measurements.uses_detections() => {
                let dets = finite(dets);
                let z = cfg.detections.measurements(&dets);
                let sizes: Vec<Point> = dets
                    .iter()
                    .map(|d| {
                        d.size_px
                            .map_or(Point::default(), |(w, h)| Point::new(w, h))
                    })
                    .collect();
                let pts = t.step_with_detections(
                    frame,
                    &z,
                    &sizes,
                    &cfg.detections.phd_model(),
                    cfg.birth_particles_per_detection,
                    with_image,
                )?;
                let (tracked, labels) = label_state(t);
                (pts, t.expected_count(), tracked, labels)
            }
            Filter::Pf(t) => {
                // Choice: a detection starts an object only when no object's last estimate
                // lies within half its box's longer side (at least the PF's own gate), so a
                // large nearby vehicle does not start a second object.
                let gate = BirthGate {
                    gate_px: cfg.pf.new_object_gate_px,
                    widen_to_box: true,
                };
                let starts: Vec<Detection> = gate
                    .unexplained(&self.last_pf, dets)
                    .into_iter()
                    .cloned()
                    .collect();
                let pts = t.step(frame, &starts)?;
                let tracked: Vec<(u64, Point)> =
                    pts.iter().map(|p| (p.id, p.bbox.centre())).collect();
                let n = t.n_objects() as f64;
                (pts, n, tracked, LabelWeights::new())
            }
            Filter::Phd(t) => {
                let births: Vec<Point> = if matches!(cfg.births, BirthSource::Grid) {
                    Vec::new()
                } else {
                    // Labels predicted one frame ahead explain the detections near them.
                    let predicted: Vec<Point> = t.filter().map_or_else(Vec::new, |f| {
                        f.all_estimates()
                            .iter()
                            .map(|e| Point::new(e.pos.x + e.vel.x, e.pos.y + e.vel.y))
                            .collect()
                    });
                    let gate = BirthGate {
                        gate_px: cfg.birth_gate_px,
                        widen_to_box: false,
                    };
                    gate.unexplained(&predicted, dets)
                        .into_iter()
                        .map(|d| d.pos_px)
                        .collect()
                };
                let pts = t.step_with_births(
                    frame,
                    &births,
                    cfg.birth_particles_per_detection,
                    cfg.birth_spread_px,
                )?;
                let (tracked, labels) = label_state(t);
                (pts, t.expected_count(), tracked, labels)
            }
        };

        let most_probable = match &self.filter {
            Filter::Pf(t) => t.n_objects(),
            Filter::Phd(_) => super::phd::map_cardinality(labels.values().copied()),
        };

        // Support by detections; end tracks unsupported for too long.
        let ended = self.deleter.update(frame.index, &tracked, dets);
        if !ended.is_empty() {
            match &mut self.filter {
                Filter::Pf(t) => t.end_objects(&ended),
                Filter::Phd(t) => {
                    let labels: Vec<u32> = ended
                        .iter()
                        .filter_map(|&id| u32::try_from(id).ok())
                        .collect();
                    t.remove_labels(&labels);
                }
            }
            points.retain(|p| !ended.contains(&p.id));
        }
        if cfg.box_from_detections {
            let live: Vec<u64> = tracked.iter().map(|t| t.0).collect();
            self.sizer.apply(&mut points, dets, &live);
        }
        if let Filter::Pf(_) = self.filter {
            self.last_pf = points.iter().map(|p| p.bbox.centre()).collect();
        }
        // Until the smoother fills them in (the PF's stay): the filter's own counts.
        let count = FrameCount {
            frame: frame.index,
            expected,
            most_probable,
            smoothed: expected,
            smoothed_most_probable: most_probable,
            reported: points.len(),
            detections: dets.len(),
        };
        Ok((points, count, labels))
    }
}

/// Every PHD label's estimated position (the tracks the deleter checks for support) and
/// weight, from one pass over the labels.
fn label_state(t: &PhdTracker) -> (Vec<(u64, Point)>, LabelWeights) {
    let estimates = t.filter().map_or_else(Vec::new, |f| f.all_estimates());
    (
        estimates
            .iter()
            .map(|e| (u64::from(e.label), e.pos))
            .collect(),
        estimates.iter().map(|e| (e.label, e.weight)).collect(),
    )
}

/// Sets a frame's smoothed count from its labels' smoothed weights.
fn set_smoothed(count: &mut FrameCount, weights: &[f64]) {
    count.smoothed = weights.iter().sum();
    count.smoothed_most_probable = super::phd::map_cardinality(weights.iter().copied());
}

/// The detections whose centre is finite (the measurements).
fn finite(dets: &[Detection]) -> Vec<Detection> {
    dets.iter()
        .filter(|d| d.pos_px.x.is_finite() && d.pos_px.y.is_finite())
        .cloned()
        .collect()
}

/// The shared likelihood: `model` when given, else the colour likelihood with reference =
/// mean histogram of every detection box in `pending`, dense when configured; window =
/// median detection size.
fn shared_likelihood(
    lc: &TrackLikelihoodConfig,
    pending: &[Pending],
    mask: &SharedMask,
    model: Option<Box<dyn Likelihood>>,
) -> Result<(Box<dyn Likelihood>, (u32, u32))> {
    let mut hists = Vec::new();
    let (mut ws, mut hs) = (Vec::new(), Vec::new());
    for (f, dets, _) in pending {
        for d in dets {
            if let Some(b) = d.bbox() {
                hists.push(ColourHistogram::of_box(&f.image, lc.bins_per_channel, &b));
                ws.push(b.width);
                hs.push(b.height);
            }
        }
    }
    let median = |v: &mut Vec<f64>| -> f64 {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(32.0)
    };
    let colour = lc.colour((median(&mut ws), median(&mut hs)));
    let window = (colour.window.width_px, colour.window.height_px);
    if let Some(model) = model {
        return Ok((
            with_foreground(lc.kind, lc.foreground_full, model, colour.window, mask),
            window,
        ));
    }
    // No detection at all: an empty reference (every window scores exp(−λ), nothing is
    // tracked).
    let reference = ColourHistogram::mean(&hists)
        .unwrap_or_else(|| ColourHistogram::zeros(lc.bins_per_channel));
    let lik = ColourLikelihood::new(colour, reference)?;
    let lik: Box<dyn Likelihood> = if lc.dense_stride_px > 0 {
        Box::new(DenseLikelihood::new(Box::new(GridScorer {
            inner: lik,
            stride_px: lc.dense_stride_px,
        })))
    } else {
        Box::new(lik)
    };
    Ok((
        with_foreground(lc.kind, lc.foreground_full, lik, colour.window, mask),
        window,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::class::ObjectClass;
    use crate::detect::background::BackgroundDetector;
    use crate::track::filter::config::LikelihoodKind;
    use crate::track::pipeline::run_frames;
    use roadtrack_sim::testkit::three_cars;
    use roadtrack_sim::{SceneKind, SimConfig, Simulation, ViewKind};

    /// Points and per-frame counts of `method` over `frames` (seed 7).
    fn run(
        method: FilterMethod,
        frames: &[Frame],
        cfg: &FilterTrackConfig,
    ) -> Result<(Vec<TrackPoint>, Vec<FrameCount>)> {
        let detector = BackgroundDetector::bootstrap(
            cfg.detector.clone(),
            frames.iter().cloned().map(Ok),
            Some(frames.len() as u32),
        )?;
        let mut tracker = FilterTracker::new(method, cfg, 7, None)?;
        tracker.record_counts();
        let points = run_frames(
            Some(Box::new(detector)),
            Box::new(&mut tracker),
            frames.iter().cloned().map(Ok),
        )?;
        Ok((points, tracker.counts().to_vec()))
    }

    #[test]
    fn phd_weight_sum_tracks_the_true_count_on_a_simulated_scene() -> Result<()> {
        let (frames, truth) = three_cars(30)?;
        let cfg = FilterTrackConfig {
            measurements: Measurements::Image,
            ..Default::default()
        };
        let (_, counts) = run(FilterMethod::Phd, &frames, &cfg)?;
        assert_eq!(counts.len(), frames.len());
        let mut errors = Vec::new();
        for c in &counts[5..] {
            let n = truth
                .iter()
                .filter(|t| t.frame == c.frame && t.visibility >= 0.3)
                .count() as f64;
            errors.push((c.expected - n).abs());
        }
        let mae = errors.iter().sum::<f64>() / errors.len() as f64;
        assert!(mae < 0.8, "mean |Σw − true count| = {mae:.2}: {counts:?}");
        Ok(())
    }

    /// Mean true count, mean Σw and mean |Σw − true count| of the PHD tracker on the
    /// crossing scene with pedestrians only (docs/EXPERIMENTS.md "Filters on image
    /// sequences": the setting, truth rule and tracker config of `filter_experiments`).
    fn crossing_counts(
        frames: u32,
        seed: u64,
        update: crate::track::filter::phd::LabelUpdate,
        kind: LikelihoodKind,
    ) -> Result<(f64, f64, f64)> {
        let mut sim = SimConfig {
            scene: SceneKind::Crossing,
            view: ViewKind::Oblique,
            frames,
            ..Default::default()
        };
        sim.crossing.inflow_veh_per_h_per_direction = 0.0;
        let mut cfg = FilterTrackConfig {
            measurements: Measurements::Image,
            ..Default::default()
        };
        cfg.phd.motion = crate::track::filter::motion::ConstantVelocity::proportional(0.2, 1.0);
        cfg.phd.class = ObjectClass::Pedestrian;
        cfg.phd.label_update = update;
        cfg.likelihood.kind = kind;
        let (mut images, mut truth) = (Vec::new(), Vec::new());
        for step in Simulation::new(&sim, seed)? {
            let step = step?;
            images.push(step.frame);
            truth.extend(step.truth);
        }
        let min_area = f64::from(cfg.detector.regions.min_area_px);
        let detector = BackgroundDetector::bootstrap(
            cfg.detector.clone(),
            images.iter().cloned().map(Ok),
            Some(frames),
        )?;
        let mut tracker = FilterTracker::new(FilterMethod::Phd, &cfg, seed, None)?;
        tracker.record_counts();
        run_frames(
            Some(Box::new(detector)),
            Box::new(&mut tracker),
            images.iter().cloned().map(Ok),
        )?;
        let (mut t_sum, mut e_sum, mut abs_sum) = (0.0, 0.0, 0.0);
        for c in tracker.counts() {
            let n = truth
                .iter()
                .filter(|t| {
                    t.frame == c.frame
                        && t.visibility >= 0.3
                        && t.bbox.width * t.bbox.height >= min_area
                })
                .count() as f64;
            t_sum += n;
            e_sum += c.expected;
            abs_sum += (c.expected - n).abs();
        }
        let n = tracker.counts().len().max(1) as f64;
        Ok((t_sum / n, e_sum / n, abs_sum / n))
    }

    /// The count experiment of docs/EXPERIMENTS.md (issue 14): both label updates, both
    /// likelihoods, seeds 1–3, 200 frames. Run with
    /// `cargo test -p roadtrack --lib crossing_count_experiment -- --ignored --nocapture`.
    #[test]
    #[ignore = "experiment, ~3 min"]
    fn crossing_count_experiment() -> Result<()> {
        use crate::track::filter::phd::LabelUpdate;
        for kind in [LikelihoodKind::Colour, LikelihoodKind::ColourForeground] {
            for update in [LabelUpdate::Phd, LabelUpdate::Bernoulli] {
                let runs: Vec<(f64, f64, f64)> = (1..=3)
                    .map(|seed| crossing_counts(200, seed, update, kind))
                    .collect::<Result<_>>()?;
                let mean = |f: fn(&(f64, f64, f64)) -> f64| runs.iter().map(f).sum::<f64>() / 3.0;
                println!(
                    "{kind:?} {update:?}: mean count {:.2} ({:.2}), count MAE {:.2}; per seed {runs:.2?}",
                    mean(|r| r.1),
                    mean(|r| r.0),
                    mean(|r| r.2)
                );
            }
        }
        Ok(())
    }

    #[test]
    fn bernoulli_labels_bring_the_crossing_count_closer_to_the_truth() -> Result<()> {
        use crate::track::filter::phd::LabelUpdate;
        let (truth, phd, phd_mae) =
            crossing_counts(60, 1, LabelUpdate::Phd, LikelihoodKind::Colour)?;
        let (_, bern, bern_mae) =
            crossing_counts(60, 1, LabelUpdate::Bernoulli, LikelihoodKind::Colour)?;
        assert!(
            bern > phd && bern_mae < phd_mae,
            "truth {truth:.2}: PHD {phd:.2} (MAE {phd_mae:.2}), Bernoulli {bern:.2} (MAE {bern_mae:.2})"
        );
        Ok(())
    }

    #[test]
    fn pf_follows_each_car() -> Result<()> {
        let (frames, truth) = three_cars(24)?;
        let cfg = FilterTrackConfig {
            measurements: Measurements::Image,
            ..Default::default()
        };
        let (in_memory, _) = run(FilterMethod::Pf, &frames, &cfg)?;
        assert!(!in_memory.is_empty());
        // Reported centres lie on a car: inside a truth box of the frame. (The colour
        // histogram ignores where in the window the colours are, so a track may lag
        // inside a long car's box by tens of px.)
        let near = in_memory
            .iter()
            .filter(|p| {
                let c = p.bbox.centre();
                truth.iter().any(|t| {
                    let b = t.bbox;
                    t.frame == p.frame
                        && c.x >= b.left
                        && c.x <= b.left + b.width
                        && c.y >= b.top
                        && c.y <= b.top + b.height
                })
            })
            .count() as u32;
        let share = f64::from(near) / in_memory.len() as f64;
        assert!(share > 0.8, "{near} of {} points on a car", in_memory.len());
        Ok(())
    }

    #[test]
    fn methods_parse_and_an_invalid_config_is_refused() {
        assert_eq!("pf".parse::<FilterMethod>().ok(), Some(FilterMethod::Pf));
        assert_eq!("phd".parse::<FilterMethod>().ok(), Some(FilterMethod::Phd));
        assert!("mrf".parse::<FilterMethod>().is_err());
        let mut cfg = FilterTrackConfig::default();
        assert!(cfg.validate().is_ok());
        cfg.likelihood.foreground_full = 0.0;
        assert!(cfg.validate().is_err());
        let text = "births = \"grid\"\n[likelihood]\nkind = \"colour_foreground\"\n";
        let parsed: std::result::Result<FilterTrackConfig, _> = toml::from_str(text);
        assert!(parsed.is_ok_and(|c| c.births == BirthSource::Grid
            && c.likelihood.kind == LikelihoodKind::ColourForeground));
        assert!(toml::from_str::<FilterTrackConfig>("bogus = 1").is_err());
    }
}
