//! Ground positions, speeds and headings of tracks from image positions and a mapping to
//! the ground plane.
//!
//! Smoother: for every point, a straight line is fitted by least squares to the object's
//! ground positions within ±`half_window_s` of it (x and y separately against time); the
//! fitted value is the smoothed position and the slope the velocity. This is a first-order
//! Savitzky–Golay filter that also works with missing frames and uneven time steps. At the
//! ends of a track the window is one-sided, so the velocity there is a one-sided estimate.

use crate::error::{Error, Result};
use crate::geometry::Point;
use crate::track::{FramePoints, PointStage};
use crate::track_point::{GroundState, TrackPoint};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, VecDeque};

/// Which image point of a box stands on the ground.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum GroundPoint {
    /// The middle of the box's bottom edge: where a vehicle or a person touches the road in
    /// an oblique view. Default.
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "Middle of the bottom edge (oblique views)")
    )]
    BottomCentre,
    /// The box centre: right for nadir (aerial) views.
    #[cfg_attr(feature = "clap", value(help = "Box centre (nadir views)"))]
    Centre,
}

/// Parameters of the ground-speed smoother.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct KinematicsConfig {
    /// Half-width of the local line fit, s. Default 0.5 s (±5 frames at 10 fps).
    pub half_window_s: f64,
    /// Which point of the box is mapped to the ground.
    pub ground_point: GroundPoint,
}

impl Default for KinematicsConfig {
    fn default() -> Self {
        Self {
            half_window_s: 0.5,
            ground_point: GroundPoint::BottomCentre,
        }
    }
}

/// Sets `ground` on every point: position from `ground_from_image` (image px → ground m)
/// applied to the chosen box point, smoothed; speed and heading from the local slope.
///
/// # Errors
/// The mapping fails for a point (e.g. above the horizon of an oblique calibration): the
/// error names the frame and id.
pub fn attach_ground(
    points: &mut [TrackPoint],
    ground_from_image: &dyn Fn(Point) -> Option<Point>,
    config: &KinematicsConfig,
) -> Result<()> {
    config.validate()?;
    let mut by_id: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for (i, p) in points.iter().enumerate() {
        by_id.entry(p.id).or_default().push(i);
    }
    for idx in by_id.values_mut() {
        idx.sort_by(|&a, &b| points[a].time_s.total_cmp(&points[b].time_s));
        let mut raw = Vec::with_capacity(idx.len());
        for &i in idx.iter() {
            raw.push((
                points[i].time_s,
                raw_ground(&points[i], ground_from_image, config)?,
            ));
        }
        for (k, &i) in idx.iter().enumerate() {
            points[i].ground = Some(smoothed(raw.iter(), raw[k].0, config));
        }
    }
    Ok(())
}

impl KinematicsConfig {
    /// Checks the window.
    ///
    /// # Errors
    /// A negative or NaN half window.
    pub fn validate(&self) -> Result<()> {
        crate::error::check_range(
            "KinematicsConfig",
            "half_window_s",
            self.half_window_s,
            0.0..,
        )?;
        Ok(())
    }
}

/// The unsmoothed ground position of `p`'s chosen box point.
fn raw_ground(
    p: &TrackPoint,
    ground_from_image: &dyn Fn(Point) -> Option<Point>,
    config: &KinematicsConfig,
) -> Result<Point> {
    let img = match config.ground_point {
        GroundPoint::BottomCentre => Point::new(p.bbox.centre().x, p.bbox.bottom()),
        GroundPoint::Centre => p.bbox.centre(),
    };
    ground_from_image(img).ok_or_else(|| {
        Error::Invalid(format!(
            "frame {}, id {}: image point ({:.1}, {:.1}) px has no ground position under the calibration",
            p.frame, p.id, img.x, img.y
        ))
    })
}

/// The ground state at `t0` from a track's `(time, raw ground)` samples in time order: the
/// local line through those within the half window.
fn smoothed<'a>(
    samples: impl Iterator<Item = &'a (f64, Point)>,
    t0: f64,
    config: &KinematicsConfig,
) -> GroundState {
    let window = samples.filter(|(t, _)| (t - t0).abs() <= config.half_window_s + 1e-9);
    let (pos, vel) = local_line(window, t0);
    GroundState {
        x_m: pos.x,
        y_m: pos.y,
        speed_mps: vel.x.hypot(vel.y),
        heading_deg: vel.y.atan2(vel.x).to_degrees(),
    }
}

/// [`attach_ground`] as the points come, frame by frame in time order: a frame leaves once
/// a frame more than the half window later has come (or at the end), so it holds about one
/// window of frames and, per track, one window of samples on each side. The results are
/// those of [`attach_ground`] over the whole run, bit for bit.
pub struct GroundSmoother<'a> {
    ground_from_image: Box<dyn Fn(Point) -> Option<Point> + 'a>,
    config: KinematicsConfig,
    held: VecDeque<FramePoints>,
    /// Per track id: `(time, raw ground)` samples still inside some held frame's window.
    history: BTreeMap<u64, VecDeque<(f64, Point)>>,
}

impl std::fmt::Debug for GroundSmoother<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GroundSmoother")
            .field("config", &self.config)
            .field("held", &self.held.len())
            .finish_non_exhaustive()
    }
}

impl<'a> GroundSmoother<'a> {
    /// A smoother mapping image px to ground m with `ground_from_image`.
    ///
    /// # Errors
    /// An invalid config.
    pub fn new(
        ground_from_image: Box<dyn Fn(Point) -> Option<Point> + 'a>,
        config: KinematicsConfig,
    ) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            ground_from_image,
            config,
            held: VecDeque::new(),
            history: BTreeMap::new(),
        })
    }

    /// Releases the oldest held frame with its ground states set.
    fn release(&mut self) -> Option<FramePoints> {
        let mut f = self.held.pop_front()?;
        for p in &mut f.points {
            if let Some(h) = self.history.get(&p.id) {
                p.ground = Some(smoothed(h.iter(), p.time_s, &self.config));
            }
        }
        // Samples older than every remaining window are no longer needed (with a margin, so
        // rounding never drops one the window test would keep).
        let limit = self
            .held
            .front()
            .map(|n| n.time_s - 2.0 * self.config.half_window_s - 1e-6);
        self.history.retain(|_, h| {
            match limit {
                Some(limit) => {
                    while h.front().is_some_and(|s| s.0 < limit) {
                        h.pop_front();
                    }
                }
                None => h.clear(),
            }
            !h.is_empty()
        });
        Some(f)
    }
}

impl PointStage for GroundSmoother<'_> {
    fn push(&mut self, frame: FramePoints) -> Result<Vec<FramePoints>> {
        for p in &frame.points {
            let g = raw_ground(p, &*self.ground_from_image, &self.config)?;
            self.history
                .entry(p.id)
                .or_default()
                .push_back((p.time_s, g));
        }
        let latest = frame.time_s;
        self.held.push_back(frame);
        let mut out = Vec::new();
        while self
            .held
            .front()
            .is_some_and(|f| latest - f.time_s > self.config.half_window_s + 1e-9)
        {
            out.extend(self.release());
        }
        Ok(out)
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        let mut out = Vec::new();
        while let Some(f) = self.release() {
            out.push(f);
        }
        Ok(out)
    }
}

/// Least-squares line through `(t, p)` pairs evaluated at `t0`: (value, slope).
fn local_line<'a>(samples: impl Iterator<Item = &'a (f64, Point)>, t0: f64) -> (Point, Point) {
    let (mut n, mut st, mut stt, mut sx, mut sy, mut stx, mut sty) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (t, p) in samples {
        let dt = t - t0;
        n += 1.0;
        st += dt;
        stt += dt * dt;
        sx += p.x;
        sy += p.y;
        stx += dt * p.x;
        sty += dt * p.y;
    }
    let det = n * stt - st * st;
    if n < 2.0 || det.abs() < 1e-12 {
        return (
            Point::new(sx / n.max(1.0), sy / n.max(1.0)),
            Point::new(0.0, 0.0),
        );
    }
    let bx = (n * stx - st * sx) / det;
    let by = (n * sty - st * sy) / det;
    let ax = (sx - bx * st) / n;
    let ay = (sy - by * st) / n;
    (Point::new(ax, ay), Point::new(bx, by))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::class::ObjectClass;
    use crate::geometry::BBox;
    use rand::RngExt;

    fn track(
        id: u64,
        n: u32,
        f: impl Fn(f64) -> Point,
        noise_px: f64,
        seed: u64,
    ) -> Vec<TrackPoint> {
        let mut rng = crate::rng::rng_for(seed, crate::rng::Stream::Synthetic, id);
        (1..=n)
            .map(|i| {
                let t = f64::from(i - 1) / 10.0;
                let c = f(t);
                let (nx, ny) = (
                    rng.random_range(-noise_px..=noise_px),
                    rng.random_range(-noise_px..=noise_px),
                );
                TrackPoint {
                    frame: i,
                    time_s: t,
                    id,
                    class: ObjectClass::Car,
                    bbox: BBox::from_centre(Point::new(c.x + nx, c.y + ny), 10.0, 10.0),
                    score: 1.0,
                    ground: None,
                }
            })
            .collect()
    }

    #[test]
    fn constant_speed_is_recovered_within_tolerance_under_pixel_noise() -> Result<()> {
        // 0.1 m/px nadir view; 13.9 m/s (50 km/h) along +x, heading 0; ±1 px noise.
        let mpp = 0.1;
        let mut pts = track(1, 100, |t| Point::new(20.0 + 139.0 * t, 200.0), 1.0, 3);
        let cfg = KinematicsConfig {
            ground_point: GroundPoint::Centre,
            ..Default::default()
        };
        attach_ground(&mut pts, &|p| Some(Point::new(p.x * mpp, p.y * mpp)), &cfg)?;
        for p in &pts {
            let g = p.ground.expect("ground set");
            // ±1 px uniform noise over an 11-point fit: tolerance 0.5 m/s (3.6 %).
            assert!(
                (g.speed_mps - 13.9).abs() < 0.5,
                "frame {}: {}",
                p.frame,
                g.speed_mps
            );
            assert!(
                g.heading_deg.abs() < 3.0,
                "frame {}: {}",
                p.frame,
                g.heading_deg
            );
        }
        Ok(())
    }

    #[test]
    fn exact_line_gives_exact_speed_and_heading() -> Result<()> {
        let mut pts = track(7, 20, |t| Point::new(10.0 * t, 10.0 * t), 0.0, 0);
        let cfg = KinematicsConfig {
            ground_point: GroundPoint::Centre,
            ..Default::default()
        };
        attach_ground(&mut pts, &|p| Some(p), &cfg)?;
        for p in &pts {
            let g = p.ground.expect("ground");
            assert!((g.speed_mps - 200f64.sqrt()).abs() < 1e-9);
            assert!((g.heading_deg - 45.0).abs() < 1e-9);
            assert!((g.x_m - p.bbox.centre().x).abs() < 1e-9);
        }
        Ok(())
    }

    #[test]
    fn unmappable_point_names_frame_and_id() {
        let mut pts = track(4, 3, |_| Point::new(1.0, 1.0), 0.0, 0);
        let e = attach_ground(&mut pts, &|_| None, &KinematicsConfig::default())
            .expect_err("no ground")
            .to_string();
        assert!(e.contains("frame 1") && e.contains("id 4"), "{e}");
    }
}
