//! Generated scenes with known truth for tests and benchmarks (feature `testkit`), so that
//! every crate's tests draw their small synthetic inputs from one place:
//! - [`moving_boxes`]: coloured boxes wrapping around lanes (detector and pipeline
//!   throughput);
//! - [`square_scene`]: red squares at constant velocity with first-frame detections (the
//!   filters' tests and benchmark);
//! - [`rectangles`]: textured rectangles with depth order and per-pixel truth (the MRF
//!   tracker's occlusion scenarios);
//! - [`three_cars`]: three cars of distinct colours on the simulated crossing (the filters'
//!   and the CNN likelihood's tests).
//!
//! Whole traffic scenes come from the simulator itself ([`crate::simulate_in_memory`]).

pub mod rectangles;

use image::{Rgb, RgbImage};
use rand::RngExt as _;
use roadtrack_core::class::ObjectClass;
use roadtrack_core::detection::Detection;
use roadtrack_core::error::Result;
use roadtrack_core::frame::Frame;
use roadtrack_core::geometry::{BBox, Point};
use roadtrack_core::rng::{Stream, rng_for};

pub use rectangles::{RectObjectTruth, RectTruth, SynthObject, SynthScene, SynthSequence};

use crate::external::{ExternalTrajectories, TrajectorySample};
use crate::{SceneKind, SimConfig, Simulation, TruthRow, ViewKind};

/// Size of a [`square_scene`].
#[derive(Debug, Clone, PartialEq)]
pub struct SquareSceneConfig {
    /// Frame width, px. Default 640.
    pub width: u32,
    /// Frame height, px. Default 480.
    pub height: u32,
    /// Number of squares. Default 10.
    pub targets: usize,
    /// Frames. Default 30.
    pub frames: u32,
    /// Seed.
    pub seed: u64,
}

impl Default for SquareSceneConfig {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            targets: 10,
            frames: 30,
            seed: 0,
        }
    }
}

/// `cfg.targets` red 24 px squares at constant velocity over a checkerboard: the frames and
/// the first frame's detections (the filters' benchmark scene).
pub fn square_scene(cfg: &SquareSceneConfig) -> (Vec<Frame>, Vec<Detection>) {
    let mut rng = rng_for(cfg.seed, Stream::Synthetic, 0xBE7C);
    let (w, h) = (cfg.width, cfg.height);
    let background = RgbImage::from_fn(w, h, |x, y| {
        let v = 70 + ((x / 16 + y / 16) % 2) as u8 * 30;
        Rgb([v, v + 10, v])
    });
    let size = 24.0;
    let targets: Vec<(Point, Point, Rgb<u8>)> = (0..cfg.targets)
        .map(|_| {
            // One colour class (as one CNN class would be).
            let pos = Point::new(
                40.0 + rng.random::<f64>() * (f64::from(w) - 80.0),
                40.0 + rng.random::<f64>() * (f64::from(h) - 80.0),
            );
            let vel = Point::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
            let colour = Rgb([200, 40, 40]);
            (pos, vel, colour)
        })
        .collect();
    let frames = (1..=cfg.frames)
        .map(|index| {
            let t = f64::from(index - 1);
            let mut img = background.clone();
            for (p, v, c) in &targets {
                let b = BBox::from_centre(Point::new(p.x + v.x * t, p.y + v.y * t), size, size);
                for y in b.top.max(0.0) as u32..(b.bottom().min(f64::from(h))) as u32 {
                    for x in b.left.max(0.0) as u32..(b.right().min(f64::from(w))) as u32 {
                        img.put_pixel(x, y, *c);
                    }
                }
            }
            Frame {
                index,
                time_s: t / 10.0,
                image: img,
            }
        })
        .collect();
    let detections = targets
        .iter()
        .enumerate()
        .map(|(k, (p, _, _))| Detection {
            size_px: Some((size, size)),
            ..Detection::at(1, k as u64 + 1, *p)
        })
        .collect();
    (frames, detections)
}

/// A generated sequence: `n_objects` coloured rectangles moving at constant velocity over
/// a textured static background, `width × height` px. Deterministic (no randomness).
pub fn moving_boxes(width: u32, height: u32, n_frames: u32, n_objects: u32) -> Vec<Frame> {
    let background = RgbImage::from_fn(width, height, |x, y| {
        let v = 95 + ((x * 7 + y * 13) % 17) as u8;
        Rgb([v, v, v.saturating_add(3)])
    });
    (1..=n_frames)
        .map(|i| {
            let mut img = background.clone();
            for k in 0..n_objects {
                let (bw, bh) = (24 + 4 * (k % 5), 14 + 3 * (k % 4));
                let speed = 2 + (k % 6) as i64;
                let dir = if k % 2 == 0 { 1 } else { -1 };
                let lane_y = (20 + (k * 37) % (height.saturating_sub(bh + 40)).max(1)) as i64;
                let span = i64::from(width + bw);
                let x0 = (i64::from(k * 53) + dir * speed * i64::from(i)).rem_euclid(span)
                    - i64::from(bw);
                let colour = Rgb([
                    (40 + k * 67 % 200) as u8,
                    (30 + k * 101 % 210) as u8,
                    (50 + k * 29 % 190) as u8,
                ]);
                for y in lane_y..lane_y + i64::from(bh) {
                    for x in x0..x0 + i64::from(bw) {
                        if x >= 0 && y >= 0 && x < i64::from(width) && y < i64::from(height) {
                            img.put_pixel(x as u32, y as u32, colour);
                        }
                    }
                }
            }
            Frame {
                index: i,
                time_s: f64::from(i - 1) / 10.0,
                image: img,
            }
        })
        .collect()
}

/// Three cars of distinct colours (red, blue, yellow) driving along the oblique crossing's
/// road at 6 m/s, 20 m apart, for `frames` frames (simulator seed 3): the frames and the
/// truth. The yellow car is in view from the first frame, the blue one drives in at frame
/// 6, the red one after frame 30.
///
/// # Errors
/// As [`Simulation::from_trajectories`].
pub fn three_cars(frames: u32) -> Result<(Vec<Frame>, Vec<TruthRow>)> {
    let cfg = SimConfig {
        scene: SceneKind::Crossing,
        view: ViewKind::Oblique,
        frames,
        ..Default::default()
    };
    let mut samples = Vec::new();
    let cars = [
        (1u64, -1.75, -34.0, [200u8, 30, 30]),
        (2, 1.75, -14.0, [30, 60, 200]),
        (3, -1.75, 6.0, [230, 200, 40]),
    ];
    for (id, y, x0, rgb) in cars {
        for k in 0..=2 {
            let t = f64::from(k) * f64::from(frames) / 10.0 / 2.0;
            samples.push((
                id,
                TrajectorySample {
                    time_s: t,
                    class: ObjectClass::Car,
                    x_m: x0 + 6.0 * t,
                    y_m: y,
                    heading_deg: 0.0,
                    length_m: 4.5,
                    width_m: 1.8,
                    height_m: None,
                    rgb: Some(rgb),
                },
            ));
        }
    }
    let ext = ExternalTrajectories::new(samples)?;
    let sim = Simulation::from_trajectories(&cfg, 3, ext, Some(frames))?;
    let (mut out, mut truth) = (Vec::new(), Vec::new());
    for step in sim {
        let step = step?;
        out.push(step.frame);
        truth.extend(step.truth);
    }
    Ok((out, truth))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_cars_drive_one_behind_another_at_six_metres_a_second() -> Result<()> {
        let (frames, truth) = three_cars(30)?;
        assert_eq!(frames.len(), 30);
        let first = |id: u64| truth.iter().find(|r| r.id == id).map(|r| r.frame);
        // Car 3 starts in view; car 2, 20 m behind it, drives in later; car 1, 40 m
        // behind, is still out of view after 3 s.
        assert_eq!([1, 2, 3].map(first), [None, Some(6), Some(1)]);
        for r in &truth {
            assert!((r.speed_mps - 6.0).abs() < 1e-9, "{r:?}");
            let rgb = if r.id == 2 {
                [30, 60, 200]
            } else {
                [230, 200, 40]
            };
            assert_eq!(r.colour_rgb, rgb);
        }
        let x = |f: u32| {
            truth
                .iter()
                .find(|r| r.frame == f && r.id == 3)
                .map(|r| r.x_m)
        };
        let (x1, x11) = (x(1).unwrap_or(f64::NAN), x(11).unwrap_or(f64::NAN));
        assert!((x11 - x1 - 6.0).abs() < 1e-6, "{x1} -> {x11}");
        Ok(())
    }

    #[test]
    fn squares_start_where_their_detections_say_and_are_drawn_red() {
        let cfg = SquareSceneConfig {
            targets: 3,
            frames: 2,
            ..SquareSceneConfig::default()
        };
        let (frames, dets) = square_scene(&cfg);
        assert_eq!((frames.len(), dets.len()), (2, 3));
        for d in &dets {
            let p = frames[0]
                .image
                .get_pixel(d.pos_px.x as u32, d.pos_px.y as u32);
            assert_eq!(*p, Rgb([200, 40, 40]));
        }
        assert_eq!(square_scene(&cfg).0[1].image, frames[1].image);
    }

    #[test]
    fn moving_boxes_move() {
        let f = moving_boxes(320, 240, 3, 4);
        assert_eq!(f.len(), 3);
        assert_ne!(f[0].image, f[2].image);
        assert_eq!(moving_boxes(320, 240, 3, 4)[2].image, f[2].image);
    }
}
