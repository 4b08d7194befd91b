//! Moving textured rectangles over a textured background with a known depth order and
//! per-pixel truth: the MRF tracker's occlusion scenarios and benchmark scene.

use image::RgbImage;
use rand::RngExt as _;
use roadtrack_core::frame::Frame;
use roadtrack_core::geometry::BBox;
use roadtrack_core::rng::{Stream, rng_for};
use std::collections::BTreeMap;

/// The truth of one frame of a [`SynthSequence`].
#[derive(Debug, Clone, PartialEq)]
pub struct RectTruth {
    /// Frame width, px.
    pub width: u32,
    /// Frame height, px.
    pub height: u32,
    /// The id of the object each pixel shows (row-major), `None` for background.
    pub owner: Vec<Option<u64>>,
    /// Every object at least partly inside the frame, in the scene's order.
    pub objects: Vec<RectObjectTruth>,
}

/// One object of a [`RectTruth`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectObjectTruth {
    /// Truth id.
    pub id: u64,
    /// Its whole box (may extend past the frame), px.
    pub bbox: BBox,
    /// Whether another object hides some of its in-frame pixels.
    pub occluded: bool,
}

/// One rectangle.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthObject {
    /// Truth id.
    pub id: u64,
    /// Left edge at frame 1, px.
    pub left_px: f64,
    /// Top edge at frame 1, px.
    pub top_px: f64,
    /// Width, px.
    pub width_px: u32,
    /// Height, px.
    pub height_px: u32,
    /// Velocity, px/frame.
    pub velocity_px_per_frame: (f64, f64),
    /// Depth: smaller is nearer the camera and hides larger depths.
    pub depth: u32,
}

/// A scene: frame size, objects, sensor noise.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthScene {
    /// Frame width, px.
    pub width: u32,
    /// Frame height, px.
    pub height: u32,
    /// The objects.
    pub objects: Vec<SynthObject>,
    /// Per-pixel uniform noise amplitude added to every frame, grey levels (±).
    pub noise: u8,
}

/// A scene with its textures drawn: renders any frame.
#[derive(Debug, Clone)]
pub struct SynthSequence {
    scene: SynthScene,
    seed: u64,
    background: RgbImage,
    textures: Vec<RgbImage>,
}

impl SynthScene {
    /// `n` rectangles of 24–80 × 16–48 px at random places and velocities (±1–6 px/frame)
    /// over a `width × height` frame, random depths (the benchmark scene).
    pub fn moving_rectangles(width: u32, height: u32, n: u32, seed: u64) -> Self {
        let mut r = rng_for(seed, Stream::Scenario, 0);
        let objects = (0..n)
            .map(|i| {
                let w = r.random_range(24..=80u32);
                let h = r.random_range(16..=48u32);
                let sign =
                    |r: &mut roadtrack_core::rng::Rng| if r.random::<bool>() { 1.0 } else { -1.0 };
                SynthObject {
                    id: u64::from(i) + 1,
                    left_px: r.random_range(0.0..f64::from(width.saturating_sub(w).max(1))),
                    top_px: r.random_range(0.0..f64::from(height.saturating_sub(h).max(1))),
                    width_px: w,
                    height_px: h,
                    velocity_px_per_frame: (
                        sign(&mut r) * r.random_range(1.0..6.0),
                        sign(&mut r) * r.random_range(0.0..3.0),
                    ),
                    depth: i,
                }
            })
            .collect();
        Self {
            width,
            height,
            objects,
            noise: 2,
        }
    }

    /// Draws the textures: a sequence that can render every frame.
    pub fn build(&self, seed: u64) -> SynthSequence {
        let mut r = rng_for(seed, Stream::Render, 0);
        let background = RgbImage::from_fn(self.width, self.height, |_, _| {
            let v = r.random_range(40..110u8);
            image::Rgb([v, v.saturating_add(5), v.saturating_sub(5)])
        });
        let textures = self
            .objects
            .iter()
            .map(|o| {
                let mut r = rng_for(seed, Stream::Render, o.id + 1);
                let base: [u8; 3] = [
                    r.random_range(130..215),
                    r.random_range(130..215),
                    r.random_range(130..215),
                ];
                RgbImage::from_fn(o.width_px, o.height_px, |_, _| {
                    let d = r.random_range(0..40u8);
                    image::Rgb(base.map(|b| b.saturating_add(d)))
                })
            })
            .collect();
        SynthSequence {
            scene: self.clone(),
            seed,
            background,
            textures,
        }
    }
}

impl SynthSequence {
    /// The scene.
    pub fn scene(&self) -> &SynthScene {
        &self.scene
    }

    /// The object textures, in the scene's order.
    pub fn textures(&self) -> &[RgbImage] {
        &self.textures
    }

    /// Left and top of object `k` at frame `index` (1-based), whole px.
    fn position(&self, k: usize, index: u32) -> (i64, i64) {
        let o = &self.scene.objects[k];
        let t = f64::from(index.saturating_sub(1));
        (
            (o.left_px + o.velocity_px_per_frame.0 * t).round() as i64,
            (o.top_px + o.velocity_px_per_frame.1 * t).round() as i64,
        )
    }

    /// Frame `index` (1-based, 10 frames/s) and its truth: which object each pixel shows
    /// and every object at least partly inside the frame.
    pub fn frame(&self, index: u32) -> (Frame, RectTruth) {
        let (w, h) = (self.scene.width, self.scene.height);
        let mut img = self.background.clone();
        let mut owner = vec![None; (w * h) as usize];
        let mut order: Vec<usize> = (0..self.scene.objects.len()).collect();
        order.sort_by_key(|&k| std::cmp::Reverse(self.scene.objects[k].depth));
        for &k in &order {
            let (x0, y0) = self.position(k, index);
            let tex = &self.textures[k];
            for ty in 0..tex.height() {
                let y = y0 + i64::from(ty);
                if y < 0 || y >= i64::from(h) {
                    continue;
                }
                for tx in 0..tex.width() {
                    let x = x0 + i64::from(tx);
                    if x < 0 || x >= i64::from(w) {
                        continue;
                    }
                    img.put_pixel(x as u32, y as u32, *tex.get_pixel(tx, ty));
                    owner[(y as u32 * w + x as u32) as usize] = Some(self.scene.objects[k].id);
                }
            }
        }
        if self.scene.noise > 0 {
            let mut r = rng_for(self.seed, Stream::Render, 1 << 32 | u64::from(index));
            let a = i16::from(self.scene.noise);
            for p in img.iter_mut() {
                *p = (i16::from(*p) + r.random_range(-a..=a)).clamp(0, 255) as u8;
            }
        }
        let mut visible_px: BTreeMap<u64, u64> = BTreeMap::new();
        for id in owner.iter().flatten() {
            *visible_px.entry(*id).or_insert(0) += 1;
        }
        let objects = (0..self.scene.objects.len())
            .filter_map(|k| {
                let o = &self.scene.objects[k];
                let (x0, y0) = self.position(k, index);
                let inside_w = (x0 + i64::from(o.width_px)).min(i64::from(w)) - x0.max(0);
                let inside_h = (y0 + i64::from(o.height_px)).min(i64::from(h)) - y0.max(0);
                if inside_w <= 0 || inside_h <= 0 {
                    return None;
                }
                let in_frame = (inside_w * inside_h) as u64;
                Some(RectObjectTruth {
                    id: o.id,
                    bbox: BBox::new(
                        x0 as f64,
                        y0 as f64,
                        f64::from(o.width_px),
                        f64::from(o.height_px),
                    ),
                    occluded: visible_px.get(&o.id).copied().unwrap_or(0) < in_frame,
                })
            })
            .collect();
        (
            Frame {
                index,
                time_s: f64::from(index - 1) / 10.0,
                image: img,
            },
            RectTruth {
                width: w,
                height: h,
                owner,
                objects,
            },
        )
    }

    /// The empty scene (background and frame-0 sensor noise, no object): a clean sample for
    /// the background model.
    pub fn empty_frame(&self) -> RgbImage {
        let mut img = self.background.clone();
        if self.scene.noise > 0 {
            let mut r = rng_for(self.seed, Stream::Render, 1 << 32);
            let a = i16::from(self.scene.noise);
            for p in img.iter_mut() {
                *p = (i16::from(*p) + r.random_range(-a..=a)).clamp(0, 255) as u8;
            }
        }
        img
    }

    /// Frames `1..=n` with their truth.
    pub fn frames(&self, n: u32) -> (Vec<Frame>, Vec<RectTruth>) {
        (1..=n).map(|i| self.frame(i)).unzip()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn front_object_hides_the_back_one_and_truth_says_so() {
        let obj = |id, left_px, velocity_px_per_frame, depth| SynthObject {
            id,
            left_px,
            top_px: 16.0,
            width_px: 32,
            height_px: 32,
            velocity_px_per_frame,
            depth,
        };
        let scene = SynthScene {
            width: 128,
            height: 64,
            objects: vec![obj(1, 16.0, (8.0, 0.0), 0), obj(2, 40.0, (0.0, 0.0), 1)],
            noise: 0,
        };
        let seq = scene.build(1);
        let (f1, t1) = seq.frame(1);
        // Frame 1: object 1 covers x 16..48, object 2 x 40..72 behind it: 2 shows from 48.
        let shown = |id| t1.owner.iter().filter(|o| **o == Some(id)).count();
        assert_eq!(shown(1), 32 * 32);
        assert_eq!(shown(2), 24 * 32);
        assert!(!t1.objects[0].occluded && t1.objects[1].occluded);
        assert_eq!(t1.owner[20 * 128 + 44], Some(1));
        assert_eq!(
            f1.image.get_pixel(44, 20),
            seq.textures()[0].get_pixel(28, 4)
        );
        // Same seed → same pixels.
        assert_eq!(scene.build(1).frame(3).0.image, seq.frame(3).0.image);
    }
}
