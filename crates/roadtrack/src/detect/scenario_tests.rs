//! The background detector on simulated scenes and synthetic frames: queued vehicles at a
//! red light, shadows, a vehicle that stops, a platoon merged into one region.

use super::background::{BackgroundDetector, BackgroundDetectorConfig};
use super::background_model::{BackgroundConfig, BackgroundModel};
use crate::error::Result;
use crate::frame::Frame;
use crate::geometry::BBox;
use image::{Rgb, RgbImage};
use roadtrack_sim::{SceneKind, SimConfig, ViewKind, simulate_in_memory};

/// Recall at IoU 0.5 over the vehicles standing still (speed < 0.5 m/s) after being seen
/// moving in the sequence, at least half visible; and their number of boxes.
fn arrived_stopped_recall(
    run: &roadtrack_sim::SimRun,
    config: BackgroundDetectorConfig,
) -> Result<(f64, usize)> {
    let config = BackgroundDetectorConfig {
        calibration: Some(Box::new(run.calibration.clone())),
        ..config
    };
    let n = run.frames.len() as u32;
    let mut det =
        BackgroundDetector::bootstrap(config, run.frames.iter().cloned().map(Ok), Some(n))?;
    let mut boxes: Vec<Vec<BBox>> = Vec::new();
    for f in &run.frames {
        boxes.push(det.detect(f)?.iter().filter_map(|d| d.bbox()).collect());
    }
    let mut moved = std::collections::BTreeSet::new();
    let mut rows = Vec::new();
    // Truth rows come frame by frame.
    for t in &run.truth {
        if t.class == crate::class::ObjectClass::Pedestrian {
            continue;
        }
        if t.speed_mps >= 0.5 {
            moved.insert(t.id);
        } else if moved.contains(&t.id) && t.visibility >= 0.5 {
            rows.push(t);
        }
    }
    let found = rows
        .iter()
        .filter(|t| {
            boxes[t.frame as usize - 1]
                .iter()
                .any(|b| b.iou(&t.bbox) >= 0.5)
        })
        .count();
    Ok((found as f64 / rows.len().max(1) as f64, rows.len()))
}

/// An intersection whose light turns red during the sequence: vehicles drive up and wait
/// for the rest of it. The median start-up has them in the background (they cover their
/// pixels in most samples); the default (persistent start-up, hold, shadows) with splitting
/// by the calibration finds them (one region per queue otherwise).
#[test]
fn queued_vehicles_at_a_red_light_are_detected() -> Result<()> {
    let sim = SimConfig {
        scene: SceneKind::Intersection,
        view: ViewKind::Oblique,
        frames: QUEUE_FRAMES,
        ..Default::default()
    };
    let run = simulate_in_memory(&sim, QUEUE_SEED)?;
    let mut with_split = BackgroundDetectorConfig::default();
    with_split.split.enabled = true;
    let (new, n) = arrived_stopped_recall(&run, with_split)?;
    let (old, _) =
        arrived_stopped_recall(&run, BackgroundDetectorConfig::default().as_published())?;
    assert!(n >= 100, "only {n} stopped-vehicle boxes in the scene");
    assert!(old < 0.25, "old start-up recall {old:.2}");
    assert!(new >= 0.35, "new recall {new:.2} (old {old:.2})");
    Ok(())
}

const QUEUE_SEED: u64 = 0;
const QUEUE_FRAMES: u32 = 300;

fn grey(w: u32, h: u32, v: [u8; 3]) -> RgbImage {
    RgbImage::from_pixel(w, h, Rgb(v))
}

fn fill(img: &mut RgbImage, x0: u32, y0: u32, w: u32, h: u32, f: impl Fn([u8; 3]) -> [u8; 3]) {
    for y in y0..y0 + h {
        for x in x0..x0 + w {
            let p = img.get_pixel(x, y).0;
            img.put_pixel(x, y, Rgb(f(p)));
        }
    }
}

#[test]
fn a_shadow_is_not_foreground_but_a_dark_object_of_another_colour_is() -> Result<()> {
    let road = [110, 105, 100];
    let mut img = grey(40, 20, road);
    // A shadow: the road × 0.6 (same chromaticity).
    fill(&mut img, 2, 2, 10, 10, |p| {
        p.map(|v| (f32::from(v) * 0.6) as u8)
    });
    // A dark green object, as dark as the shadow.
    fill(&mut img, 20, 2, 10, 10, |_| [40, 80, 40]);
    let on = BackgroundConfig::default();
    let mut model = BackgroundModel::from_samples(&[grey(40, 20, road)], on.clone())?;
    let mask = model.classify(1, &img)?;
    assert_eq!(mask.get_pixel(5, 5)[0], 0, "shadow is foreground");
    assert_eq!(mask.get_pixel(25, 5)[0], 255, "dark object is background");
    // A black object (ratio below τ) stays foreground.
    let mut black = grey(40, 20, road);
    fill(&mut black, 2, 2, 10, 10, |_| [20, 20, 20]);
    assert_eq!(model.classify(2, &black)?.get_pixel(5, 5)[0], 255);
    // Switched off, the shadow is foreground.
    let off = BackgroundConfig {
        shadows: false,
        ..on
    };
    let mut model = BackgroundModel::from_samples(&[grey(40, 20, road)], off)?;
    assert_eq!(model.classify(1, &img)?.get_pixel(5, 5)[0], 255);
    Ok(())
}

/// A square that drives in and stops: with the hold it stays one whole object (its
/// road-coloured middle included) for the hold time; without it the middle is learnt and
/// the object falls apart.
#[test]
fn a_vehicle_that_stops_stays_whole_until_the_hold_ends() -> Result<()> {
    let road = [100, 100, 100];
    let frames: Vec<Frame> = (1..=140u32)
        .map(|i| {
            let mut img = grey(80, 40, road);
            let x0 = 2 + 2 * i.min(20);
            // A 20 × 12 white vehicle with a road-coloured 12 × 6 middle (its roof).
            fill(&mut img, x0, 14, 20, 12, |_| [230, 230, 230]);
            fill(&mut img, x0 + 4, 17, 12, 6, |_| road);
            Frame {
                index: i,
                time_s: f64::from(i - 1) / 10.0,
                image: img,
            }
        })
        .collect();
    let boot = vec![grey(80, 40, road)];
    let run = |hold: f64| -> Result<Vec<usize>> {
        let cfg = BackgroundDetectorConfig {
            background: BackgroundConfig {
                hold_still_s: hold,
                ..BackgroundConfig::default()
            },
            ..BackgroundDetectorConfig::default()
        };
        let mut det = BackgroundDetector::new(cfg, &boot)?;
        frames
            .iter()
            .map(|f| {
                Ok(det
                    .process(f)?
                    .regions
                    .iter()
                    .map(|r| r.area_px)
                    .sum::<u32>() as usize)
            })
            .collect()
    };
    let held = run(60.0)?;
    let free = run(0.0)?;
    // Stopped from frame 20; after 120 more frames (12 s) the held vehicle is whole
    // (20 × 12 = 240 px), the other lost its middle.
    assert_eq!(held[139], 240, "held: {:?}", &held[130..]);
    assert!(free[139] < 200, "not held: {:?}", &free[130..]);
    Ok(())
}

/// Two cars 6.5 m apart on a nadir view, merged into one mask region, come out as two
/// detections with a calibration and as one without.
#[test]
fn a_region_of_two_cars_in_a_row_is_split_in_two() -> Result<()> {
    use crate::calibration::Calibration;
    // 0.25 m/px: a car is 18 × 7 px, the pitch 26 px: two cars with the gap between them
    // filled (by a shadow, say) are one 44 × 7 px region.
    let road = [100, 100, 100];
    let mut img = grey(100, 40, road);
    fill(&mut img, 10, 16, 44, 7, |_| [230, 40, 40]);
    let cal = Calibration::from_nadir(0.25, [0.0, 0.0], 0.0)?;
    let detect = |cal: Option<Calibration>| -> Result<Vec<BBox>> {
        let mut cfg = BackgroundDetectorConfig {
            calibration: cal.map(Box::new),
            ..BackgroundDetectorConfig::default()
        };
        cfg.split.enabled = true;
        let mut det = BackgroundDetector::new(cfg, &[grey(100, 40, road)])?;
        let f = Frame {
            index: 1,
            time_s: 0.0,
            image: img.clone(),
        };
        Ok(det.detect(&f)?.iter().filter_map(|d| d.bbox()).collect())
    };
    assert_eq!(detect(None)?.len(), 1);
    let two = detect(Some(cal))?;
    assert_eq!(two.len(), 2, "{two:?}");
    for b in &two {
        assert!((b.width - 22.0).abs() <= 3.0, "{b:?}");
    }
    Ok(())
}
