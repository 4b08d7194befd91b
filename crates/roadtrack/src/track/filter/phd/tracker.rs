//! [`PhdTracker`]: the labelled SMC-PHD filter on frames with an image likelihood.

use super::super::SurveillanceRegion;
use super::{
    BoxMeasurement, DetectionModel, FilterStageTimes, LabelAssociation, LabelBox, LabelEstimate,
    LabelUpdate, LabelledPhd, PhdConfig, occluded_pd, visible_fractions,
};
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::geometry::{BBox, Point};
use crate::likelihood::Likelihood;
use crate::track_point::TrackPoint;
use std::collections::BTreeMap;
use std::time::Instant;

/// How a [`PhdTracker`] starts.
#[derive(Debug, Clone)]
enum Start {
    /// From the birth process alone.
    Births,
    /// `ρ` particles around each `(position, velocity)`.
    At(Vec<(Point, Point)>),
    /// Step a): uniform particles weighted by `h`, k-means with this many objects.
    Uniform(usize),
}

/// A reported label as a track point: a box of the configured size around its position,
/// its weight (capped at 1) as the score.
fn estimate_point(config: &PhdConfig, frame: &Frame, e: &LabelEstimate) -> TrackPoint {
    TrackPoint {
        frame: frame.index,
        time_s: frame.time_s,
        id: u64::from(e.label),
        class: config.class.clone(),
        bbox: BBox::from_centre(e.pos, config.object_width_px, config.object_height_px),
        score: e.weight.min(1.0),
        ground: None,
    }
}

/// The labelled SMC-PHD filter on frames with an image likelihood (METHODS.md §3): grid
/// births, per-label update (eqs. 11–13), label rules, stratified resampling. Labels are
/// the track ids.
pub struct PhdTracker {
    config: PhdConfig,
    seed: u64,
    likelihood: Box<dyn Likelihood>,
    filter: Option<LabelledPhd>,
    start: Start,
    frame_size: (u32, u32),
    times: FilterStageTimes,
    positions: Vec<Point>,
    h: Vec<f64>,
    grid_births: bool,
    /// Each label's box size, from the last detection it explained (the occlusion model).
    label_size: BTreeMap<u32, Point>,
    /// Labels written at a detection's centre this frame
    /// ([`DetectionModel::write_detection_centre`]).
    written: BTreeMap<u32, Point>,
    /// Labels whose most probable association this frame was a detection (exclusive
    /// labels only; empty otherwise).
    detected: std::collections::BTreeSet<u32>,
}

impl std::fmt::Debug for PhdTracker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PhdTracker")
            .field("config", &self.config)
            .field("seed", &self.seed)
            .field("filter", &self.filter)
            .finish_non_exhaustive()
    }
}

impl PhdTracker {
    /// A tracker that starts from the birth process alone.
    ///
    /// # Errors
    /// When the config is invalid.
    pub fn new(config: PhdConfig, likelihood: Box<dyn Likelihood>, seed: u64) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config,
            seed,
            likelihood,
            filter: None,
            start: Start::Births,
            frame_size: (0, 0),
            times: FilterStageTimes::default(),
            positions: Vec::new(),
            h: Vec::new(),
            grid_births: true,
            label_size: BTreeMap::new(),
            written: BTreeMap::new(),
            detected: std::collections::BTreeSet::new(),
        })
    }

    /// Turns the paper's grid births (step c) on (the default) or off, e.g. when births
    /// come from detections ([`PhdTracker::step_with_births`]).
    pub fn set_grid_births(&mut self, on: bool) {
        self.grid_births = on;
    }

    /// Removes every particle of `labels` (see [`LabelledPhd::remove_labels`]).
    pub fn remove_labels(&mut self, labels: &[u32]) {
        if let Some(f) = self.filter.as_mut() {
            f.remove_labels(labels);
        }
    }

    /// Starts the first frame with `ρ` particles around each detection (one label each);
    /// call before the first [`PhdTracker::step`].
    pub fn start_from_detections(&mut self, detections: &[crate::detection::Detection]) {
        self.start = Start::At(
            detections
                .iter()
                .map(|d| (d.pos_px, Point::default()))
                .collect(),
        );
    }

    /// Starts the first frame with step a) of the paper for `n_objects` objects.
    pub fn start_uniform(&mut self, n_objects: usize) {
        self.start = Start::Uniform(n_objects);
    }

    /// The filter state (after the first step).
    pub fn filter(&self) -> Option<&LabelledPhd> {
        self.filter.as_ref()
    }

    /// The labels whose most probable association in the last detection step was one of
    /// the frame's detections rather than a miss (exclusive labels; empty with the other
    /// label updates and before the first step).
    pub fn detected_labels(&self) -> &std::collections::BTreeSet<u32> {
        &self.detected
    }

    /// The expected number of objects (sum of weights); 0 before the first step.
    pub fn expected_count(&self) -> f64 {
        self.filter
            .as_ref()
            .map_or(0.0, LabelledPhd::expected_count)
    }

    /// Wall time per stage so far.
    pub fn stage_times(&self) -> FilterStageTimes {
        self.times
    }

    /// Advances by one frame; returns the reported labels as track points sorted by id.
    ///
    /// # Errors
    /// When the frame size changes or the likelihood fails.
    pub fn step(&mut self, frame: &Frame) -> Result<Vec<TrackPoint>> {
        self.step_with_births(frame, &[], 0, 0.0)
    }

    /// One frame with the detections as measurements ([`LabelledPhd::update_detections`]):
    /// predict → a labelled birth at each detection farther than
    /// [`DetectionModel::birth_gate_sigmas`] from every label's prediction
    /// ([`LabelledPhd::add_labelled_births`], `per_point` particles each) → the image
    /// likelihood when `with_image` → update → border-exit and merge rules
    /// ([`LabelledPhd::update_labels_detections`]) → estimates → resampling. Returns the
    /// reported labels sorted by id. `sizes`: each measurement's box (width, height), px,
    /// for the occlusion model ([`DetectionModel::occlusion_full_visibility`]); empty or
    /// non-positive where unknown.
    ///
    /// # Errors
    /// When the frame size changes or the likelihood fails.
    pub fn step_with_detections(
        &mut self,
        frame: &Frame,
        measurements: &[BoxMeasurement],
        sizes: &[Point],
        model: &DetectionModel,
        per_point: usize,
        with_image: bool,
    ) -> Result<Vec<TrackPoint>> {
        let (w, h) = frame.size();
        let t0 = Instant::now();
        if with_image {
            self.likelihood.begin_frame(&frame.image)?;
        }
        self.times.likelihood += t0.elapsed();
        let t0 = Instant::now();
        match self.filter {
            None => {
                self.filter = Some(LabelledPhd::new(
                    self.config.clone(),
                    SurveillanceRegion::image(w, h),
                    self.seed,
                )?);
                self.frame_size = (w, h);
            }
            Some(ref mut f) => {
                if (w, h) != self.frame_size {
                    return Err(Error::FrameSize {
                        frame: frame.index,
                        got: (w, h),
                        expected: self.frame_size,
                    });
                }
                f.predict(1.0);
            }
        }
        let Some(filter) = self.filter.as_mut() else {
            return Ok(Vec::new());
        };
        // Births at the detections no label explains: none within `birth_gate_sigmas` of
        // the detection's σ from a label's mean after prediction.
        let estimates = filter.all_estimates();
        let predicted: Vec<Point> = estimates.iter().map(|e| e.pos).collect();
        let exclusive = model.label_update == LabelUpdate::Bernoulli
            && model.association == LabelAssociation::Exclusive;
        let label_pd = if exclusive && model.occlusion_full_visibility > 0.0 {
            occlusion_pds(&estimates, &self.label_size, model)
        } else {
            BTreeMap::new()
        };
        let gate2 = model.birth_gate_sigmas.powi(2);
        let claims = if exclusive && model.birth_claim_below > 0.0 {
            filter.detection_claims(
                measurements,
                model.detection_prob,
                model.clutter_per_frame,
                &label_pd,
            )
        } else {
            Vec::new()
        };
        let free: Vec<usize> = (0..measurements.len())
            .filter(|&j| {
                let m = &measurements[j];
                !predicted.iter().any(|p| mahalanobis2(m, *p) <= gate2)
                    || claims.get(j).is_some_and(|&c| c < model.birth_claim_below)
            })
            .collect();
        let born = filter.add_labelled_births(
            &free.iter().map(|&j| measurements[j]).collect::<Vec<_>>(),
            &free
                .iter()
                .map(|&j| sizes.get(j).map_or(0.0, |s| s.x.max(s.y)))
                .collect::<Vec<_>>(),
            per_point,
        );
        if model.occlusion_full_visibility > 0.0 {
            for (label, &j) in born.iter().zip(&free) {
                if let Some(&s) = sizes.get(j).filter(|s| s.x > 0.0 && s.y > 0.0) {
                    self.label_size.insert(*label, s);
                }
            }
        }
        self.times.predict += t0.elapsed();

        let t0 = Instant::now();
        let image_h = if with_image {
            filter.particles().positions_into(&mut self.positions);
            self.h.clear();
            self.h.resize(self.positions.len(), 0.0);
            self.likelihood
                .evaluate(&frame.image, &self.positions, &mut self.h)?;
            for v in &mut self.h {
                *v = if v.is_finite() {
                    v.clamp(0.0, 1.0)
                } else {
                    0.0
                };
            }
            Some(&self.h[..])
        } else {
            None
        };
        self.times.likelihood += t0.elapsed();
        let t0 = Instant::now();
        if model.label_update == LabelUpdate::Bernoulli
            && model.association == LabelAssociation::Exclusive
        {
            let best = filter.update_detections_exclusive(
                measurements,
                model.detection_prob,
                model.clutter_per_frame,
                image_h,
                &label_pd,
            );
            self.written.clear();
            self.detected = best.keys().copied().collect();
            if model.write_detection_centre {
                self.written
                    .extend(best.into_iter().map(|(l, j)| (l, measurements[j].pos)));
            }
        } else {
            self.written.clear();
            self.detected.clear();
            filter.update_detections(
                measurements,
                model.detection_prob,
                model.clutter_per_frame,
                model.label_update,
                image_h,
            );
        }
        self.times.update += t0.elapsed();
        let t0 = Instant::now();
        filter.update_labels_detections();
        if model.occlusion_full_visibility > 0.0 {
            update_sizes(
                &mut self.label_size,
                &filter.all_estimates(),
                measurements,
                sizes,
            );
        }
        self.times.labels += t0.elapsed();
        let t0 = Instant::now();
        let out = self.points(frame);
        if let Some(filter) = self.filter.as_mut() {
            filter.resample();
        }
        self.times.resample += t0.elapsed();
        self.times.steps += 1;
        Ok(out)
    }

    /// The reported labels of the filter as track points, sorted by id.
    fn points(&self, frame: &Frame) -> Vec<TrackPoint> {
        self.filter.as_ref().map_or_else(Vec::new, |filter| {
            filter
                .estimates()
                .into_iter()
                .map(|e| {
                    let mut p = estimate_point(&self.config, frame, &e);
                    if let Some(c) = self.written.get(&e.label) {
                        p.bbox = BBox::from_centre(*c, p.bbox.width, p.bbox.height);
                    }
                    p
                })
                .collect()
        })
    }

    /// [`PhdTracker::step`] with detection births: `per_point` birth particles around each
    /// of `births` ([`LabelledPhd::add_births_at`]), in addition to the grid births when
    /// they are on.
    ///
    /// # Errors
    /// When the frame size changes or the likelihood fails.
    pub fn step_with_births(
        &mut self,
        frame: &Frame,
        births: &[Point],
        per_point: usize,
        spread_px: f64,
    ) -> Result<Vec<TrackPoint>> {
        let (w, h) = frame.size();
        let t0 = Instant::now();
        self.likelihood.begin_frame(&frame.image)?;
        self.times.likelihood += t0.elapsed();
        let t0 = Instant::now();
        let first = match self.filter {
            None => {
                let mut f = LabelledPhd::new(
                    self.config.clone(),
                    SurveillanceRegion::image(w, h),
                    self.seed,
                )?;
                self.frame_size = (w, h);
                match std::mem::replace(&mut self.start, Start::Births) {
                    Start::Births => {}
                    Start::At(objects) => f.initialise_at(&objects, self.config.initial_spread_px),
                    Start::Uniform(n) => {
                        let lik = &self.likelihood;
                        let image = &frame.image;
                        f.initialise_uniform(n, &mut |pos, out| lik.evaluate(image, pos, out))?;
                    }
                }
                self.filter = Some(f);
                true
            }
            Some(_) => {
                if (w, h) != self.frame_size {
                    return Err(Error::FrameSize {
                        frame: frame.index,
                        got: (w, h),
                        expected: self.frame_size,
                    });
                }
                false
            }
        };
        let Some(filter) = self.filter.as_mut() else {
            return Ok(Vec::new());
        };
        if !first {
            filter.predict(1.0);
        }
        if self.grid_births {
            filter.add_grid_births();
        }
        filter.add_births_at(births, per_point, spread_px);
        self.times.predict += t0.elapsed();

        let t0 = Instant::now();
        filter.particles().positions_into(&mut self.positions);
        self.h.clear();
        self.h.resize(self.positions.len(), 0.0);
        self.likelihood
            .evaluate(&frame.image, &self.positions, &mut self.h)?;
        for (dst, &v) in filter.particles_mut().h.iter_mut().zip(&self.h) {
            *dst = if v.is_finite() {
                v.clamp(0.0, 1.0)
            } else {
                0.0
            };
        }
        self.times.likelihood += t0.elapsed();

        let t0 = Instant::now();
        filter.update_image();
        self.times.update += t0.elapsed();
        let t0 = Instant::now();
        filter.update_labels();
        self.times.labels += t0.elapsed();

        let t0 = Instant::now();
        let out = filter
            .estimates()
            .into_iter()
            .map(|e| estimate_point(&self.config, frame, &e))
            .collect();
        filter.resample();
        self.times.resample += t0.elapsed();
        self.times.steps += 1;
        Ok(out)
    }
}

/// Squared Mahalanobis distance of `p` from the measurement's centre.
fn mahalanobis2(m: &BoxMeasurement, p: Point) -> f64 {
    ((p.x - m.pos.x) / m.sigma.x).powi(2) + ((p.y - m.pos.y) / m.sigma.y).powi(2)
}

/// The occlusion model's `p_D` per label ([`super::occlusion`]): the labels with a known box
/// size at their predicted positions. Labels without a size keep the one `p_D`.
fn occlusion_pds(
    estimates: &[LabelEstimate],
    sizes: &BTreeMap<u32, Point>,
    model: &DetectionModel,
) -> BTreeMap<u32, f64> {
    let boxes: Vec<LabelBox> = estimates
        .iter()
        .filter_map(|e| {
            sizes.get(&e.label).map(|&size| LabelBox {
                label: e.label,
                centre: e.pos,
                size,
                weight: e.weight,
            })
        })
        .collect();
    boxes
        .iter()
        .zip(visible_fractions(&boxes))
        .map(|(b, v)| {
            (
                b.label,
                occluded_pd(model.detection_prob, v, model.occlusion_full_visibility),
            )
        })
        .collect()
}

/// Each label takes the box size of the closest measurement with a size within 3 σ of its
/// estimate (closest first, one label per measurement,
/// [`assign_closest`](crate::track::filter::detections::assign_closest)); labels that no
/// longer exist are dropped.
// Choice: a label hidden behind a neighbour keeps its last size (the neighbour's detection
// is taken by the neighbour's nearer label first).
fn update_sizes(
    label_size: &mut BTreeMap<u32, Point>,
    estimates: &[LabelEstimate],
    measurements: &[BoxMeasurement],
    sizes: &[Point],
) {
    let sized: Vec<usize> = (0..measurements.len())
        .filter(|&j| sizes.get(j).is_some_and(|s| s.x > 0.0 && s.y > 0.0))
        .collect();
    let z: Vec<BoxMeasurement> = sized.iter().map(|&j| measurements[j]).collect();
    let objects: Vec<(Point, Point)> = estimates
        .iter()
        .map(|e| (e.pos, Point::default()))
        .collect();
    let matched = crate::track::filter::detections::assign_closest(&objects, &z, 3.0, &|_, _| true);
    for (e, k) in estimates.iter().zip(matched) {
        if let Some(k) = k {
            label_size.insert(e.label, sizes[sized[k]]);
        }
    }
    label_size.retain(|l, _| estimates.iter().any(|e| e.label == *l));
}
