//! The learned detector's levels: the shrunk pyramid level and the zoomed one.

use super::tests::{cand, iou, shipped};
use super::*;
use image::RgbImage;

#[test]
fn the_added_zoom_finds_small_far_vehicles_the_other_levels_miss() -> Result<()> {
    use roadtrack_sim::{SceneKind, SimConfig, ViewKind};
    // Oblique road frames of held-out seeds: most of their vehicles are far and small.
    let cfg = SimConfig {
        scene: SceneKind::Road,
        view: ViewKind::Oblique,
        frames: 1,
        ..SimConfig::default()
    };
    let plain = CenterNetDetector::load(&shipped(), &CenterNetConfig::default())?;
    let zoomed = CenterNetDetector::load(
        &shipped(),
        &CenterNetConfig {
            zoom_max_side: 12.0,
            zoom_mode: ZoomMode::Add,
            ..Default::default()
        },
    )?;
    let (mut n_small, mut before, mut after, mut banded) = (0, 0, 0, 0);
    for seed in [24, 25, 26] {
        let run = roadtrack_sim::simulate_in_memory(&cfg, seed)?;
        let image = &run.frames[0].image;
        let a = plain.detect_boxes(image)?;
        let b = zoomed.detect_boxes(image)?;
        // With the calibration, only the far rows are enlarged: added centres lie in them.
        let in_band = CenterNetDetector::load(
            &shipped(),
            &CenterNetConfig {
                zoom_max_side: 12.0,
                zoom_mode: ZoomMode::Add,
                ..Default::default()
            },
        )?
        .with_zoom_calibration(run.calibration.clone());
        let c = in_band.detect_boxes(image)?;
        assert_eq!(&c[..a.len()], &a[..]);
        let (top, bottom) =
            zoom_rows(&run.calibration, image.width(), image.height(), 12.0).expect("far rows");
        assert!(c[a.len()..].iter().all(|(bb, _, _)| {
            let y = bb.centre().y;
            y >= f64::from(top) - 0.5 && y < f64::from(bottom) + 0.5
        }));
        // The other levels' boxes are kept as they are, first; the zoom only adds.
        assert_eq!(&b[..a.len()], &a[..]);
        assert!(
            b[a.len()..]
                .iter()
                .all(|(bb, _, _)| bb.width.max(bb.height) < 12.0)
        );
        let small: Vec<_> = run
            .truth
            .iter()
            .filter(|t| t.visibility >= 0.5 && t.bbox.width.max(t.bbox.height) < 12.0)
            .collect();
        let hits = |boxes: &[(
            roadtrack::geometry::BBox,
            roadtrack::class::ObjectClass,
            f64,
        )]| {
            small
                .iter()
                .filter(|t| boxes.iter().any(|(bb, _, _)| iou(bb, &t.bbox) >= 0.5))
                .count()
        };
        n_small += small.len();
        before += hits(&a);
        after += hits(&b);
        banded += hits(&c);
    }
    eprintln!("small vehicles {n_small}: found {before} → {after}, {banded} in the band only");
    assert!(
        banded >= before + 6,
        "band only: found {before} → {banded} of {n_small}"
    );
    assert!(n_small >= 15, "too few small vehicles: {n_small}");
    assert!(after >= before + 6, "found {before} → {after} of {n_small}");
    Ok(())
}

#[test]
fn the_zoomed_level_boxes_small_objects_better_than_the_full_size_level() -> Result<()> {
    use roadtrack_sim::{SceneKind, SimConfig, ViewKind};
    // Oblique frames of held-out seeds: far vehicles and walkers under 16 px.
    let detector = |zoom: f64, mode: ZoomMode| {
        CenterNetDetector::load(
            &shipped(),
            &CenterNetConfig {
                zoom_max_side: zoom,
                zoom_mode: mode,
                ..Default::default()
            },
        )
    };
    let plain = detector(0.0, ZoomMode::Level)?;
    let level = detector(16.0, ZoomMode::Level)?;
    let added = detector(16.0, ZoomMode::Add)?;
    let (mut n_small, mut found, mut tight) = (0, [0usize; 3], [0usize; 3]);
    let (mut sum_iou, mut false_small) = ([0.0f64; 3], [0usize; 3]);
    for (scene, seed) in [
        (SceneKind::Road, 24),
        (SceneKind::Road, 25),
        (SceneKind::Road, 26),
        (SceneKind::Intersection, 24),
        (SceneKind::Intersection, 25),
        (SceneKind::Intersection, 26),
    ] {
        let cfg = SimConfig {
            scene,
            view: ViewKind::Oblique,
            frames: 1,
            ..SimConfig::default()
        };
        let run = roadtrack_sim::simulate_in_memory(&cfg, seed)?;
        let image = &run.frames[0].image;
        let all = [
            plain.detect_boxes(image)?,
            level.detect_boxes(image)?,
            added.detect_boxes(image)?,
        ];
        // The level's boxes under 16 px are the zoomed level's: none of the full-size
        // level's small boxes is left unless the zoomed level found the same box.
        let zoomed_small: Vec<_> = all[1]
            .iter()
            .filter(|(b, _, _)| b.width.max(b.height) < 16.0)
            .collect();
        assert!(!zoomed_small.is_empty());
        let small: Vec<_> = run
            .truth
            .iter()
            .filter(|t| t.visibility >= 0.5 && t.bbox.width.max(t.bbox.height) < 16.0)
            .collect();
        n_small += small.len();
        for (k, boxes) in all.iter().enumerate() {
            found[k] += small
                .iter()
                .filter(|t| boxes.iter().any(|(b, _, _)| iou(b, &t.bbox) >= 0.5))
                .count();
            tight[k] += small
                .iter()
                .filter(|t| boxes.iter().any(|(b, _, _)| iou(b, &t.bbox) >= 0.7))
                .count();
            sum_iou[k] += small
                .iter()
                .map(|t| {
                    boxes
                        .iter()
                        .map(|(b, _, _)| iou(b, &t.bbox))
                        .fold(0.0, f64::max)
                })
                .sum::<f64>();
            false_small[k] += boxes
                .iter()
                .filter(|(b, _, _)| b.width.max(b.height) < 16.0)
                .filter(|(b, _, _)| run.truth.iter().all(|t| iou(b, &t.bbox) < 0.3))
                .count();
        }
    }
    let [p, l, a] = found;
    eprintln!(
        "small objects {n_small}: found at IoU 0.5 plain {p}, level {l}, added {a}; at 0.7 \
         {tight:?}; sum of best IoUs {sum_iou:?}; small boxes on no object {false_small:?}"
    );
    assert!(n_small >= 30, "too few small objects: {n_small}");
    // Both zooms find the small objects the full-size level misses (measured 17 → 33, 34
    // of 57); as a level, the full-size level's false small boxes go with its true ones
    // (measured 8 plain, 2 level, 8 added).
    assert!(l >= p + 10, "level {l} against plain {p} of {n_small}");
    assert!(l + 2 >= a, "level {l} against added {a} of {n_small}");
    assert!(
        2 * false_small[1] <= false_small[2],
        "small boxes on no object: {false_small:?}"
    );
    Ok(())
}

#[test]
fn the_zoomed_level_replaces_the_small_boxes_in_its_rows() {
    let levels = vec![
        cand(50.0, 50.0, 10.0, 20.0, 3, 0.9), // small, in the rows: replaced
        cand(50.0, 150.0, 10.0, 20.0, 3, 0.9), // small, below the rows: kept
        cand(200.0, 60.0, 40.0, 20.0, 0, 0.8), // large, in the rows: kept
        cand(300.0, 99.9, 12.0, 8.0, 0, 0.7), // small, last row in: replaced
    ];
    let zoomed = vec![cand(51.0, 50.5, 9.0, 19.0, 3, 0.6)];
    let mut out = levels.clone();
    replace_small(&mut out, zoomed.clone(), (0.0, 100.0), 24.0);
    assert_eq!(out, vec![levels[1], levels[2], zoomed[0]]);
    // A limit of 0 replaces nothing: the zoomed boxes are only added.
    let mut out = levels.clone();
    replace_small(&mut out, zoomed.clone(), (0.0, 100.0), 0.0);
    assert_eq!(out.len(), levels.len() + 1);
}

#[test]
fn the_zoom_rows_are_where_a_car_measures_under_the_limit() -> Result<()> {
    use roadtrack::calibration::Calibration;
    use roadtrack_sim::{SceneKind, SimConfig, ViewKind};
    // Nadir: a 4.5 m car is 4.5 / 0.33 = 13.6 px everywhere (no rows under 12 px) and
    // 9 px at 0.5 m/px (every row).
    let aerial = Calibration::from_nadir(0.33, [0.0, 0.0], 0.0)?;
    assert_eq!(zoom_rows(&aerial, 640, 480, 12.0), None);
    let high = Calibration::from_nadir(0.5, [0.0, 0.0], 0.0)?;
    assert_eq!(zoom_rows(&high, 640, 480, 12.0), Some((0, 480)));
    // Oblique: a band from just below the horizon; against the same rule evaluated
    // naively (the car's two ground steps projected) on each side of its lower edge.
    let cfg = SimConfig {
        scene: SceneKind::Road,
        view: ViewKind::Oblique,
        frames: 1,
        ..SimConfig::default()
    };
    let cal = roadtrack_sim::simulate_in_memory(&cfg, 1)?.calibration;
    let (top, bottom) = zoom_rows(&cal, 640, 480, 12.0).expect("far rows");
    assert!(bottom > top && bottom < 480, "{top}..{bottom}");
    let car_px = |y: u32| {
        let p = roadtrack::geometry::Point::new(320.0, f64::from(y) + 0.5);
        let g = cal.ground_from_image(p).expect("below the horizon");
        let len = |dx: f64, dy: f64| {
            let q = cal
                .image_from_ground(g.0 + 4.5 * dx, g.1 + 4.5 * dy)
                .expect("in front");
            ((q.x - p.x).powi(2) + (q.y - p.y).powi(2)).sqrt()
        };
        len(1.0, 0.0).max(len(0.0, 1.0))
    };
    // Steps of 1 m scaled by 4.5 against steps of 4.5 m: equal only to first order, so
    // compare a few rows away from the edge.
    assert!(car_px(bottom - 3) < 12.0, "{}", car_px(bottom - 3));
    assert!(car_px(bottom + 3) > 12.0, "{}", car_px(bottom + 3));
    Ok(())
}

#[test]
fn a_zoomed_box_on_an_object_already_boxed_is_not_added() {
    let cfg = CenterNetConfig {
        max_detections: 3,
        ..Default::default()
    };
    let mut kept = vec![cand(50.0, 50.0, 10.0, 10.0, 0, 0.9)];
    // IoU 0.52 with the kept box (another class): the same object again.
    let same = cand(52.0, 51.0, 8.0, 8.0, 3, 0.8);
    let apart = cand(80.0, 50.0, 8.0, 8.0, 0, 0.7);
    let next = cand(100.0, 50.0, 8.0, 8.0, 0, 0.6);
    let over = cand(120.0, 50.0, 8.0, 8.0, 0, 0.5);
    add_zoomed(&mut kept, vec![same, apart, next, over], &cfg);
    assert_eq!(kept.len(), 3, "{kept:?}");
    assert_eq!((kept[1].cx, kept[2].cx), (80.0, 100.0));
    let bad = CenterNetConfig {
        zoom_max_side: -1.0,
        ..Default::default()
    };
    use roadtrack::config::Validate;
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("zoom_max_side"), "{e}");
}

#[test]
fn shrinking_averages_blocks_and_keeps_positions() {
    // A naive reference: every output pixel is the rounded mean of its k × k block.
    let img = RgbImage::from_fn(37, 22, |x, y| {
        image::Rgb([(x * 7 + y * 3) as u8, (x * y) as u8, (255 - x - y) as u8])
    });
    for k in [2u32, 3] {
        let s = shrink(&img, k);
        assert_eq!(s.dimensions(), (37 / k, 22 / k));
        for (x, y, p) in s.enumerate_pixels() {
            for c in 0..3 {
                let mut sum = 0.0;
                for dy in 0..k {
                    for dx in 0..k {
                        sum += f64::from(img.get_pixel(x * k + dx, y * k + dy).0[c]);
                    }
                }
                let want = (sum / f64::from(k * k)).round();
                assert!((f64::from(p.0[c]) - want).abs() <= 0.5, "k {k} ({x}, {y})");
            }
        }
    }
    // A white 8 × 8 square at frame px [10, 18) lands on [5, 9) at half size.
    let sq = RgbImage::from_fn(32, 32, |x, y| {
        let v = if (10..18).contains(&x) && (10..18).contains(&y) {
            255
        } else {
            0
        };
        image::Rgb([v; 3])
    });
    let s = shrink(&sq, 2);
    for (x, y, p) in s.enumerate_pixels() {
        let inside = (5..9).contains(&x) && (5..9).contains(&y);
        assert_eq!(p.0[0] == 255, inside, "({x}, {y})");
    }
}

#[test]
fn pyramid_levels_keep_their_sizes_and_drop_parts_of_large_vehicles() {
    let cfg = CenterNetConfig::default();
    let (car, ped) = (0, 3);
    let fine = vec![
        cand(100.0, 100.0, 20.0, 10.0, car, 0.6), // part of the large car below: dropped
        cand(104.0, 98.0, 6.0, 18.0, ped, 0.5),   // a pedestrian in front of it: kept
        cand(300.0, 200.0, 30.0, 15.0, car, 0.7), // an ordinary car: kept
        cand(400.0, 300.0, 120.0, 60.0, car, 0.4), // too large for the fine level: dropped
    ];
    let coarse = vec![
        cand(50.0, 50.0, 60.0, 25.0, car, 0.8), // 120 × 50 frame px at (100, 100): kept
        cand(150.0, 20.0, 10.0, 5.0, car, 0.9), // 20 × 10 frame px: left to the fine level
        cand(200.0, 150.0, 30.0, 12.0, ped, 0.5), // a large pedestrian box: kept
    ];
    let got = merge_levels(fine, coarse, 2, &cfg);
    let keys: Vec<(f64, f64, f64, usize)> =
        got.iter().map(|c| (c.cx, c.cy, c.w, c.class)).collect();
    assert_eq!(
        keys,
        vec![
            (104.0, 98.0, 6.0, ped),
            (300.0, 200.0, 30.0, car),
            (100.0, 100.0, 120.0, car),
            (400.0, 300.0, 60.0, ped),
        ]
    );
    // Without the part rule the car part stays.
    let loose = CenterNetConfig {
        part_fraction: 1.01,
        ..cfg.clone()
    };
    assert_eq!(
        merge_levels(
            vec![cand(100.0, 100.0, 20.0, 10.0, car, 0.6)],
            vec![cand(50.0, 50.0, 60.0, 25.0, car, 0.8)],
            2,
            &loose
        )
        .len(),
        2
    );
}

#[test]
fn bad_pyramid_settings_are_refused_by_name() {
    use roadtrack::config::Validate;
    for (cfg, field) in [
        (
            CenterNetConfig {
                pyramid: 0,
                ..Default::default()
            },
            "pyramid",
        ),
        (
            CenterNetConfig {
                pyramid: 9,
                ..Default::default()
            },
            "pyramid",
        ),
        (
            CenterNetConfig {
                fine_max_side: 0.0,
                ..Default::default()
            },
            "fine_max_side",
        ),
        (
            CenterNetConfig {
                coarse_min_side: f64::NAN,
                ..Default::default()
            },
            "coarse_min_side",
        ),
        (
            CenterNetConfig {
                part_fraction: 2.0,
                ..Default::default()
            },
            "part_fraction",
        ),
        (
            CenterNetConfig {
                min_side: -1.0,
                ..Default::default()
            },
            "min_side",
        ),
        (
            CenterNetConfig {
                coarse_min_score: 1.5,
                ..Default::default()
            },
            "coarse_min_score",
        ),
    ] {
        let err = cfg.validate().unwrap_err().to_string();
        assert!(err.contains(field), "{field}: {err}");
    }
}

#[test]
fn a_zoom_of_three_finds_more_of_the_far_road_than_a_zoom_of_two() -> Result<()> {
    use roadtrack_sim::{SceneKind, SimConfig, ViewKind};
    // The far end of an oblique road (held-out seeds): most cars there are under 8 px,
    // two of the network's cells at a zoom of 2 and three at 3.
    let detector = |factor: u32, calibration: &roadtrack::calibration::Calibration| {
        CenterNetDetector::load(
            &shipped(),
            &CenterNetConfig {
                zoom_max_side: 16.0,
                zoom_factor: factor,
                ..Default::default()
            },
        )
        .map(|d| d.with_zoom_calibration(calibration.clone()))
    };
    const SMALL: f64 = 8.0;
    let (mut n_small, mut found) = (0, [0usize; 2]);
    for seed in 24..40 {
        let cfg = SimConfig {
            scene: SceneKind::Road,
            view: ViewKind::Oblique,
            frames: 1,
            ..SimConfig::default()
        };
        let run = roadtrack_sim::simulate_in_memory(&cfg, seed)?;
        let image = &run.frames[0].image;
        let small: Vec<_> = run
            .truth
            .iter()
            .filter(|t| t.visibility >= 0.5 && t.bbox.width.max(t.bbox.height) < SMALL)
            .collect();
        n_small += small.len();
        for (k, factor) in [2, 3].into_iter().enumerate() {
            let boxes = detector(factor, &run.calibration)?.detect_boxes(image)?;
            found[k] += small
                .iter()
                .filter(|t| boxes.iter().any(|(b, _, _)| iou(b, &t.bbox) >= 0.5))
                .count();
        }
    }
    eprintln!("objects under {SMALL} px {n_small}: found at IoU 0.5, zoom 2 and 3 {found:?}");
    assert!(n_small >= 100, "too few small objects: {n_small}");
    // Measured 99 and 107 of 189 (under 4 px alone: 21 and 24 of 73). Over whole
    // sequences the gain is larger under 4 px and the loss is between 8 and 16 px, where
    // a zoom of 3 boxes fewer at IoU 0.5 yet tracks better (docs/DETECTION.md "Zoom factor").
    assert!(found[1] > found[0], "{found:?} of {n_small}");
    // Out of range is refused by name.
    let bad = CenterNetConfig {
        zoom_factor: 5,
        ..Default::default()
    };
    use roadtrack::config::Validate;
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("zoom_factor"), "{e}");
    Ok(())
}
