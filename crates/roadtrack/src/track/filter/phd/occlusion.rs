//! Occlusion-aware detection probability for the PHD with detections
//! (`[detections] occlusion_full_visibility`).
//!
//! The paper's `p_D` is one number. Where people walk behind one another (oblique crossing
//! views) a hidden person is not detected, and with a constant `p_D` every frame behind
//! someone takes its label's existence down as a miss would (0.1^k after k frames with
//! `p_D` 0.9): the label dies and the person reappears under a new one. A state-dependent
//! `p_D` (the occlusion models of labelled RFS trackers) instead lowers `p_D` for a label
//! whose box the labels in front of it cover, so a miss there costs it little:
//!
//! ```text
//! v_ℓ   = fraction of label ℓ's box not covered by the boxes of labels in front of it
//! p_D,ℓ = p_D · min(1, v_ℓ / v_full)
//! ```
//!
//! A label is in front of another when its box's bottom edge is lower in the image (its
//! foot point nearer the camera on a ground-plane view). Only labels of existence ≥ 0.5
//! occlude. Measured worse than the one `p_D` on the oblique scenes (docs/EXPERIMENTS.md
//! "Occlusion-aware p_D"), so off by default.

use crate::geometry::Point;

/// A label's predicted box for the occlusion model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelBox {
    /// The label.
    pub label: u32,
    /// Predicted centre, px.
    pub centre: Point,
    /// Box width and height, px (the last detection it was matched to).
    pub size: Point,
    /// The label's weight (its existence when ≤ 1).
    pub weight: f64,
}

impl LabelBox {
    fn bounds(&self) -> (f64, f64, f64, f64) {
        let (hw, hh) = (self.size.x / 2.0, self.size.y / 2.0);
        (
            self.centre.x - hw,
            self.centre.y - hh,
            self.centre.x + hw,
            self.centre.y + hh,
        )
    }
}

/// Samples per box side for the covered fraction.
// Choice: 16 × 16 sample points (the covered fraction to 1/16 per axis): the union of
// several occluders needs no polygon clipping, and only overlapping pairs are sampled.
const SAMPLES: usize = 16;

/// Smallest weight of a label that occludes others.
// Choice: a label below 0.5 is more likely not there (a birth or a dying label); letting it
// hide the label behind would protect that label from its own misses on a guess.
pub const MIN_OCCLUDER_WEIGHT: f64 = 0.5;

/// The visible fraction of each of `boxes` (in order): 1 minus the part of its box covered
/// by the union of the boxes of labels in front of it (lower bottom edge) with weight ≥
/// [`MIN_OCCLUDER_WEIGHT`], sampled on a 16 × 16 grid of cell centres. A box without area
/// is fully visible.
pub fn visible_fractions(boxes: &[LabelBox]) -> Vec<f64> {
    boxes
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let (x0, y0, x1, y1) = b.bounds();
            if !(x1 > x0 && y1 > y0) {
                return 1.0;
            }
            let front: Vec<(f64, f64, f64, f64)> = boxes
                .iter()
                .enumerate()
                .filter(|&(k, o)| {
                    k != i
                        && o.weight >= MIN_OCCLUDER_WEIGHT
                        && o.bounds().3 > y1
                        && o.size.x > 0.0
                        && o.size.y > 0.0
                })
                .map(|(_, o)| o.bounds())
                .filter(|&(a0, b0, a1, b1)| a0 < x1 && a1 > x0 && b0 < y1 && b1 > y0)
                .collect();
            if front.is_empty() {
                return 1.0;
            }
            let (dx, dy) = ((x1 - x0) / SAMPLES as f64, (y1 - y0) / SAMPLES as f64);
            let mut hidden = 0usize;
            for r in 0..SAMPLES {
                let y = y0 + (r as f64 + 0.5) * dy;
                for c in 0..SAMPLES {
                    let x = x0 + (c as f64 + 0.5) * dx;
                    if front
                        .iter()
                        .any(|&(a0, b0, a1, b1)| x >= a0 && x < a1 && y >= b0 && y < b1)
                    {
                        hidden += 1;
                    }
                }
            }
            1.0 - hidden as f64 / (SAMPLES * SAMPLES) as f64
        })
        .collect()
}

/// `p_D,ℓ = p_D · min(1, v / v_full)`; `v_full ≤ 0` turns the model off (`p_D`).
pub fn occluded_pd(pd: f64, visible: f64, full_visibility: f64) -> f64 {
    if full_visibility <= 0.0 {
        pd
    } else {
        pd * (visible / full_visibility).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lb(label: u32, x: f64, y: f64, w: f64, h: f64, weight: f64) -> LabelBox {
        LabelBox {
            label,
            centre: Point::new(x, y),
            size: Point::new(w, h),
            weight,
        }
    }

    /// Exact covered fraction of one axis-aligned box by one other (reference).
    fn overlap_fraction(b: &LabelBox, o: &LabelBox) -> f64 {
        let (x0, y0, x1, y1) = b.bounds();
        let (a0, b0, a1, b1) = o.bounds();
        let w = (x1.min(a1) - x0.max(a0)).max(0.0);
        let h = (y1.min(b1) - y0.max(b0)).max(0.0);
        w * h / ((x1 - x0) * (y1 - y0))
    }

    #[test]
    fn the_box_behind_loses_the_covered_part_and_the_box_in_front_none() {
        // b is behind a (a's bottom edge is lower), a covers b's right half exactly.
        let a = lb(1, 20.0, 12.0, 20.0, 40.0, 1.0);
        let b = lb(2, 10.0, 10.0, 20.0, 40.0, 1.0);
        let v = visible_fractions(&[a, b]);
        assert_eq!(v[0], 1.0);
        // Sampled on 16 × 16 cell centres: within one cell row and column of the exact.
        let exact = 1.0 - overlap_fraction(&b, &a);
        assert!((exact - 0.525).abs() < 1e-12);
        assert!((v[1] - exact).abs() <= 2.0 / 16.0, "{v:?}");
    }

    #[test]
    fn light_or_separate_labels_hide_nothing() {
        let a = lb(1, 20.0, 12.0, 20.0, 40.0, 0.4);
        let b = lb(2, 10.0, 10.0, 20.0, 40.0, 1.0);
        assert_eq!(visible_fractions(&[a, b]), vec![1.0, 1.0]);
        let far = lb(3, 200.0, 12.0, 20.0, 40.0, 1.0);
        assert_eq!(visible_fractions(&[far, b]), vec![1.0, 1.0]);
    }

    #[test]
    fn the_union_of_occluders_is_counted_once() {
        // Two occluders in front of the left half, o2's part containing o1's: the union is
        // o2's part (0.4375), not the sum of the two (0.81).
        let b = lb(1, 0.0, 0.0, 16.0, 16.0, 1.0);
        let o1 = lb(2, -8.0, 4.0, 16.0, 16.0, 1.0);
        let o2 = lb(3, -8.0, 2.0, 16.0, 16.0, 1.0);
        let v = visible_fractions(&[b, o1, o2])[0];
        let sum = overlap_fraction(&b, &o1) + overlap_fraction(&b, &o2);
        assert!(sum > 0.6, "{sum}");
        assert!((v - (1.0 - overlap_fraction(&b, &o2))).abs() < 1e-12, "{v}");
    }

    #[test]
    fn detection_probability_falls_linearly_below_full_visibility() {
        assert_eq!(occluded_pd(0.9, 0.2, 0.0), 0.9);
        assert_eq!(occluded_pd(0.9, 0.8, 0.5), 0.9);
        assert!((occluded_pd(0.9, 0.25, 0.5) - 0.45).abs() < 1e-12);
        assert_eq!(occluded_pd(0.9, 0.0, 0.5), 0.0);
    }
}
