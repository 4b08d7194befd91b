//! Cutting network inputs from a frame: model-sized windows centred on points, and whole
//! resampled frames for dense mode, with the model's preprocessing applied.
//!
//! Both go through [`sample_grid`], so a window cut at a dense grid point and the same
//! region of the dense input hold bit-for-bit the same samples; this is what makes dense
//! lookups agree with per-window scores (docs/CNN.md "Dense mode").
//!
//! Border policy: samples outside the image take the nearest edge pixel's value
//! (replicate-edge), so a particle at the border still sees a full window.

use image::RgbImage;
use serde::{Deserialize, Serialize};

use roadtrack::geometry::Point;

/// Per-channel preprocessing: `value = (pixel · input_scale − mean[c]) / std[c]`, with
/// `pixel` the 8-bit RGB value and channels in R, G, B order.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Preprocessing {
    /// Multiplier applied to the 0–255 pixel value first. Default 1/255.
    pub input_scale: f32,
    /// Per-channel mean subtracted after scaling (R, G, B). Default 0.
    pub mean: [f32; 3],
    /// Per-channel divisor applied last (R, G, B). Default 1.
    pub std: [f32; 3],
}

impl Default for Preprocessing {
    fn default() -> Self {
        // Choice: [0, 1] inputs when neither the config nor the model's metadata says
        // otherwise (the paper does not describe its preprocessing).
        Self {
            input_scale: 1.0 / 255.0,
            mean: [0.0; 3],
            std: [1.0; 3],
        }
    }
}

impl Preprocessing {
    /// The SSD/MobileNet convention `RGB · 2/255 − 1` (inputs in `[−1, 1]`).
    pub fn minus_one_to_one() -> Self {
        Self {
            input_scale: 2.0 / 255.0,
            mean: [1.0; 3],
            std: [1.0; 3],
        }
    }

    /// Rejects zero or non-finite divisors and scales.
    pub fn validate(&self) -> roadtrack::Result<()> {
        if !self.input_scale.is_finite() || self.input_scale == 0.0 {
            return Err(roadtrack::Error::config(
                "Preprocessing",
                "input_scale",
                format!("must be finite and non-zero, got {}", self.input_scale),
            ));
        }
        if self.std.iter().any(|s| !s.is_finite() || *s == 0.0) {
            return Err(roadtrack::Error::config(
                "Preprocessing",
                "std",
                format!("must be finite and non-zero, got {:?}", self.std),
            ));
        }
        if self.mean.iter().any(|m| !m.is_finite()) {
            return Err(roadtrack::Error::config(
                "Preprocessing",
                "mean",
                format!("must be finite, got {:?}", self.mean),
            ));
        }
        Ok(())
    }

    /// The affine map of channel `c` as `(gain, offset)`: `value = gain · pixel + offset`.
    fn affine(&self, c: usize) -> (f32, f32) {
        (self.input_scale / self.std[c], -self.mean[c] / self.std[c])
    }
}

/// Precomputed bilinear taps along one axis, replicate-edge clamped.
fn taps(start: f64, step: f64, n: usize, len: u32) -> Vec<(usize, usize, f32)> {
    let last = len.saturating_sub(1) as f64;
    (0..n)
        .map(|i| {
            let p = (start + i as f64 * step).clamp(0.0, last);
            let i0 = p.floor();
            let f = (p - i0) as f32;
            let i0 = i0 as usize;
            let i1 = (i0 + 1).min(last as usize);
            (i0, i1, f)
        })
        .collect()
}

/// Samples a `width × height` grid of `image` into `out` as planar CHW `f32` (R, G, B
/// planes), preprocessed. Grid sample `(u, v)` reads the image at pixel-index position
/// `(x0 + u · step, y0 + v · step)` (pixel centres at integer positions) with bilinear
/// interpolation; positions outside the image are clamped to the edge (replicate-edge).
///
/// # Panics
/// If `out.len() != 3 · width · height` (a programmer error).
#[allow(clippy::too_many_arguments)]
pub fn sample_grid(
    image: &RgbImage,
    x0: f64,
    y0: f64,
    step: f64,
    width: usize,
    height: usize,
    prep: &Preprocessing,
    out: &mut [f32],
) {
    sample_grid_xy(image, (x0, y0), (step, step), (width, height), prep, out);
}

/// [`sample_grid`] with separate steps along x and y (`origin`, `step` and `size` as
/// `(x, y)` pairs), for stretching a patch of any aspect to the model's input.
///
/// # Panics
/// If `out.len() != 3 · width · height`.
pub fn sample_grid_xy(
    image: &RgbImage,
    (x0, y0): (f64, f64),
    (step_x, step_y): (f64, f64),
    (width, height): (usize, usize),
    prep: &Preprocessing,
    out: &mut [f32],
) {
    assert_eq!(out.len(), 3 * width * height, "output buffer is 3·w·h");
    let (iw, ih) = image.dimensions();
    if iw == 0 || ih == 0 {
        out.fill(0.0);
        return;
    }
    let xs = taps(x0, step_x, width, iw);
    let ys = taps(y0, step_y, height, ih);
    let raw = image.as_raw();
    let stride = iw as usize * 3;
    let plane = width * height;
    let gains: [(f32, f32); 3] = [prep.affine(0), prep.affine(1), prep.affine(2)];
    for (v, &(y0i, y1i, fy)) in ys.iter().enumerate() {
        let r0 = &raw[y0i * stride..(y0i + 1) * stride];
        let r1 = &raw[y1i * stride..(y1i + 1) * stride];
        for (u, &(x0i, x1i, fx)) in xs.iter().enumerate() {
            let o = v * width + u;
            for (c, &(gain, offset)) in gains.iter().enumerate() {
                let a = r0[x0i * 3 + c] as f32;
                let b = r0[x1i * 3 + c] as f32;
                let cc = r1[x0i * 3 + c] as f32;
                let d = r1[x1i * 3 + c] as f32;
                let top = a + (b - a) * fx;
                let bottom = cc + (d - cc) * fx;
                let value = top + (bottom - top) * fy;
                out[c * plane + o] = gain * value + offset;
            }
        }
    }
}

/// Cuts the window of `width × height` model pixels, each `scale` image pixels wide,
/// centred on `centre_px`, into `out` (planar CHW, preprocessed). Replicate-edge borders.
///
/// Window pixel `u` covers image x in `centre.x + (u − width/2 + [0, 1)) · scale`, so with
/// `scale = 1` and an integer `centre.x − width/2` the samples are exact pixels.
pub fn cut_window(
    image: &RgbImage,
    centre_px: Point,
    width: usize,
    height: usize,
    scale: f64,
    prep: &Preprocessing,
    out: &mut [f32],
) {
    let x0 = centre_px.x + (0.5 - width as f64 / 2.0) * scale - 0.5;
    let y0 = centre_px.y + (0.5 - height as f64 / 2.0) * scale - 0.5;
    sample_grid(image, x0, y0, scale, width, height, prep, out);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8, y as u8, (x + y) as u8]))
    }

    #[test]
    fn unit_scale_window_copies_exact_pixels() {
        let img = ramp(20, 10);
        let prep = Preprocessing {
            input_scale: 1.0,
            ..Default::default()
        };
        let mut out = vec![0.0; 3 * 4 * 2];
        cut_window(&img, Point::new(10.0, 5.0), 4, 2, 1.0, &prep, &mut out);
        // Window x = 8..12, y = 4..6.
        assert_eq!(&out[0..4], &[8.0, 9.0, 10.0, 11.0]);
        assert_eq!(&out[8..12], &[4.0, 4.0, 4.0, 4.0]);
        assert_eq!(&out[12..16], &[5.0, 5.0, 5.0, 5.0]);
        assert_eq!(out[16], 12.0);
    }

    #[test]
    fn outside_samples_replicate_the_edge() {
        let img = ramp(20, 10);
        let prep = Preprocessing {
            input_scale: 1.0,
            ..Default::default()
        };
        let mut out = vec![0.0; 3 * 4 * 4];
        cut_window(&img, Point::new(0.0, 0.0), 4, 4, 1.0, &prep, &mut out);
        // Window x = -2..2: columns -2, -1 replicate column 0.
        assert_eq!(&out[0..4], &[0.0, 0.0, 0.0, 1.0]);
        // Green plane, rows -2, -1, 0, 1.
        let g: Vec<f32> = (0..4).map(|v| out[16 + v * 4]).collect();
        assert_eq!(g, vec![0.0, 0.0, 0.0, 1.0]);
    }

    #[test]
    fn half_pixel_shift_interpolates() {
        let img = ramp(20, 10);
        let prep = Preprocessing {
            input_scale: 1.0,
            ..Default::default()
        };
        let mut out = vec![0.0; 3 * 2];
        cut_window(&img, Point::new(10.5, 5.0), 2, 1, 1.0, &prep, &mut out);
        assert_eq!(&out[0..2], &[9.5, 10.5]);
    }

    #[test]
    fn preprocessing_is_affine_per_channel() {
        let img = RgbImage::from_pixel(2, 2, image::Rgb([255, 0, 51]));
        let prep = Preprocessing {
            input_scale: 1.0 / 255.0,
            mean: [0.5, 0.5, 0.0],
            std: [0.5, 0.25, 1.0],
        };
        let mut out = vec![0.0; 3];
        cut_window(&img, Point::new(1.0, 1.0), 1, 1, 1.0, &prep, &mut out);
        assert!((out[0] - 1.0).abs() < 1e-6);
        assert!((out[1] + 2.0).abs() < 1e-6);
        assert!((out[2] - 0.2).abs() < 1e-6);
        assert!(Preprocessing::minus_one_to_one().validate().is_ok());
        assert!(
            Preprocessing {
                std: [0.0, 1.0, 1.0],
                ..Default::default()
            }
            .validate()
            .is_err()
        );
    }
}
