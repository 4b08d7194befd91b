//! Image-plane geometry: points and axis-aligned boxes in pixels.
//!
//! Pixel coordinates have their origin at the image's top-left corner, x to the right and
//! y down, in float pixels (INTERFACES.md "Conventions").

use serde::{Deserialize, Serialize};

/// A point in the image, in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Point {
    /// Horizontal coordinate, px (right is positive).
    pub x: f64,
    /// Vertical coordinate, px (down is positive).
    pub y: f64,
}

impl Point {
    /// A point at `(x, y)` px.
    pub const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }

    /// Euclidean distance to `other`, px.
    pub fn distance(self, other: Point) -> f64 {
        (self.x - other.x).hypot(self.y - other.y)
    }
}

/// An axis-aligned box, in pixels, as MOTChallenge writes it: left, top, width, height.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct BBox {
    /// Left edge, px.
    pub left: f64,
    /// Top edge, px.
    pub top: f64,
    /// Width, px (non-negative).
    pub width: f64,
    /// Height, px (non-negative).
    pub height: f64,
}

impl BBox {
    /// A box from its left, top, width and height, px.
    pub const fn new(left: f64, top: f64, width: f64, height: f64) -> Self {
        Self {
            left,
            top,
            width,
            height,
        }
    }

    /// The box of size `width × height` centred on `centre`.
    pub fn from_centre(centre: Point, width: f64, height: f64) -> Self {
        Self::new(
            centre.x - width / 2.0,
            centre.y - height / 2.0,
            width,
            height,
        )
    }

    /// The box's centre.
    pub fn centre(&self) -> Point {
        Point::new(self.left + self.width / 2.0, self.top + self.height / 2.0)
    }

    /// Right edge, px.
    pub fn right(&self) -> f64 {
        self.left + self.width
    }

    /// Bottom edge, px.
    pub fn bottom(&self) -> f64 {
        self.top + self.height
    }

    /// Area, px².
    pub fn area(&self) -> f64 {
        self.width.max(0.0) * self.height.max(0.0)
    }

    /// Area of the intersection with `other`, px².
    pub fn intersection_area(&self, other: &BBox) -> f64 {
        let w = self.right().min(other.right()) - self.left.max(other.left);
        let h = self.bottom().min(other.bottom()) - self.top.max(other.top);
        w.max(0.0) * h.max(0.0)
    }

    /// Intersection over union with `other`, in `[0, 1]`; 0 when both are empty.
    pub fn iou(&self, other: &BBox) -> f64 {
        let inter = self.intersection_area(other);
        let union = self.area() + other.area() - inter;
        if union <= 0.0 { 0.0 } else { inter / union }
    }
}

/// A rectangular region of a filter's state space: `[x0, x1] × [y0, y1]` (image px or any
/// units), e.g. the surveillance region of the PHD filter and of the point simulator.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SurveillanceRegion {
    /// Left edge.
    pub x0: f64,
    /// Top edge.
    pub y0: f64,
    /// Right edge.
    pub x1: f64,
    /// Bottom edge.
    pub y1: f64,
}

impl SurveillanceRegion {
    /// The region `[x0, x1] × [y0, y1]`.
    pub const fn new(x0: f64, y0: f64, x1: f64, y1: f64) -> Self {
        Self { x0, y0, x1, y1 }
    }

    /// The whole image of `width × height` px.
    pub fn image(width: u32, height: u32) -> Self {
        Self::new(0.0, 0.0, f64::from(width), f64::from(height))
    }

    /// Width.
    pub fn width(&self) -> f64 {
        self.x1 - self.x0
    }

    /// Height.
    pub fn height(&self) -> f64 {
        self.y1 - self.y0
    }

    /// Area.
    pub fn area(&self) -> f64 {
        self.width() * self.height()
    }

    /// Whether `p` is inside (edges included).
    pub fn contains(&self, p: Point) -> bool {
        p.x >= self.x0 && p.x <= self.x1 && p.y >= self.y0 && p.y <= self.y1
    }

    /// Whether the region has positive, finite width and height.
    pub fn is_valid(&self) -> bool {
        [self.x0, self.y0, self.x1, self.y1]
            .iter()
            .all(|v| v.is_finite())
            && self.x1 > self.x0
            && self.y1 > self.y0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iou_of_identical_boxes_is_one_and_of_disjoint_boxes_zero() {
        let a = BBox::new(0.0, 0.0, 10.0, 10.0);
        assert_eq!(a.iou(&a), 1.0);
        assert_eq!(a.iou(&BBox::new(20.0, 0.0, 5.0, 5.0)), 0.0);
    }

    #[test]
    fn iou_of_half_overlapping_boxes() {
        // Overlap 5×10 = 50, union 100 + 100 − 50 = 150.
        let a = BBox::new(0.0, 0.0, 10.0, 10.0);
        let b = BBox::new(5.0, 0.0, 10.0, 10.0);
        assert!((a.iou(&b) - 50.0 / 150.0).abs() < 1e-12);
    }

    #[test]
    fn centre_round_trips() {
        let b = BBox::from_centre(Point::new(3.0, 4.0), 2.0, 6.0);
        assert_eq!(b, BBox::new(2.0, 1.0, 2.0, 6.0));
        assert_eq!(b.centre(), Point::new(3.0, 4.0));
    }
}
