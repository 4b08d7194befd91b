//! One video frame with its number and time.

use image::RgbImage;

/// A frame of a sequence.
#[derive(Debug, Clone)]
pub struct Frame {
    /// 1-based frame number in the source (MOTChallenge convention); kept when frames are
    /// skipped with `--start`/`--step`.
    pub index: u32,
    /// Time since the source's first frame, s: `(index − 1) / fps`.
    pub time_s: f64,
    /// The pixels, 8-bit RGB.
    pub image: RgbImage,
}

impl Frame {
    /// Width and height, px.
    pub fn size(&self) -> (u32, u32) {
        self.image.dimensions()
    }
}
