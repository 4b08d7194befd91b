//! Nested boxes: a box lying mostly inside a larger box of its group (vehicles,
//! pedestrians) is a part of that object or the object seen smaller, and is dropped.
//!
//! Class-wise NMS at IoU 0.45 keeps a small box inside a large one whenever their area ratio
//! is under 0.45 (a lorry's cab boxed as a car, a person's head or legs boxed apart); the
//! learned detector applies this rule after its NMS (`roadtrack_cnn::centernet::drop_nested`),
//! the motion gate after gating (docs/DETECTION.md "Nested boxes").

use crate::class::ObjectClass;
use crate::detection::Detection;
use crate::error::{Error, Result};
use crate::geometry::BBox;

/// The fractions of [`nested`]: 0 turns a group's rule off.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NestedConfig {
    /// A vehicle box (any vehicle class) lying at least this fraction inside a larger
    /// vehicle box is dropped. 0 = off.
    pub vehicle_fraction: f64,
    /// The same for a pedestrian box inside a larger pedestrian box. 0 = off.
    pub pedestrian_fraction: f64,
}

impl NestedConfig {
    /// The rule off for both groups.
    pub const OFF: Self = Self {
        vehicle_fraction: 0.0,
        pedestrian_fraction: 0.0,
    };

    /// Whether the rule drops anything.
    pub fn is_on(&self) -> bool {
        self.vehicle_fraction > 0.0 || self.pedestrian_fraction > 0.0
    }

    /// Checks the ranges; `owner` names the configuration in the error.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self, owner: &'static str) -> Result<()> {
        for (field, v) in [
            ("vehicle_fraction", self.vehicle_fraction),
            ("pedestrian_fraction", self.pedestrian_fraction),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::config(
                    owner,
                    field,
                    format!("must be in [0, 1] (0 = off), got {v}"),
                ));
            }
        }
        Ok(())
    }
}

impl Default for NestedConfig {
    /// Choice: 0.6 and 0.7, measured with the learned detector on the seed-0 scenes:
    /// +0.03–0.05 vehicle precision at ≤ 0.02 recall, crossing pedestrians 0.82 / 0.81 →
    /// 0.81 / 0.86 (docs/DETECTION.md "Nested boxes").
    fn default() -> Self {
        Self {
            vehicle_fraction: 0.6,
            pedestrian_fraction: 0.7,
        }
    }
}

/// For each `(box, is_pedestrian)`: whether it lies at least the group's fraction inside a
/// larger box of its group.
// Choice: the larger box wins whatever the scores (keeping the better-scored box of a pair
// lost more recall for less precision on the same boxes: road aerial vehicles 0.827 →
// 0.815); a box is tested against every other box, dropped ones included, so the result
// does not depend on the order. Boxes of equal area never drop each other.
pub fn nested(boxes: &[(BBox, bool)], cfg: &NestedConfig) -> Vec<bool> {
    nested_in(boxes, &vec![true; boxes.len()], cfg)
}

/// [`nested`] where only the boxes marked in `containers` may hold others (every box is
/// still tested for lying inside one).
pub fn nested_in(boxes: &[(BBox, bool)], containers: &[bool], cfg: &NestedConfig) -> Vec<bool> {
    boxes
        .iter()
        .map(|(b, ped)| {
            let f = if *ped {
                cfg.pedestrian_fraction
            } else {
                cfg.vehicle_fraction
            };
            let area = b.area();
            f > 0.0
                && area > 0.0
                && boxes.iter().zip(containers).any(|((k, kped), &holds)| {
                    holds && kped == ped && k.area() > area && b.intersection_area(k) / area >= f
                })
        })
        .collect()
}

/// `detections` without the nested ones ([`nested`]), renumbered `1..`; a detection
/// without a box or a class is never dropped and drops nothing.
pub fn drop_nested_detections(detections: Vec<Detection>, cfg: &NestedConfig) -> Vec<Detection> {
    if !cfg.is_on() {
        return detections;
    }
    let judged: Vec<Option<(BBox, bool)>> = detections
        .iter()
        .map(|d| {
            let (w, h) = d.size_px?;
            let class = d.class.as_ref()?;
            (class != &ObjectClass::Unknown).then(|| {
                (
                    BBox::from_centre(d.pos_px, w, h),
                    class == &ObjectClass::Pedestrian,
                )
            })
        })
        .collect();
    let boxes: Vec<(BBox, bool)> = judged.iter().flatten().copied().collect();
    let mut drop = nested(&boxes, cfg).into_iter();
    let mut out: Vec<Detection> = detections
        .into_iter()
        .zip(&judged)
        .filter_map(|(d, j)| match j {
            Some(_) => (!drop.next().unwrap_or(false)).then_some(d),
            None => Some(d),
        })
        .collect();
    for (i, d) in out.iter_mut().enumerate() {
        d.id = i as u64 + 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Point;

    fn det(id: u64, x: f64, y: f64, w: f64, h: f64, class: Option<ObjectClass>) -> Detection {
        let mut d = Detection::at(7, id, Point::new(x, y));
        d.size_px = Some((w, h));
        d.class = class;
        d
    }

    #[test]
    fn nested_detections_are_dropped_and_the_rest_renumbered() {
        let cfg = NestedConfig::default();
        let dets = vec![
            det(1, 300.0, 200.0, 10.0, 30.0, Some(ObjectClass::Pedestrian)), // a person
            det(2, 300.0, 190.0, 6.0, 8.0, Some(ObjectClass::Pedestrian)),   // their head
            det(3, 300.0, 195.0, 6.0, 8.0, Some(ObjectClass::Car)),          // another group: kept
            det(4, 300.0, 192.0, 4.0, 4.0, None),                            // no class: kept
            det(5, 100.0, 100.0, 40.0, 16.0, Some(ObjectClass::Truck)),      // a lorry
            det(6, 92.0, 100.0, 16.0, 12.0, Some(ObjectClass::Car)),         // its cab
            det(7, 100.0, 100.0, 30.0, 30.0, Some(ObjectClass::Unknown)),    // unknown: kept
        ];
        let mut no_box = Detection::at(7, 8, Point::new(300.0, 200.0));
        no_box.class = Some(ObjectClass::Pedestrian);
        let mut all = dets.clone();
        all.push(no_box);
        let got = drop_nested_detections(all.clone(), &cfg);
        let centres: Vec<(f64, f64)> = got.iter().map(|d| (d.pos_px.x, d.pos_px.y)).collect();
        assert_eq!(
            centres,
            vec![
                (300.0, 200.0),
                (300.0, 195.0),
                (300.0, 192.0),
                (100.0, 100.0),
                (100.0, 100.0),
                (300.0, 200.0)
            ]
        );
        let ids: Vec<u64> = got.iter().map(|d| d.id).collect();
        assert_eq!(ids, (1..=6).collect::<Vec<u64>>());
        // Off: untouched, ids included.
        assert_eq!(drop_nested_detections(all.clone(), &NestedConfig::OFF), all);
        // The same boxes through the slice form.
        let boxes: Vec<(BBox, bool)> = [(300.0, 200.0, 10.0, 30.0), (300.0, 190.0, 6.0, 8.0)]
            .iter()
            .map(|&(x, y, w, h)| (BBox::from_centre(Point::new(x, y), w, h), true))
            .collect();
        assert_eq!(nested(&boxes, &cfg), vec![false, true]);
        let loose = NestedConfig {
            pedestrian_fraction: 0.0,
            ..cfg
        };
        assert_eq!(nested(&boxes, &loose), vec![false, false]);
        let e = NestedConfig {
            pedestrian_fraction: f64::NAN,
            ..cfg
        }
        .validate("X")
        .unwrap_err()
        .to_string();
        assert!(e.contains("pedestrian_fraction"), "{e}");
    }
}
