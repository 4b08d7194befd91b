//! The shared track life cycle as a pipeline stage after any method ([`LifecycleStage`]):
//!
//! - **tentative → confirmed**: a track's points are written only once it has been seen in
//!   `confirm_hits` frames (Stone Soup's "M of N" initiator in its simplest form); a track
//!   that never gets there (a shadow, a one-frame split) writes nothing;
//! - **coasting**: a confirmed track that misses up to `max_coast_frames` frames and then
//!   comes back under the same id gets a box in each missed frame, interpolated between the
//!   box before and the box after the gap; a longer gap, or no return, ends it;
//! - **box size** smoothed per track (centre kept): `w ← α·w_new + (1 − α)·w`;
//! - **a class per track**: the majority of its points' classes so far, looking
//!   `delay` frames ahead (ties: the class seen first), so one track never flickers
//!   between car and truck.
//!
//! The stage holds `delay = max(confirm_hits − 1, max_coast_frames)` frames back, so the
//! decisions above use that much of the future; memory is that many frames of points.
//! Association stays each method's own: the stage never changes an id.

use super::FramePoints;
use super::pipeline::PointStage;
use crate::class::ObjectClass;
use crate::error::{Error, Result};
use crate::geometry::BBox;
use crate::track_point::TrackPoint;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, VecDeque};

/// Parameters of the shared life cycle ([`LifecycleStage`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LifecycleConfig {
    /// Frames a track must be seen in before it is written. Default 8; 1 writes every
    /// track (the methods as published).
    // Choice: 8 (0.8 s at 10 frames/s; it was 3 until 2026-11-30). From the learned
    // detector's boxes it gains 0.001-0.008 HOTA on the road and crossing scenes and
    // changes nothing on the oblique intersection; from public detections it moves HOTA
    // by -0.001 to +0.003 (docs/EXPERIMENTS.md "Eight hits to confirm"). The stage holds
    // max(hits - 1, coast) frames back, 10 either way with the default coasting.
    pub confirm_hits: u32,
    /// Missed frames a confirmed track may coast through (boxes interpolated), frames.
    /// Default 10 (1 s at 10 frames/s); 0 fills no gaps.
    pub max_coast_frames: u32,
    /// `α`, the weight of a new box size against the track's smoothed size, in `(0, 1]`.
    /// Default 0.5; 1 keeps each frame's size.
    pub box_alpha: f64,
    /// Whether each point takes its track's majority class. Default true.
    pub class_by_majority: bool,
}

impl Default for LifecycleConfig {
    fn default() -> Self {
        Self {
            confirm_hits: 8,
            max_coast_frames: 10,
            box_alpha: 0.5,
            class_by_majority: true,
        }
    }
}

impl LifecycleConfig {
    /// The methods as published: every point written as the method gave it.
    pub fn off() -> Self {
        Self {
            confirm_hits: 1,
            max_coast_frames: 0,
            box_alpha: 1.0,
            class_by_majority: false,
        }
    }

    /// Whether the stage would change nothing.
    pub fn is_off(&self) -> bool {
        self.confirm_hits <= 1
            && self.max_coast_frames == 0
            && self.box_alpha == 1.0
            && !self.class_by_majority
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        if self.confirm_hits == 0 {
            return Err(Error::config(
                "LifecycleConfig",
                "confirm_hits",
                "must be at least 1",
            ));
        }
        if self.confirm_hits > 1000 || self.max_coast_frames > 10_000 {
            return Err(Error::config(
                "LifecycleConfig",
                "confirm_hits/max_coast_frames",
                "at most 1000 and 10000 frames",
            ));
        }
        if !(self.box_alpha > 0.0 && self.box_alpha <= 1.0) {
            return Err(Error::config(
                "LifecycleConfig",
                "box_alpha",
                "must be in (0, 1]",
            ));
        }
        Ok(())
    }
}

/// What the stage knows of one track.
#[derive(Debug, Clone, Default)]
struct TrackState {
    /// Frames the track was seen in (pushed so far, including the frames held back).
    hits: u32,
    /// Last frame it was pushed in.
    last_seen: u32,
    confirmed: bool,
    /// The last point written (smoothed box, final class).
    last_written: Option<TrackPoint>,
    /// Smoothed width and height.
    size: Option<(f64, f64)>,
    /// Class votes.
    votes: ClassVotes,
}

impl TrackState {
    fn majority(&self) -> Option<ObjectClass> {
        self.votes.majority()
    }
}

/// A track's class votes, with the order each class was first seen.
#[derive(Debug, Clone, Default)]
pub(crate) struct ClassVotes(Vec<(ObjectClass, u32)>);

impl ClassVotes {
    /// One more vote for `class`.
    pub(crate) fn add(&mut self, class: &ObjectClass) {
        match self.0.iter_mut().find(|v| v.0 == *class) {
            Some(v) => v.1 += 1,
            None => self.0.push((class.clone(), 1)),
        }
    }

    /// The class with the most votes; ties go to the class seen first.
    pub(crate) fn majority(&self) -> Option<ObjectClass> {
        let mut best: Option<&(ObjectClass, u32)> = None;
        for v in &self.0 {
            // Strictly more votes wins, so ties go to the class seen first.
            if best.is_none_or(|b| v.1 > b.1) {
                best = Some(v);
            }
        }
        best.map(|b| b.0.clone())
    }
}

/// The shared life cycle between a tracker and the sinks (see the module documentation).
#[derive(Debug)]
pub struct LifecycleStage {
    config: LifecycleConfig,
    delay: usize,
    held: VecDeque<FramePoints>,
    tracks: BTreeMap<u64, TrackState>,
}

impl LifecycleStage {
    /// A stage with no tracks yet.
    ///
    /// # Errors
    /// An invalid configuration.
    pub fn new(config: LifecycleConfig) -> Result<Self> {
        config.validate()?;
        let delay = (config.confirm_hits - 1).max(config.max_coast_frames) as usize;
        Ok(Self {
            config,
            delay,
            held: VecDeque::new(),
            tracks: BTreeMap::new(),
        })
    }

    /// Writes the oldest held frame.
    fn release(&mut self) -> Option<FramePoints> {
        let mut fp = self.held.pop_front()?;
        let frame = fp.frame;
        let mut out = Vec::with_capacity(fp.points.len());
        for mut p in std::mem::take(&mut fp.points) {
            let Some(t) = self.tracks.get_mut(&p.id) else {
                continue;
            };
            if t.hits >= self.config.confirm_hits {
                t.confirmed = true;
            }
            if !t.confirmed {
                continue;
            }
            let (w, h) = match t.size {
                Some((w, h)) => {
                    let a = self.config.box_alpha;
                    (
                        a * p.bbox.width + (1.0 - a) * w,
                        a * p.bbox.height + (1.0 - a) * h,
                    )
                }
                None => (p.bbox.width, p.bbox.height),
            };
            t.size = Some((w, h));
            p.bbox = BBox::from_centre(p.bbox.centre(), w, h);
            if self.config.class_by_majority
                && let Some(c) = t.majority()
            {
                p.class = c;
            }
            t.last_written = Some(p.clone());
            out.push(p);
        }
        // Coasting: confirmed tracks missing here that come back within the limit.
        let present: Vec<u64> = out.iter().map(|p| p.id).collect();
        let max_gap = self.config.max_coast_frames;
        for (id, t) in &mut self.tracks {
            if max_gap == 0 || !t.confirmed || present.binary_search(id).is_ok() {
                continue;
            }
            let Some(before) = t.last_written.as_ref() else {
                continue;
            };
            if before.frame >= frame {
                continue;
            }
            let next = self
                .held
                .iter()
                .find_map(|f| f.points.iter().find(|q| q.id == *id));
            let Some(after) = next else { continue };
            if after.frame - before.frame - 1 > max_gap {
                continue;
            }
            let size = t.size.unwrap_or((before.bbox.width, before.bbox.height));
            let p = super::interpolated_point(before, size, after, frame, fp.time_s, *id);
            t.last_written = Some(p.clone());
            out.push(p);
        }
        out.sort_by_key(|p| p.id);
        // Forget tracks that can neither be written again nor coast.
        let horizon = u64::from(frame).saturating_sub(u64::from(max_gap) + 1);
        self.tracks
            .retain(|_, t| u64::from(t.last_seen) >= horizon || t.last_seen > frame);
        fp.points = out;
        Some(fp)
    }
}

impl PointStage for LifecycleStage {
    fn push(&mut self, frame: FramePoints) -> Result<Vec<FramePoints>> {
        for p in &frame.points {
            let t = self.tracks.entry(p.id).or_default();
            t.hits += 1;
            t.last_seen = frame.frame;
            t.votes.add(&p.class);
        }
        self.held.push_back(frame);
        let mut out = Vec::new();
        while self.held.len() > self.delay {
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

    fn point(frame: u32, id: u64, x: f64, w: f64, class: ObjectClass) -> TrackPoint {
        let bbox = BBox::from_centre(crate::geometry::Point::new(x, 50.0), w, 10.0);
        crate::track::point_at(frame, id, class, bbox)
    }

    use crate::track::frames_of as frames;

    fn run(config: LifecycleConfig, input: Vec<FramePoints>) -> Result<Vec<FramePoints>> {
        let mut s = LifecycleStage::new(config)?;
        let mut out = Vec::new();
        for f in input {
            out.extend(s.push(f)?);
        }
        out.extend(s.finish()?);
        Ok(out)
    }

    /// The rules below on short tracks: confirmed after 3 hits.
    fn three_hits() -> LifecycleConfig {
        LifecycleConfig {
            confirm_hits: 3,
            ..LifecycleConfig::default()
        }
    }

    #[test]
    fn every_frame_comes_out_once_in_order() -> Result<()> {
        let pts: Vec<_> = (1..=20)
            .map(|f| point(f, 1, f64::from(f), 10.0, ObjectClass::Car))
            .collect();
        let out = run(three_hits(), frames(&pts, 20))?;
        assert_eq!(
            out.iter().map(|f| f.frame).collect::<Vec<_>>(),
            (1..=20).collect::<Vec<_>>()
        );
        assert!(out.iter().all(|f| f.points.len() == 1));
        Ok(())
    }

    #[test]
    fn off_changes_nothing() -> Result<()> {
        let mut pts = vec![point(3, 7, 1.0, 4.0, ObjectClass::Truck)];
        pts.extend(
            (1..=9).map(|f| point(f, 1, f64::from(f), 10.0 + f64::from(f), ObjectClass::Car)),
        );
        let input = frames(&pts, 9);
        assert_eq!(run(LifecycleConfig::off(), input.clone())?, input);
        Ok(())
    }

    #[test]
    fn short_tracks_are_dropped_and_long_ones_kept_from_their_first_frame() -> Result<()> {
        let mut pts = vec![
            point(4, 9, 0.0, 10.0, ObjectClass::Car),
            point(5, 9, 1.0, 10.0, ObjectClass::Car),
        ];
        pts.extend((1..=8).map(|f| point(f, 1, f64::from(f), 10.0, ObjectClass::Car)));
        let out = run(three_hits(), frames(&pts, 8))?;
        let ids: Vec<u64> = out
            .iter()
            .flat_map(|f| f.points.iter().map(|p| p.id))
            .collect();
        assert_eq!(
            ids,
            vec![1; 8],
            "the 2-frame track 9 is tentative and never written"
        );
        Ok(())
    }

    #[test]
    fn a_gap_within_the_limit_is_filled_by_interpolation_and_a_longer_one_is_not() -> Result<()> {
        let mut pts: Vec<TrackPoint> = [1, 2, 3, 7, 8]
            .iter()
            .map(|&f| point(f, 1, 10.0 * f64::from(f), 10.0, ObjectClass::Car))
            .collect();
        pts.extend(
            [1, 2, 3, 20, 21, 22]
                .iter()
                .map(|&f| point(f, 2, 5.0, 10.0, ObjectClass::Car)),
        );
        let cfg = LifecycleConfig {
            max_coast_frames: 5,
            ..three_hits()
        };
        let out = run(cfg, frames(&pts, 22))?;
        let of = |id: u64| -> Vec<(u32, f64)> {
            out.iter()
                .flat_map(|f| f.points.iter().filter(|p| p.id == id))
                .map(|p| (p.frame, p.bbox.centre().x))
                .collect()
        };
        let one = of(1);
        assert_eq!(one.len(), 8, "{one:?}");
        for (f, x) in &one {
            assert!((x - 10.0 * f64::from(*f)).abs() < 1e-9, "frame {f}: {x}");
        }
        let two: Vec<u32> = of(2).iter().map(|p| p.0).collect();
        assert_eq!(
            two,
            vec![1, 2, 3, 20, 21, 22],
            "a 16-frame gap is not coasted"
        );
        Ok(())
    }

    #[test]
    fn a_track_takes_its_majority_class_and_a_smoothed_size() -> Result<()> {
        let classes = [
            ObjectClass::Car,
            ObjectClass::Truck,
            ObjectClass::Car,
            ObjectClass::Car,
        ];
        let pts: Vec<_> = classes
            .iter()
            .enumerate()
            .map(|(i, c)| {
                point(
                    i as u32 + 1,
                    1,
                    0.0,
                    if i == 1 { 30.0 } else { 10.0 },
                    c.clone(),
                )
            })
            .collect();
        let out = run(three_hits(), frames(&pts, 4))?;
        let got: Vec<_> = out.iter().map(|f| f.points[0].class.clone()).collect();
        assert_eq!(got, vec![ObjectClass::Car; 4]);
        let widths: Vec<f64> = out.iter().map(|f| f.points[0].bbox.width).collect();
        assert_eq!(widths, vec![10.0, 20.0, 15.0, 12.5]);
        Ok(())
    }

    #[test]
    fn bad_configs_name_the_field() {
        let e = LifecycleStage::new(LifecycleConfig {
            box_alpha: 0.0,
            ..three_hits()
        })
        .map(|_| ())
        .map_err(|e| e.to_string());
        assert!(e.is_err_and(|m| m.contains("box_alpha")));
    }
}
