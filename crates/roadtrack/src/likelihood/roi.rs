//! Windows (ROIs) cut from a frame around a particle's position (seed 004 eq. 10,
//! `ROI(I_k, x)`), with an explicit policy for windows that cross the image border.

use crate::geometry::Point;
use image::{Rgb, RgbImage};
use serde::{Deserialize, Serialize};

/// What to do with the part of a window that lies outside the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BorderPolicy {
    /// Replicate the nearest edge pixel (the window keeps its centre).
    #[default]
    Clamp,
    /// Move the window inside the image (its centre shifts towards the image).
    Shift,
    /// Leave outside pixels out (histograms count only the inside; cut windows are black there).
    Skip,
}

/// A fixed-size window centred on a position.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Window {
    /// Width, px.
    pub width_px: u32,
    /// Height, px.
    pub height_px: u32,
    /// Border handling.
    pub border: BorderPolicy,
}

impl Default for Window {
    fn default() -> Self {
        // Choice: 32 × 32 px; the paper fixes a window size but does not state it (its CNN
        // input is Inception v3's 299 × 299, rescaled from the window).
        Self {
            width_px: 32,
            height_px: 32,
            border: BorderPolicy::Clamp,
        }
    }
}

impl Window {
    /// A `width × height` px window with `border` handling.
    pub const fn new(width_px: u32, height_px: u32, border: BorderPolicy) -> Self {
        Self {
            width_px,
            height_px,
            border,
        }
    }

    /// Top-left pixel of the window centred on `centre_px` in an image of `w × h` px.
    fn origin(&self, centre_px: Point, w: u32, h: u32) -> (i64, i64) {
        // Choice: pixel (i, j) has its centre at (i + 0.5, j + 0.5), and the window covers
        // the `width × height` pixels whose centres are nearest to being centred on the
        // position; non-finite positions are treated as the image origin.
        let cx = if centre_px.x.is_finite() {
            centre_px.x
        } else {
            0.0
        };
        let cy = if centre_px.y.is_finite() {
            centre_px.y
        } else {
            0.0
        };
        let left = (cx - f64::from(self.width_px) / 2.0)
            .round()
            .clamp(-1e9, 1e9) as i64;
        let top = (cy - f64::from(self.height_px) / 2.0)
            .round()
            .clamp(-1e9, 1e9) as i64;
        match self.border {
            BorderPolicy::Shift => (
                left.min(i64::from(w) - i64::from(self.width_px)).max(0),
                top.min(i64::from(h) - i64::from(self.height_px)).max(0),
            ),
            BorderPolicy::Clamp | BorderPolicy::Skip => (left, top),
        }
    }

    /// Calls `f` with every pixel of the window (every `step`-th row and column, `step ≥ 1`),
    /// after border handling; returns how many pixels were visited.
    pub fn for_each_pixel(
        &self,
        image: &RgbImage,
        centre_px: Point,
        step: u32,
        mut f: impl FnMut(&Rgb<u8>),
    ) -> usize {
        let (w, h) = image.dimensions();
        if w == 0 || h == 0 {
            return 0;
        }
        let (left, top) = self.origin(centre_px, w, h);
        let step = step.max(1) as usize;
        let mut n = 0;
        for dy in (0..self.height_px as i64).step_by(step) {
            let y = top + dy;
            if self.border == BorderPolicy::Skip && (y < 0 || y >= i64::from(h)) {
                continue;
            }
            let yc = y.clamp(0, i64::from(h) - 1) as u32;
            for dx in (0..self.width_px as i64).step_by(step) {
                let x = left + dx;
                if self.border == BorderPolicy::Skip && (x < 0 || x >= i64::from(w)) {
                    continue;
                }
                let xc = x.clamp(0, i64::from(w) - 1) as u32;
                f(image.get_pixel(xc, yc));
                n += 1;
            }
        }
        n
    }

    /// The window as an image of `width_px × height_px` (the input of a classifier).
    pub fn cut(&self, image: &RgbImage, centre_px: Point) -> RgbImage {
        let (w, h) = image.dimensions();
        let (left, top) = self.origin(centre_px, w, h);
        RgbImage::from_fn(self.width_px, self.height_px, |dx, dy| {
            let x = left + i64::from(dx);
            let y = top + i64::from(dy);
            let inside = x >= 0 && y >= 0 && x < i64::from(w) && y < i64::from(h);
            if w == 0 || h == 0 || (!inside && self.border == BorderPolicy::Skip) {
                Rgb([0, 0, 0])
            } else {
                let xc = x.clamp(0, i64::from(w) - 1) as u32;
                let yc = y.clamp(0, i64::from(h) - 1) as u32;
                *image.get_pixel(xc, yc)
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| Rgb([x as u8, y as u8, 7]))
    }

    #[test]
    fn inner_window_is_the_plain_crop() {
        let img = ramp(20, 10);
        let win = Window::new(4, 2, BorderPolicy::Clamp).cut(&img, Point::new(10.0, 5.0));
        assert_eq!(win.get_pixel(0, 0).0, [8, 4, 7]);
        assert_eq!(win.get_pixel(3, 1).0, [11, 5, 7]);
    }

    #[test]
    fn border_policies_differ_only_outside_the_image() {
        let img = ramp(20, 10);
        let c = Point::new(0.0, 0.0);
        let clamp = Window::new(4, 4, BorderPolicy::Clamp).cut(&img, c);
        let shift = Window::new(4, 4, BorderPolicy::Shift).cut(&img, c);
        let skip = Window::new(4, 4, BorderPolicy::Skip).cut(&img, c);
        // Clamp replicates pixel (0, 0) over the outside quadrants.
        assert_eq!(clamp.get_pixel(0, 0).0, [0, 0, 7]);
        assert_eq!(clamp.get_pixel(3, 3).0, [1, 1, 7]);
        // Shift moves the window to start at (0, 0).
        assert_eq!(shift.get_pixel(3, 3).0, [3, 3, 7]);
        // Skip blacks out the outside and keeps the inside.
        assert_eq!(skip.get_pixel(0, 0).0, [0, 0, 0]);
        assert_eq!(skip.get_pixel(3, 3).0, [1, 1, 7]);
        let n = Window::new(4, 4, BorderPolicy::Skip).for_each_pixel(&img, c, 1, |_| {});
        assert_eq!(n, 4);
        let n = Window::new(4, 4, BorderPolicy::Clamp).for_each_pixel(&img, c, 2, |_| {});
        assert_eq!(n, 4);
    }

    #[test]
    fn window_larger_than_the_image_stays_defined() {
        let img = ramp(3, 3);
        for border in [BorderPolicy::Clamp, BorderPolicy::Shift, BorderPolicy::Skip] {
            let win = Window::new(8, 8, border);
            let _ = win.cut(&img, Point::new(f64::NAN, 1e300));
            assert!(win.for_each_pixel(&img, Point::new(1.0, 1.0), 1, |_| {}) > 0);
        }
    }
}
