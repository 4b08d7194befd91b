//! Detections: objects found in one frame, before any tracking.

use crate::class::ObjectClass;
use crate::geometry::{BBox, Point};

/// One object found in one frame (a row of the detections CSV, INTERFACES.md).
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    /// 1-based frame number.
    pub frame: u32,
    /// Identifier, unique within the frame.
    pub id: u64,
    /// Centre, px.
    pub pos_px: Point,
    /// Box width and height, px, when known.
    pub size_px: Option<(f64, f64)>,
    /// Mean colour of the object's pixels, 8-bit RGB (0–255), when known. Seed 000 uses it.
    pub colour_rgb: Option<[f64; 3]>,
    /// Class, when known.
    pub class: Option<ObjectClass>,
    /// Confidence in `[0, 1]`, when known.
    pub score: Option<f64>,
    /// Region area, px², when known (foreground extraction writes it).
    pub area_px: Option<f64>,
}

impl Detection {
    /// A detection with only a frame, an id and a centre.
    pub fn at(frame: u32, id: u64, pos_px: Point) -> Self {
        Self {
            frame,
            id,
            pos_px,
            size_px: None,
            colour_rgb: None,
            class: None,
            score: None,
            area_px: None,
        }
    }

    /// The box, when the size is known.
    pub fn bbox(&self) -> Option<BBox> {
        self.size_px
            .map(|(w, h)| BBox::from_centre(self.pos_px, w, h))
    }
}
