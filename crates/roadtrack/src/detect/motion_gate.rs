//! Motion gate ([`MotionGated`]): another detector's boxes, kept only where the background
//! model sees something that moves or has moved.
//!
//! A detector trained on the simulator fires on static structure in real footage (posts,
//! windows, a tripod: docs/DETECTION.md, `vtest.avi`). On a fixed camera those are part of
//! the background, so a box whose pixels are almost all background is dropped. Vehicles
//! that stop stay foreground while the background detector holds them (`hold_still_s`),
//! so a queue that formed in view keeps its boxes; objects that never move (parked from the
//! first frame) are dropped with the clutter: the gate is for fixed cameras and moving
//! traffic, and off unless asked for.

use super::FrameDetections;
use super::nested::{NestedConfig, drop_nested_detections};
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::geometry::BBox;
use image::GrayImage;

/// Parameters of [`MotionGated`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MotionGateConfig {
    /// Smallest fraction of a box's pixels that must be foreground (the background
    /// detector's cleaned mask) for the box to be kept. Default 0.2.
    pub min_foreground_fraction: f64,
    /// Nested boxes dropped after gating ([`super::nested`]). Default off; `detect
    /// --detector cnn --motion-gate F` moves the learned detector's rule here.
    pub nested: NestedConfig,
}

impl Default for MotionGateConfig {
    fn default() -> Self {
        Self {
            min_foreground_fraction: 0.2,
            nested: NestedConfig::OFF,
        }
    }
}

impl MotionGateConfig {
    /// Checks the range.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        if !(self.min_foreground_fraction > 0.0 && self.min_foreground_fraction <= 1.0) {
            return Err(Error::config(
                "MotionGateConfig",
                "min_foreground_fraction",
                format!("must be in (0, 1], found {}", self.min_foreground_fraction),
            ));
        }
        self.nested.validate("MotionGateConfig.nested")
    }
}

/// Fraction of the pixels of `bbox` (clipped to the image) that are set in `mask`; 0 when
/// nothing of it is inside.
pub fn foreground_fraction(mask: &GrayImage, bbox: &BBox) -> f64 {
    let Some((x0, x1, y0, y1)) = super::file::pixel_span(bbox, mask.width(), mask.height()) else {
        return 0.0;
    };
    let width = mask.width() as usize;
    let raw = mask.as_raw();
    let set: usize = (y0..y1)
        .map(|y| {
            let row = &raw[y as usize * width..(y as usize + 1) * width];
            row[x0 as usize..x1 as usize]
                .iter()
                .filter(|&&v| v != 0)
                .count()
        })
        .sum();
    set as f64 / f64::from((x1 - x0) * (y1 - y0))
}

super::background_wrapper!(
    /// `inner`'s detections where the background detector sees motion (module documentation).
    /// The result carries the background detector's foreground mask; detections are numbered
    /// `1..` again after the gate.
    MotionGated,
    MotionGateConfig
);

impl MotionGated {
    /// `found` gated by the background detector's mask of `frame`; learns the frame.
    fn after(&mut self, frame: &Frame, found: FrameDetections) -> Result<FrameDetections> {
        let mask = self.background.process(frame)?.mask;
        Ok(self.gate(found, mask))
    }

    fn gate(&self, found: FrameDetections, mask: GrayImage) -> FrameDetections {
        let detections: Vec<_> = found
            .detections
            .into_iter()
            .filter(|d| {
                // Choice: a detection without a box is judged on a 1-pixel box at its centre.
                let (w, h) = d.size_px.unwrap_or((1.0, 1.0));
                foreground_fraction(&mask, &BBox::from_centre(d.pos_px, w, h))
                    >= self.config.min_foreground_fraction
            })
            .collect();
        let mut detections = drop_nested_detections(detections, &self.config.nested);
        for (i, d) in detections.iter_mut().enumerate() {
            d.id = i as u64 + 1;
        }
        FrameDetections {
            detections,
            foreground: Some(mask),
        }
    }
}

super::detector_after_inner!(MotionGated, after);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::Detector;
    use crate::detect::background::{BackgroundDetector, BackgroundDetectorConfig};
    use crate::detection::Detection;
    use crate::geometry::Point;
    use image::Luma;

    #[test]
    fn foreground_fraction_counts_the_box_inside_the_image() {
        let mut mask = GrayImage::new(20, 10);
        for y in 0..10 {
            for x in 0..5 {
                mask.put_pixel(x, y, Luma([255]));
            }
        }
        // Box x 0..10, y 0..10: half of it set.
        let at = |x, y, w, h| BBox::from_centre(Point::new(x, y), w, h);
        assert_eq!(foreground_fraction(&mask, &at(5.0, 5.0, 10.0, 10.0)), 0.5);
        // Half outside on the left: only x 0..5 inside, all set.
        assert_eq!(foreground_fraction(&mask, &at(0.0, 5.0, 10.0, 10.0)), 1.0);
        assert_eq!(foreground_fraction(&mask, &at(40.0, 5.0, 4.0, 4.0)), 0.0);
    }

    /// A detector that reports two boxes per frame: one on a moving rectangle and one on
    /// static background.
    #[test]
    fn boxes_on_static_background_are_dropped_and_boxes_on_movers_kept() -> Result<()> {
        let frames = roadtrack_sim::testkit::moving_boxes(200, 120, 100, 1);
        let bg = BackgroundDetector::bootstrap(
            BackgroundDetectorConfig::default(),
            frames.iter().cloned().map(Ok),
            Some(100),
        )?;
        // The generated sequence's first object: 24 × 14 px at y 20, moving right 2 px per
        // frame from x = 2·i − 24 (roadtrack_sim::testkit::moving_boxes).
        let inner = move |f: &Frame| -> Result<FrameDetections> {
            let mut still = Detection::at(f.index, 1, Point::new(150.0, 100.0));
            still.size_px = Some((20.0, 14.0));
            let x0 = 2.0 * f64::from(f.index) - 24.0;
            let mut mover = Detection::at(f.index, 2, Point::new(x0 + 12.0, 27.0));
            mover.size_px = Some((24.0, 14.0));
            Ok(FrameDetections {
                detections: vec![still, mover],
                foreground: None,
            })
        };
        let mut gated = MotionGated::new(Box::new(inner), bg, MotionGateConfig::default())?;
        for f in &frames {
            let out = gated.detect(f)?;
            assert!(out.foreground.is_some());
            // Once the mover is wholly in view, it alone is kept, renumbered 1.
            if f.index >= 12 {
                assert_eq!(out.detections.len(), 1, "frame {}", f.index);
                assert_eq!(out.detections[0].id, 1);
                assert_eq!(out.detections[0].pos_px.y, 27.0);
            } else {
                assert!(out.detections.iter().all(|d| d.pos_px.x != 150.0));
            }
        }
        Ok(())
    }

    #[test]
    fn a_fraction_out_of_range_names_the_field() {
        for f in [0.0, 1.5, f64::NAN] {
            let err = MotionGateConfig {
                min_foreground_fraction: f,
                ..Default::default()
            }
            .validate()
            .expect_err("out of range");
            assert!(err.to_string().contains("min_foreground_fraction"), "{err}");
        }
        let err = MotionGateConfig {
            nested: NestedConfig {
                vehicle_fraction: 2.0,
                pedestrian_fraction: 0.7,
            },
            ..Default::default()
        }
        .validate()
        .expect_err("out of range");
        assert!(err.to_string().contains("vehicle_fraction"), "{err}");
    }
}
