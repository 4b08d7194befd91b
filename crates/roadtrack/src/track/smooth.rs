//! Offline box smoothing ([`SmoothStage`]): each written box is replaced by a local linear
//! fit of its track's boxes over the frames around it, centre and size alike.
//!
//! For a point of track `i` in frame `t`, the stage takes the track's points in frames
//! `t − k … t + k` (`k` = [`SmoothConfig::half_window_frames`]) and fits, by least squares,
//! a straight line in time to each of the box's centre x, centre y, width and height; the
//! point's box becomes the lines' values at `t` (a first-order Savitzky–Golay filter on
//! unevenly spaced samples). A track seen at constant velocity keeps its path exactly; the
//! detector's frame-to-frame scatter (centre sd 1.4–2.8 px on 8–16 px cars,
//! docs/EXPERIMENTS.md "Learned detector") is averaged over up to `2k + 1` boxes.
//!
//! Choice: a local line, not a constant: a moving average would pull every box back
//! towards where the object was, by `v·k/2` at the track's ends and through any
//! acceleration. Choice: at a track's start and end the window is one-sided (the line is
//! fitted to what there is); with fewer than 3 points the box is left as it is.
//!
//! Vehicles take their own window ([`SmoothConfig::vehicle_half_window_frames`]): a car
//! keeps its course and size for longer than a walker keeps their pace, so a longer fit
//! averages more of its scatter without cutting its corners. A point's class
//! ([`ObjectClass::is_vehicle`](crate::class::ObjectClass::is_vehicle)) picks the window;
//! unclassified tracks (public detections without classes) take the general one.
//!
//! **Walkers seen from above** ([`SmoothConfig::orient_walkers`], `--orient-walkers`, off
//! by default). Looking down, a walker's box is the box of their footprint: narrower along
//! the walk (chest depth) than across it (shoulders). A detector that sees one or two pixels
//! of a walker cannot tell which way they face (the dots of `--dots` are squares), but the
//! track can: the same fit's slope of the centre is the walk's direction. With the option
//! a pedestrian's fitted box keeps its area and takes the shape of the axis-aligned box of a
//! footprint rectangle, depth : width = [`SmoothConfig::walker_depth_ratio`], turned to the
//! direction of motion; a walker slower than [`SmoothConfig::walker_min_speed_px`] keeps the
//! direction of their last steps, and one never seen moving keeps the fitted box. At one or
//! two pixels the shape is most of the overlap: a 1.15 px square on a centred 0.94 × 1.35 px
//! box has an IoU of 0.72 (docs/EXPERIMENTS.md "Walkers' boxes turned to their walk").
//!
//! The stage holds the longer window's frames (the fit looks that far ahead) and keeps each
//! track's last boxes as far back; the ids, classes, scores and frames pass unchanged.

use super::FramePoints;
use super::pipeline::PointStage;
use crate::class::ObjectClass;
use crate::error::{Error, Result};
use crate::geometry::{BBox, Point};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, VecDeque};

/// Parameters of [`SmoothStage`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SmoothConfig {
    /// `k`: frames on each side of a box that its fit looks at. 0 (the `Default`) turns
    /// smoothing off; [`SmoothConfig::recommended`] is what the commands use.
    pub half_window_frames: u32,
    /// `k` for the boxes of vehicles (car, truck, bus, motorcycle); `None`: the same as
    /// `half_window_frames`. 0 leaves vehicles unsmoothed.
    pub vehicle_half_window_frames: Option<u32>,
    /// Turn pedestrians' boxes to their direction of motion, as footprints seen from above
    /// (see the module documentation). Only for top-down views: from the side a person's
    /// box is their height, not their footprint. Needs `half_window_frames` ≥ 1.
    pub orient_walkers: bool,
    /// Depth (along the walk) over width (across it) of a walker's footprint.
    // Choice: 0.65, the simulator's walkers (0.29–0.30 m deep, 0.45–0.47 m across the
    // shoulders), about an adult's chest depth over shoulder breadth.
    pub walker_depth_ratio: f64,
    /// Below this speed (px per frame, the fit's slope) a walker's direction is not
    /// measured; their box keeps the direction of their last steps.
    // Choice: 0.05 px/frame. A walker at 1.3 m/s seen at 3 px/m and 10 frames/s moves 0.39
    // px a frame; a standing one's fitted slope is the detector's scatter over 11 frames.
    pub walker_min_speed_px: f64,
    /// Fit the centres of the general window's boxes (every class but vehicles) robustly:
    /// Huber's M-estimate with this `k` times the window's robust scale (`--smooth-robust`:
    /// 1.345); 0 (the default) is least squares. For tracks whose boxes now and then land
    /// on a neighbour or a false dot: one such box pulls a least-squares line by its whole
    /// error over the window, a Huber line by at most `k` scales.
    pub huber_k: f64,
}

impl Default for SmoothConfig {
    fn default() -> Self {
        Self {
            half_window_frames: 0,
            vehicle_half_window_frames: None,
            orient_walkers: false,
            walker_depth_ratio: 0.65,
            walker_min_speed_px: 0.05,
            huber_k: 0.0,
        }
    }
}

impl SmoothConfig {
    /// The recommended setting, what `track`, `demo` and `bench` use unless told
    /// otherwise: 5 frames on each side, vehicles too.
    // Choice: 5 frames each side (1 s at 10 frames/s). On the simulator's video scenes it
    // raised every method's HOTA (from the learned detector's boxes and from public
    // detections) and 7 did no better on walkers (docs/EXPERIMENTS.md "Box smoothing").
    // Vehicles: also 5. Nine gained 0.001–0.008 on the aerial scenes and the oblique
    // intersection from the learned detector's boxes, and lost 0.012 on the oblique road
    // (MRF), where perspective makes a car's image path and size curve within a second:
    // a setting for top-down views (`--smooth-vehicle-boxes 9`), not the default.
    pub fn recommended() -> Self {
        Self::uniform(5)
    }

    /// Every class with the same window `k` (0: off).
    pub fn uniform(k: u32) -> Self {
        Self {
            half_window_frames: k,
            ..Self::default()
        }
    }

    /// The vehicles' window.
    pub fn vehicle_window(&self) -> u32 {
        self.vehicle_half_window_frames
            .unwrap_or(self.half_window_frames)
    }

    /// Whether the stage is off.
    pub fn is_off(&self) -> bool {
        self.half_window_frames == 0 && self.vehicle_window() == 0
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        if self.half_window_frames > 1000 {
            return Err(Error::config(
                "SmoothConfig",
                "half_window_frames",
                "at most 1000 frames",
            ));
        }
        if self.vehicle_window() > 1000 {
            return Err(Error::config(
                "SmoothConfig",
                "vehicle_half_window_frames",
                "at most 1000 frames",
            ));
        }
        if self.orient_walkers && self.half_window_frames == 0 {
            return Err(Error::config(
                "SmoothConfig",
                "orient_walkers",
                "needs the box smoothing (half_window_frames ≥ 1, --smooth-boxes)",
            ));
        }
        crate::error::check_range(
            "SmoothConfig",
            "walker_depth_ratio",
            self.walker_depth_ratio,
            0.1..=1.0,
        )?;
        crate::error::check_range(
            "SmoothConfig",
            "walker_min_speed_px",
            self.walker_min_speed_px,
            0.0..=100.0,
        )?;
        if self.huber_k != 0.0 {
            crate::error::check_range("SmoothConfig", "huber_k", self.huber_k, 0.5..=10.0)?;
            if self.half_window_frames == 0 {
                return Err(Error::config(
                    "SmoothConfig",
                    "huber_k",
                    "needs the box smoothing (half_window_frames ≥ 1, --smooth-boxes)",
                ));
            }
        }
        Ok(())
    }
}

/// One box of a track: frame and centre x, centre y, width, height.
type Sample = (u32, [f64; 4]);

/// Buffers of the line fits, kept by the stage so that a fit allocates nothing.
#[derive(Debug, Default)]
struct FitBuffers {
    /// Frames relative to the fitted one.
    t: Vec<f64>,
    /// One component of the boxes.
    y: Vec<f64>,
    /// Weights.
    w: Vec<f64>,
    /// Residuals, then their sorted deviations ([`robust_line`]).
    res: Vec<f64>,
    sorted: Vec<f64>,
}

impl FitBuffers {
    /// The local linear fit at `frame` of `samples` (any order): the lines' values at
    /// `frame` and their slopes per frame; `None` under 3 samples. With `huber = Some(k)`
    /// the centre's two lines are fitted robustly ([`robust_line`]); the sizes always by
    /// least squares.
    fn fit_at(
        &mut self,
        samples: &[Sample],
        frame: u32,
        huber: Option<f64>,
    ) -> Option<([f64; 4], [f64; 4])> {
        if samples.len() < 3 {
            return None;
        }
        self.t.clear();
        self.t
            .extend(samples.iter().map(|s| f64::from(s.0) - f64::from(frame)));
        let mut out = [0.0; 4];
        let mut slopes = [0.0; 4];
        for c in 0..4 {
            self.y.clear();
            self.y.extend(samples.iter().map(|s| s.1[c]));
            self.w.clear();
            self.w.resize(samples.len(), 1.0);
            (out[c], slopes[c]) = match huber {
                Some(k) if c < 2 => robust_line(self, k),
                _ => weighted_line(&self.t, &self.y, &self.w),
            };
        }
        Some((out, slopes))
    }
}

/// Weighted least squares of `y = a + b t`: `(a, b)` (`b` = 0 when all `t` are equal).
pub(super) fn weighted_line(t: &[f64], y: &[f64], w: &[f64]) -> (f64, f64) {
    let sw: f64 = w.iter().sum();
    let mean = |v: &[f64]| v.iter().zip(w).map(|(v, w)| v * w).sum::<f64>() / sw;
    let (mean_t, mean_y) = (mean(t), mean(y));
    let (mut stt, mut sty) = (0.0, 0.0);
    for ((t, y), w) in t.iter().zip(y).zip(w) {
        stt += w * (t - mean_t) * (t - mean_t);
        sty += w * (t - mean_t) * (y - mean_y);
    }
    let slope = if stt > 0.0 { sty / stt } else { 0.0 };
    // The line's value at t = 0, the frame being smoothed.
    (mean_y - slope * mean_t, slope)
}

/// Reweightings of [`robust_line`].
// Choice: a fixed 10, not a convergence test: the same work and the same result whatever
// the data (on the aerial junctions the weights settle in 3-5).
const HUBER_ITERATIONS: usize = 10;

/// Floor of the residuals' robust scale in [`robust_line`], px.
// Choice: 0.02 px, so that a window whose boxes lie exactly on a line (a scale of 0) keeps
// weights of 1 rather than dividing by zero.
const HUBER_MIN_SCALE: f64 = 0.02;

/// Huber's M-estimate of `y = a + b t` (`b.t`, `b.y`) by iteratively reweighted least
/// squares: each round weighs a residual `r` by `min(1, c / |r|)`, `c = k · σ̂`, `σ̂ =
/// 1.4826 ·` the median absolute deviation of the last fit's residuals (Huber 1964; k =
/// 1.345 is the usual 95 % efficiency at Gaussian noise). `b.w` starts at 1 and ends with
/// the last weights.
fn robust_line(b: &mut FitBuffers, k: f64) -> (f64, f64) {
    let mut line = weighted_line(&b.t, &b.y, &b.w);
    for _ in 0..HUBER_ITERATIONS {
        b.res.clear();
        b.res
            .extend(b.t.iter().zip(&b.y).map(|(t, y)| y - (line.0 + line.1 * t)));
        let mad = median_abs_deviation(&b.res, &mut b.sorted);
        let c = k * (1.4826 * mad).max(HUBER_MIN_SCALE);
        for (w, r) in b.w.iter_mut().zip(&b.res) {
            *w = if r.abs() <= c { 1.0 } else { c / r.abs() };
        }
        line = weighted_line(&b.t, &b.y, &b.w);
    }
    line
}

/// The median of `|v − median(v)|`; `sorted` is scratch space.
fn median_abs_deviation(v: &[f64], sorted: &mut Vec<f64>) -> f64 {
    let median = |sorted: &mut Vec<f64>| {
        sorted.sort_by(f64::total_cmp);
        crate::analysis::percentile(sorted, 50.0)
    };
    sorted.clear();
    sorted.extend_from_slice(v);
    let m = median(sorted);
    sorted.clear();
    sorted.extend(v.iter().map(|x| (x - m).abs()));
    median(sorted)
}

/// The axis-aligned box, of area `area`, of a footprint `depth_ratio` times as deep as it
/// is wide turned to `heading` (radians, image axes): width and height.
fn footprint_box(area: f64, depth_ratio: f64, heading: f64) -> (f64, f64) {
    let depth = (area * depth_ratio).sqrt();
    let across = (area / depth_ratio).sqrt();
    let (c, s) = (heading.cos().abs(), heading.sin().abs());
    (c * depth + s * across, s * depth + c * across)
}

/// The box smoother between the life cycle and the sinks (see the module documentation).
#[derive(Debug)]
pub struct SmoothStage {
    /// The general window.
    k: u32,
    /// The vehicles' window.
    k_vehicle: u32,
    /// The longer of the two: frames held back and kept.
    k_max: u32,
    /// `Some((depth_ratio, min_speed))` when walkers' boxes are turned to their motion.
    orient: Option<(f64, f64)>,
    /// Huber's `k` of the general window's centre fits; `None`: least squares.
    huber_k: Option<f64>,
    /// Each walker's last measured direction of motion (radians).
    heading: BTreeMap<u64, f64>,
    /// The fits' buffers.
    fit: FitBuffers,
    held: VecDeque<FramePoints>,
    /// Each track's boxes in the frames still needed: the `k` frames before the next frame
    /// to leave, and every frame held.
    samples: BTreeMap<u64, VecDeque<Sample>>,
}

impl SmoothStage {
    /// A stage with no tracks yet.
    ///
    /// # Errors
    /// An invalid configuration.
    pub fn new(config: SmoothConfig) -> Result<Self> {
        config.validate()?;
        let (k, k_vehicle) = (config.half_window_frames, config.vehicle_window());
        Ok(Self {
            k,
            k_vehicle,
            k_max: k.max(k_vehicle),
            orient: config
                .orient_walkers
                .then_some((config.walker_depth_ratio, config.walker_min_speed_px)),
            heading: BTreeMap::new(),
            huber_k: (config.huber_k > 0.0).then_some(config.huber_k),
            fit: FitBuffers::default(),
            held: VecDeque::new(),
            samples: BTreeMap::new(),
        })
    }

    /// Writes the oldest held frame with its boxes smoothed.
    fn release(&mut self) -> Option<FramePoints> {
        let mut fp = self.held.pop_front()?;
        let frame = fp.frame;
        let mut window: Vec<Sample> = Vec::new();
        for p in &mut fp.points {
            let (k, huber) = if p.class.is_vehicle() {
                (self.k_vehicle, None)
            } else {
                (self.k, self.huber_k)
            };
            let Some(series) = self.samples.get(&p.id).filter(|_| k > 0) else {
                continue;
            };
            window.clear();
            window.extend(series.iter().filter(|s| s.0.abs_diff(frame) <= k).copied());
            if let Some(([x, y, mut w, mut h], [vx, vy, _, _])) =
                self.fit.fit_at(&window, frame, huber)
                && [x, y, w, h].iter().all(|v| v.is_finite())
                && w > 0.0
                && h > 0.0
            {
                if let Some((ratio, min_speed)) = self.orient
                    && p.class == ObjectClass::Pedestrian
                {
                    if vx.hypot(vy) >= min_speed.max(f64::MIN_POSITIVE) {
                        self.heading.insert(p.id, vy.atan2(vx));
                    }
                    if let Some(&heading) = self.heading.get(&p.id) {
                        (w, h) = footprint_box(w * h, ratio, heading);
                    }
                }
                p.bbox = BBox::from_centre(Point::new(x, y), w, h);
            }
        }
        // Keep what the next frames' fits need.
        let oldest = frame.saturating_add(1).saturating_sub(self.k_max);
        for series in self.samples.values_mut() {
            while series.front().is_some_and(|s| s.0 < oldest) {
                series.pop_front();
            }
        }
        self.samples.retain(|_, s| !s.is_empty());
        let samples = &self.samples;
        self.heading.retain(|id, _| samples.contains_key(id));
        Some(fp)
    }
}

impl PointStage for SmoothStage {
    fn push(&mut self, frame: FramePoints) -> Result<Vec<FramePoints>> {
        if self.k_max == 0 {
            return Ok(vec![frame]);
        }
        if let Some(last) = self.held.back()
            && frame.frame <= last.frame
        {
            return Err(Error::Invalid(format!(
                "box smoothing: frame {} after frame {}: frames must increase",
                frame.frame, last.frame
            )));
        }
        for p in &frame.points {
            let c = p.bbox.centre();
            self.samples
                .entry(p.id)
                .or_default()
                .push_back((frame.frame, [c.x, c.y, p.bbox.width, p.bbox.height]));
        }
        let newest = frame.frame;
        self.held.push_back(frame);
        let mut out = Vec::new();
        // A frame leaves once the frame k later has come (its fit has its whole window).
        while self
            .held
            .front()
            .is_some_and(|f| newest - f.frame >= self.k_max)
        {
            out.extend(self.release());
        }
        Ok(out)
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        // `release` gives every held frame, oldest first, then `None`.
        Ok(std::iter::from_fn(|| self.release()).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track_point::TrackPoint;

    fn point(frame: u32, id: u64, x: f64, y: f64, w: f64) -> TrackPoint {
        let bbox = BBox::from_centre(Point::new(x, y), w, w / 2.0);
        crate::track::point_at(frame, id, ObjectClass::Car, bbox)
    }

    fn run(config: SmoothConfig, input: Vec<FramePoints>) -> Result<Vec<FramePoints>> {
        let mut s = SmoothStage::new(config)?;
        let mut out = Vec::new();
        for f in input {
            out.extend(s.push(f)?);
        }
        out.extend(s.finish()?);
        Ok(out)
    }

    /// Every point of `got` has the frame, id, class and box (to 1e-9 px) of the same
    /// point of `want`, both in (frame, id) order.
    fn assert_same_boxes(got: &[TrackPoint], want: &[TrackPoint]) {
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(want) {
            assert_eq!((g.frame, g.id, &g.class), (w.frame, w.id, &w.class));
            for (u, v) in [
                (g.bbox.left, w.bbox.left),
                (g.bbox.top, w.bbox.top),
                (g.bbox.width, w.bbox.width),
                (g.bbox.height, w.bbox.height),
            ] {
                assert!((u - v).abs() < 1e-9, "{g:?} {w:?}");
            }
        }
    }

    use crate::track::frames_of as frames;

    /// The naive reference: for each point, every point of its track within k frames,
    /// least squares of [1, t] by the normal equations, in one pass over the whole track.
    fn reference(points: &[TrackPoint], k: u32) -> Vec<TrackPoint> {
        points
            .iter()
            .map(|p| {
                let near: Vec<&TrackPoint> = points
                    .iter()
                    .filter(|q| q.id == p.id && q.frame.abs_diff(p.frame) <= k)
                    .collect();
                if near.len() < 3 {
                    return p.clone();
                }
                let vals = |q: &TrackPoint| {
                    let c = q.bbox.centre();
                    [c.x, c.y, q.bbox.width, q.bbox.height]
                };
                let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
                let mut b0 = [0.0; 4];
                let mut b1 = [0.0; 4];
                for q in &near {
                    let t = f64::from(q.frame) - f64::from(p.frame);
                    s0 += 1.0;
                    s1 += t;
                    s2 += t * t;
                    for (c, v) in vals(q).iter().enumerate() {
                        b0[c] += v;
                        b1[c] += t * v;
                    }
                }
                let det = s0 * s2 - s1 * s1;
                let at0 = |c: usize| (s2 * b0[c] - s1 * b1[c]) / det;
                let mut out = p.clone();
                out.bbox = BBox::from_centre(Point::new(at0(0), at0(1)), at0(2), at0(3));
                out
            })
            .collect()
    }

    #[test]
    fn constant_velocity_tracks_pass_unchanged() -> Result<()> {
        let pts: Vec<TrackPoint> = (1..=30)
            .map(|f| point(f, 1, 3.0 * f64::from(f), 40.0 - 0.5 * f64::from(f), 20.0))
            .collect();
        let out = run(SmoothConfig::uniform(5), frames(&pts, 30))?;
        assert_eq!(out.len(), 30);
        for (f, p) in out.iter().zip(&pts) {
            assert_eq!(f.points.len(), 1);
            let (a, b) = (f.points[0].bbox, p.bbox);
            for (u, v) in [
                (a.left, b.left),
                (a.top, b.top),
                (a.width, b.width),
                (a.height, b.height),
            ] {
                assert!((u - v).abs() < 1e-9, "{a:?} {b:?}");
            }
        }
        Ok(())
    }

    #[test]
    fn boxes_match_the_naive_fit_and_jitter_shrinks() -> Result<()> {
        // Two tracks with alternating ±2 px jitter on a straight path, one with a gap and
        // one starting late; frame 40 has no point at all.
        let mut pts = Vec::new();
        for f in 1..=60u32 {
            let j = if f % 2 == 0 { 2.0 } else { -2.0 };
            if f != 40 && !(20..=24).contains(&f) {
                pts.push(point(f, 1, 2.0 * f64::from(f) + j, 100.0, 30.0 + j));
            }
            if f >= 10 && f != 40 {
                pts.push(point(f, 2, 500.0 - f64::from(f), 50.0 - j, 12.0));
            }
        }
        let k = 4;
        let out = run(SmoothConfig::uniform(k), frames(&pts, 60))?;
        let got: Vec<TrackPoint> = out.iter().flat_map(|f| f.points.clone()).collect();
        let mut want = reference(&pts, k);
        want.sort_by_key(|p| (p.frame, p.id));
        assert_same_boxes(&got, &want);
        // Away from the ends the ±2 px jitter falls below 0.5 px.
        let inner = got
            .iter()
            .filter(|p| p.id == 1 && (30..=36).contains(&p.frame))
            .map(|p| (p.bbox.centre().x - 2.0 * f64::from(p.frame)).abs())
            .fold(0.0, f64::max);
        assert!(inner < 0.5, "{inner}");
        // Every frame leaves once, in order, the empty one too.
        assert_eq!(
            out.iter().map(|f| f.frame).collect::<Vec<_>>(),
            (1..=60).collect::<Vec<_>>()
        );
        Ok(())
    }

    #[test]
    fn off_passes_frames_through_and_bad_input_is_an_error() -> Result<()> {
        let pts: Vec<TrackPoint> = (1..=5)
            .map(|f| point(f, 1, f64::from(f * f), 0.0, 8.0))
            .collect();
        let input = frames(&pts, 5);
        assert_eq!(run(SmoothConfig::uniform(0), input.clone())?, input);
        let mut s = SmoothStage::new(SmoothConfig::uniform(2))?;
        s.push(input[2].clone())?;
        let e = s.push(input[1].clone()).expect_err("out of order");
        assert!(e.to_string().contains("frames must increase"), "{e}");
        let e = SmoothStage::new(SmoothConfig::uniform(5000)).expect_err("too wide");
        assert!(e.to_string().contains("half_window_frames"), "{e}");
        let e = SmoothStage::new(SmoothConfig {
            vehicle_half_window_frames: Some(5000),
            ..SmoothConfig::uniform(5)
        })
        .expect_err("too wide");
        assert!(e.to_string().contains("vehicle_half_window_frames"), "{e}");
        Ok(())
    }

    #[test]
    fn vehicles_and_walkers_take_their_own_windows() -> Result<()> {
        // A car and a pedestrian with the same jitter on straight paths, and an unclassified
        // track: each box is the naive fit over its class's window.
        let mut pts = Vec::new();
        for f in 1..=50u32 {
            let j = if f % 3 == 0 { 2.0 } else { -1.0 };
            pts.push(point(f, 1, 3.0 * f64::from(f) + j, 80.0, 30.0 - j));
            let mut walker = point(f, 2, 200.0 + 0.5 * f64::from(f), 60.0 + j, 10.0);
            walker.class = ObjectClass::Pedestrian;
            pts.push(walker);
            let mut other = point(f, 3, 400.0 - f64::from(f), 20.0 - j, 12.0);
            other.class = ObjectClass::Unknown;
            pts.push(other);
        }
        let config = SmoothConfig {
            vehicle_half_window_frames: Some(6),
            ..SmoothConfig::uniform(2)
        };
        assert!(!config.is_off() && SmoothConfig::uniform(0).is_off());
        let out = run(config, frames(&pts, 50))?;
        let got: Vec<TrackPoint> = out.iter().flat_map(|f| f.points.clone()).collect();
        let car: Vec<TrackPoint> = pts.iter().filter(|p| p.id == 1).cloned().collect();
        let rest: Vec<TrackPoint> = pts.iter().filter(|p| p.id != 1).cloned().collect();
        let mut want = reference(&car, 6);
        want.extend(reference(&rest, 2));
        want.sort_by_key(|p| (p.frame, p.id));
        assert_same_boxes(&got, &want);
        // The two windows differ where it shows: the car's fit is not the short one.
        let short = reference(&car, 2);
        assert!(
            got.iter()
                .filter(|p| p.id == 1)
                .zip(&short)
                .any(|(g, s)| (g.bbox.left - s.bbox.left).abs() > 0.1)
        );
        // A vehicle window of 0 leaves the car's boxes as they came.
        let config = SmoothConfig {
            vehicle_half_window_frames: Some(0),
            ..SmoothConfig::uniform(2)
        };
        let out = run(config, frames(&pts, 50))?;
        for g in out.iter().flat_map(|f| &f.points).filter(|p| p.id == 1) {
            assert_eq!(Some(g), car.iter().find(|c| c.frame == g.frame));
        }
        Ok(())
    }

    #[test]
    fn a_footprint_box_keeps_its_area_and_turns_with_the_heading() {
        let (w, h) = footprint_box(1.44, 0.65, 0.0);
        assert!((w * h - 1.44).abs() < 1e-12 && (w / h - 0.65).abs() < 1e-12);
        // A quarter turn swaps the sides, a half turn changes nothing.
        let (w2, h2) = footprint_box(1.44, 0.65, std::f64::consts::FRAC_PI_2);
        assert!((w2 - h).abs() < 1e-12 && (h2 - w).abs() < 1e-12);
        let (w3, h3) = footprint_box(1.44, 0.65, -std::f64::consts::PI);
        assert!((w3 - w).abs() < 1e-12 && (h3 - h).abs() < 1e-12);
        // At 45° the box is square and holds the footprint's diagonal extent.
        let (w4, h4) = footprint_box(1.44, 0.65, std::f64::consts::FRAC_PI_4);
        assert!((w4 - h4).abs() < 1e-12);
        assert!((w4 - (w + h) / 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn walkers_boxes_turn_to_their_walk_and_nothing_else_changes() -> Result<()> {
        // Square 1.2 px dots: walker 1 walks along x, walker 2 along y then stands still,
        // walker 3 never moves, and a car drives along x.
        let dot = |f: u32, id: u64, x: f64, y: f64| {
            let bbox = BBox::from_centre(Point::new(x, y), 1.2, 1.2);
            crate::track::point_at(f, id, ObjectClass::Pedestrian, bbox)
        };
        let mut pts = Vec::new();
        for f in 1..=40u32 {
            let t = f64::from(f);
            pts.push(dot(f, 1, 10.0 + 0.4 * t, 50.0));
            pts.push(dot(f, 2, 100.0, 10.0 + 0.4 * t.min(20.0)));
            pts.push(dot(f, 3, 200.0, 200.0));
            pts.push(point(f, 4, 3.0 * t, 300.0, 12.0));
        }
        let config = SmoothConfig {
            orient_walkers: true,
            ..SmoothConfig::uniform(5)
        };
        let out = run(config, frames(&pts, 40))?;
        let got: Vec<TrackPoint> = out.iter().flat_map(|f| f.points.clone()).collect();
        let plain = run(SmoothConfig::uniform(5), frames(&pts, 40))?;
        let plain: Vec<TrackPoint> = plain.iter().flat_map(|f| f.points.clone()).collect();
        let (deep, wide) = footprint_box(1.44, 0.65, 0.0);
        for (g, p) in got.iter().zip(&plain) {
            // Centres, frames, ids and classes are the plain fit's.
            assert_eq!((g.frame, g.id), (p.frame, p.id));
            let (a, b) = (g.bbox.centre(), p.bbox.centre());
            assert!((a.x - b.x).abs() < 1e-9 && (a.y - b.y).abs() < 1e-9);
            let (w, h) = (g.bbox.width, g.bbox.height);
            let want = match g.id {
                1 => (deep, wide),
                // Walking along y, and standing still later: its last direction.
                2 => (wide, deep),
                _ => (p.bbox.width, p.bbox.height),
            };
            assert!(
                (w - want.0).abs() < 1e-9 && (h - want.1).abs() < 1e-9,
                "{g:?} want {want:?}"
            );
        }
        // Walker 2 did stand still: its fitted slope is 0 at the end.
        assert!(
            got.iter()
                .filter(|p| p.id == 2 && p.frame > 30)
                .all(|p| (p.bbox.centre().y - 18.0).abs() < 1e-9)
        );
        Ok(())
    }

    #[test]
    fn bad_walker_settings_name_the_field() {
        for (config, field) in [
            (
                SmoothConfig {
                    orient_walkers: true,
                    ..SmoothConfig::uniform(0)
                },
                "orient_walkers",
            ),
            (
                SmoothConfig {
                    walker_depth_ratio: 0.0,
                    ..SmoothConfig::uniform(5)
                },
                "walker_depth_ratio",
            ),
            (
                SmoothConfig {
                    walker_min_speed_px: f64::NAN,
                    ..SmoothConfig::uniform(5)
                },
                "walker_min_speed_px",
            ),
        ] {
            let e = SmoothStage::new(config).expect_err(field);
            assert!(e.to_string().contains(field), "{e}");
        }
    }

    #[test]
    fn the_huber_line_ignores_an_outlier_that_pulls_least_squares() {
        // y = 2 + 0.5 t with ±0.05 alternating noise over t = -6..=6, one point 4 px off.
        let t: Vec<f64> = (-6..=6).map(f64::from).collect();
        let mut y: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(i, t)| 2.0 + 0.5 * t + if i % 2 == 0 { 0.05 } else { -0.05 })
            .collect();
        y[9] += 4.0;
        let ones = vec![1.0; t.len()];
        let (a_ls, _) = weighted_line(&t, &y, &ones);
        let huber = |y: &[f64]| {
            let mut b = FitBuffers {
                t: t.clone(),
                y: y.to_vec(),
                w: ones.clone(),
                ..FitBuffers::default()
            };
            (robust_line(&mut b, 1.345), b.w)
        };
        let ((a, b), w) = huber(&y);
        assert!((a_ls - 2.0).abs() > 0.25, "least squares {a_ls}");
        assert!((a - 2.0).abs() < 0.05 && (b - 0.5).abs() < 0.02, "{a} {b}");
        // The outlier ends with the smallest weight, the others near 1.
        let low = w.iter().copied().fold(f64::INFINITY, f64::min);
        assert_eq!(w[9], low);
        assert!(
            w[9] < 0.05 && w.iter().filter(|&&v| v < 0.5).count() == 1,
            "{w:?}"
        );
        // On an exact line both fits are the line.
        let exact: Vec<f64> = t.iter().map(|t| -1.0 + 0.25 * t).collect();
        let ((a, b), _) = huber(&exact);
        assert!((a + 1.0).abs() < 1e-12 && (b - 0.25).abs() < 1e-12);
        let mut scratch = Vec::new();
        assert_eq!(
            median_abs_deviation(&[1.0, 2.0, 3.0, 4.0, 100.0], &mut scratch),
            1.0
        );
        assert_eq!(
            median_abs_deviation(&[1.0, 2.0, 4.0, 8.0], &mut scratch),
            1.5
        );
    }

    #[test]
    fn a_robust_fit_keeps_a_walker_on_its_path_and_leaves_vehicles_alone() -> Result<()> {
        // A walker on a straight line whose box lands on a neighbour 3 px away in frames 20
        // and 21, and a car with the same jump.
        let mut pts = Vec::new();
        for f in 1..=40u32 {
            let jump = if (20..=21).contains(&f) { 3.0 } else { 0.0 };
            let mut walker = point(f, 1, 10.0 + 0.4 * f64::from(f), 50.0 + jump, 2.0);
            walker.class = ObjectClass::Pedestrian;
            pts.push(walker);
            pts.push(point(f, 2, 3.0 * f64::from(f), 200.0 + jump, 12.0));
        }
        let robust = SmoothConfig {
            huber_k: 1.345,
            ..SmoothConfig::uniform(8)
        };
        let got = run(robust, frames(&pts, 40))?;
        let plain = run(SmoothConfig::uniform(8), frames(&pts, 40))?;
        let off_path = |out: &[FramePoints], id: u64, y: f64| {
            out.iter()
                .flat_map(|f| &f.points)
                .filter(|p| p.id == id)
                .map(|p| (p.bbox.centre().y - y).abs())
                .fold(0.0, f64::max)
        };
        // Least squares spreads the jump over the window (3 px × 2 / up to 17 boxes); the
        // Huber line stays on the walker's path, the jump frames included.
        assert!(off_path(&plain, 1, 50.0) > 0.3);
        assert!(
            off_path(&got, 1, 50.0) < 0.05,
            "{}",
            off_path(&got, 1, 50.0)
        );
        // The car takes the vehicles' window and its least squares.
        let car = |out: &[FramePoints]| -> Vec<TrackPoint> {
            out.iter()
                .flat_map(|f| f.points.iter().filter(|p| p.id == 2).cloned())
                .collect()
        };
        assert_same_boxes(&car(&got), &car(&plain));
        let e = SmoothStage::new(SmoothConfig {
            huber_k: 0.2,
            ..SmoothConfig::uniform(5)
        })
        .expect_err("k too small");
        assert!(e.to_string().contains("huber_k"), "{e}");
        Ok(())
    }
}
