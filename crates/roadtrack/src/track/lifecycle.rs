//! The parts of a track's life that do not depend on the method, in Stone Soup's words
//! (`tracker/simple.py`): the *initiator* decides which detections start tracks
//! ([`BirthGate`]), the *deleter* ends tracks that nothing supports any more
//! ([`SupportDeleter`]), and boxes get their size from the detections
//! ([`BoxFromDetections`]). The *predictor* and *updater* are each method's own
//! (relaxation labels, the MRF object map, one particle filter per object, PHD labels).

use crate::class::ObjectClass;
use crate::detection::Detection;
use crate::geometry::{BBox, Point};
use crate::track_point::TrackPoint;
use std::collections::BTreeMap;

/// Initiator: a detection starts a track only when no track is predicted near it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BirthGate {
    /// A detection within this distance of a predicted track position is explained by that
    /// track, px.
    pub gate_px: f64,
    /// Widen the gate to half the detection box's longer side when that is larger, so a
    /// large vehicle's detection is not taken for a second object beside its own track.
    pub widen_to_box: bool,
}

impl BirthGate {
    /// Whether `detection` is explained by a track predicted at one of `predicted`.
    pub fn explains(&self, predicted: &[Point], detection: &Detection) -> bool {
        let gate = if self.widen_to_box {
            let half = detection.size_px.map_or(0.0, |(w, h)| w.max(h) / 2.0);
            half.max(self.gate_px)
        } else {
            self.gate_px
        };
        predicted
            .iter()
            .any(|q| q.distance(detection.pos_px) <= gate)
    }

    /// The detections no predicted track explains, in input order.
    pub fn unexplained<'d>(
        &self,
        predicted: &[Point],
        detections: &'d [Detection],
    ) -> Vec<&'d Detection> {
        detections
            .iter()
            .filter(|d| !self.explains(predicted, d))
            .collect()
    }
}

/// Deleter: a track that no detection has supported for more than
/// `max_frames_without_detection` frames ends.
#[derive(Debug, Clone, PartialEq)]
pub struct SupportDeleter {
    /// A track is supported in a frame when a detection lies within this distance, px (each
    /// detection supports at most one track, closest pairs first).
    pub gate_px: f64,
    /// Frames without support after which a track ends; 0 disables the rule.
    pub max_frames_without_detection: u32,
    /// Per live track id: the last frame with support.
    last_support: BTreeMap<u64, u32>,
}

impl SupportDeleter {
    /// A deleter with no track yet.
    pub fn new(gate_px: f64, max_frames_without_detection: u32) -> Self {
        Self {
            gate_px,
            max_frames_without_detection,
            last_support: BTreeMap::new(),
        }
    }

    /// Updates support for the tracks alive in `frame` (`tracked`: id and position) from
    /// `detections`, forgets tracks no longer alive, and returns the ids that end now.
    pub fn update(
        &mut self,
        frame: u32,
        tracked: &[(u64, Point)],
        detections: &[Detection],
    ) -> Vec<u64> {
        let supported = one_to_one(tracked, detections, self.gate_px);
        let mut ended = Vec::new();
        for &(id, _) in tracked {
            let last = self.last_support.entry(id).or_insert(frame);
            if supported.contains(&id) {
                *last = frame;
            }
            let max = self.max_frames_without_detection;
            if max > 0 && frame.saturating_sub(*last) > max {
                ended.push(id);
            }
        }
        for id in &ended {
            self.last_support.remove(id);
        }
        self.last_support
            .retain(|id, _| tracked.iter().any(|t| t.0 == *id));
        ended
    }
}

/// Ids of the tracks that a detection supports: track–detection pairs within `gate`,
/// taken greedily from the closest, each track and detection at most once.
pub fn one_to_one(tracked: &[(u64, Point)], detections: &[Detection], gate: f64) -> Vec<u64> {
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (i, (_, p)) in tracked.iter().enumerate() {
        for (j, d) in detections.iter().enumerate() {
            let dist = p.distance(d.pos_px);
            if dist <= gate {
                pairs.push((dist, i, j));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let (mut t_used, mut d_used) = (vec![false; tracked.len()], vec![false; detections.len()]);
    let mut out = Vec::new();
    for (_, i, j) in pairs {
        if !t_used[i] && !d_used[j] {
            t_used[i] = true;
            d_used[j] = true;
            out.push(tracked[i].0);
        }
    }
    out
}

/// Box sizes for trackers that estimate positions only: each point takes the size of the
/// nearest detection within the gate, else its track's last size, else a default; and a
/// point of unknown class likewise the detection's class, else its track's last detected
/// class.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxFromDetections {
    /// Largest centre distance to a detection that lends its size, px.
    pub gate_px: f64,
    /// Size of a track that never had a detection near it, px.
    pub default_size_px: (f64, f64),
    /// Per live track id: its last size.
    sizes: BTreeMap<u64, (f64, f64)>,
    /// Per live track id: the class of its last detection that had one.
    classes: BTreeMap<u64, ObjectClass>,
}

impl BoxFromDetections {
    /// A sizer with no track yet.
    pub fn new(gate_px: f64, default_size_px: (f64, f64)) -> Self {
        Self {
            gate_px,
            default_size_px,
            sizes: BTreeMap::new(),
            classes: BTreeMap::new(),
        }
    }

    /// Resizes every point's box about its centre; forgets tracks not in `live`.
    pub fn apply(&mut self, points: &mut [TrackPoint], detections: &[Detection], live: &[u64]) {
        for p in points.iter_mut() {
            let c = p.bbox.centre();
            let near = detections
                .iter()
                .map(|d| (d, d.pos_px.distance(c)))
                .filter(|(_, dist)| *dist <= self.gate_px)
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(d, _)| d);
            if let Some(size) = near.and_then(|d| d.size_px) {
                self.sizes.insert(p.id, size);
            }
            // Choice: a point of unknown class (the PHD's labels carry none) takes the class
            // of the detection that lends the size, so the life cycle's majority vote sees
            // the detector's classes. A point that has one (a PF object's, its last assigned
            // detection's, which its class gate used) keeps it: the nearest detection may be
            // a neighbour's.
            if p.class == ObjectClass::Unknown {
                if let Some(class) = near.and_then(|d| d.class.clone()) {
                    self.classes.insert(p.id, class);
                }
                if let Some(class) = self.classes.get(&p.id) {
                    p.class = class.clone();
                }
            }
            let (w, h) = self
                .sizes
                .get(&p.id)
                .copied()
                .unwrap_or(self.default_size_px);
            p.bbox = BBox::from_centre(c, w, h);
        }
        self.sizes.retain(|id, _| live.contains(id));
        self.classes.retain(|id, _| live.contains(id));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn det(x: f64, y: f64, size: Option<(f64, f64)>) -> Detection {
        Detection {
            size_px: size,
            ..Detection::at(1, 1, Point::new(x, y))
        }
    }

    #[test]
    fn the_birth_gate_widens_to_large_boxes_only_when_asked() {
        let predicted = [Point::new(0.0, 0.0)];
        let bus = det(40.0, 0.0, Some((100.0, 30.0)));
        let fixed = BirthGate {
            gate_px: 30.0,
            widen_to_box: false,
        };
        assert!(!fixed.explains(&predicted, &bus));
        let wide = BirthGate {
            widen_to_box: true,
            ..fixed
        };
        assert!(wide.explains(&predicted, &bus));
        assert_eq!(
            fixed
                .unexplained(&predicted, std::slice::from_ref(&bus))
                .len(),
            1
        );
    }

    #[test]
    fn a_detection_supports_one_track_and_unsupported_tracks_end_after_the_limit() {
        let mut del = SupportDeleter::new(10.0, 2);
        // Two tracks share one detection: only the closer is supported.
        let tracked = [(1, Point::new(0.0, 0.0)), (2, Point::new(3.0, 0.0))];
        let dets = [det(1.0, 0.0, None)];
        assert_eq!(one_to_one(&tracked, &dets, 10.0), vec![1]);
        for frame in 1..=3 {
            assert!(
                del.update(frame, &tracked, &dets).is_empty(),
                "frame {frame}"
            );
        }
        // Track 2 was first seen at frame 1 and never supported: 4 − 1 > 2.
        assert_eq!(del.update(4, &tracked, &dets), vec![2]);
        // Forgotten once ended: it would start again from the frame it reappears.
        assert!(del.update(5, &tracked, &dets).is_empty());
    }

    #[test]
    fn boxes_take_the_nearest_detection_size_then_keep_it() {
        let mut sizer = BoxFromDetections::new(20.0, (8.0, 8.0));
        let point = |x: f64| TrackPoint {
            frame: 1,
            time_s: 0.0,
            id: 7,
            class: ObjectClass::Unknown,
            bbox: BBox::from_centre(Point::new(x, 0.0), 1.0, 1.0),
            score: 1.0,
            ground: None,
        };
        let mut pts = [point(0.0)];
        sizer.apply(&mut pts, &[], &[7]);
        assert_eq!((pts[0].bbox.width, pts[0].bbox.height), (8.0, 8.0));
        let dets = [
            det(5.0, 0.0, Some((30.0, 12.0))),
            det(15.0, 0.0, Some((2.0, 2.0))),
        ];
        sizer.apply(&mut pts, &dets, &[7]);
        assert_eq!((pts[0].bbox.width, pts[0].bbox.height), (30.0, 12.0));
        assert_eq!(pts[0].bbox.centre(), Point::new(0.0, 0.0));
        // No detection near: the last size stays.
        let mut far = [point(500.0)];
        sizer.apply(&mut far, &dets, &[7]);
        assert_eq!((far[0].bbox.width, far[0].bbox.height), (30.0, 12.0));
    }

    #[test]
    fn points_take_the_nearest_detection_class_then_keep_it() {
        let mut sizer = BoxFromDetections::new(20.0, (8.0, 8.0));
        let point = |x: f64, class: ObjectClass| {
            let b = BBox::from_centre(Point::new(x, 0.0), 1.0, 1.0);
            crate::track::point_at(1, 7, class, b)
        };
        let unknown = |x: f64| point(x, ObjectClass::Unknown);
        // No detection yet: the point stays unknown.
        let mut pts = [unknown(0.0)];
        sizer.apply(&mut pts, &[], &[7]);
        assert_eq!(pts[0].class, ObjectClass::Unknown);
        // The nearest detection within the gate gives its class; one without a class does not.
        let car = Detection {
            class: Some(ObjectClass::Car),
            ..det(5.0, 0.0, None)
        };
        let mut pts = [unknown(0.0)];
        sizer.apply(&mut pts, &[car.clone(), det(15.0, 0.0, None)], &[7]);
        assert_eq!(pts[0].class, ObjectClass::Car);
        // Away from every detection the track keeps its last detected class.
        let mut far = [unknown(500.0)];
        sizer.apply(&mut far, &[det(0.0, 0.0, None)], &[7]);
        assert_eq!(far[0].class, ObjectClass::Car);
        // A point with a class of its own (a PF object's) keeps it beside a car.
        let mut walker = [point(0.0, ObjectClass::Pedestrian)];
        sizer.apply(&mut walker, std::slice::from_ref(&car), &[7]);
        assert_eq!(walker[0].class, ObjectClass::Pedestrian);
        // A track that ended is forgotten.
        sizer.apply(&mut [], &[], &[]);
        let mut again = [unknown(500.0)];
        sizer.apply(&mut again, &[], &[7]);
        assert_eq!(again[0].class, ObjectClass::Unknown);
    }
}
