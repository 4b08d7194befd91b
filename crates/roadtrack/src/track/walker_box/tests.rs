use super::*;
use crate::track::boxes_of as boxes;
use crate::track_point::TrackPoint;
use roadtrack_sim::{SceneKind, SimConfig, ViewKind, simulate_in_memory};

/// A camera 12 m up at (0, −30) looking along `+y`, 0.5 rad down, f = 512 px, its
/// principal point at the centre of 640 × 480 px: the ground homography of that view.
fn calibration() -> Calibration {
    crate::track::solid::looking_along_y(12.0, 30.0, 0.5)
}

fn camera() -> Pinhole {
    Pinhole::from_calibration(&calibration(), 640, 480).expect("a perspective view")
}

/// The point of track `id` in `frame` with box `b`.
fn point(frame: u32, id: u64, class: ObjectClass, b: BBox) -> TrackPoint {
    crate::track::point_at(frame, id, class, b)
}

/// A walker 1.8 m tall at `(x0 + v·t, y)`, facing `heading`, its box the body's image
/// with the width scaled by `w_err(frame)`: the detector's guess.
fn walker(
    id: u64,
    frames: std::ops::RangeInclusive<u32>,
    (x0, y, v): (f64, f64, f64),
    heading: f64,
    w_err: impl Fn(u32) -> f64,
) -> Vec<TrackPoint> {
    let (cam, cfg) = (camera(), WalkerBoxConfig::default());
    frames
        .map(|f| {
            let x = x0 + v * f64::from(f - 1) / 10.0;
            let b = walker_box(&cam, &cfg, (x, y), heading, 1.8).expect("in front");
            let b = BBox::from_centre(b.centre(), b.width * w_err(f), b.height);
            point(f, id, ObjectClass::Pedestrian, b)
        })
        .collect()
}

fn run(points: &[TrackPoint], n: u32) -> Result<(Vec<FramePoints>, usize)> {
    run_with(points, n, WalkerBoxConfig::default(), &[])
}

/// The stage of `config` over `points`, given the detections `seen` (by frame, from 1).
fn run_with(
    points: &[TrackPoint],
    n: u32,
    config: WalkerBoxConfig,
    seen: &[(u32, BBox)],
) -> Result<(Vec<FramePoints>, usize)> {
    let mut stage = WalkerBoxStage::new(config, &calibration(), 640, 480)?;
    let dets = |f: u32| -> Vec<BBox> {
        seen.iter()
            .filter(|(g, _)| *g == f)
            .map(|(_, b)| *b)
            .collect()
    };
    let out = crate::track::run_box_stage(&mut stage, points, n, dets)?;
    Ok((out, stage.changed()))
}

/// The body seen through the camera recovered from a simulated crossing's calibration,
/// at each walker's true place, heading and size, is that walker's `gt.txt` box.
#[test]
fn the_body_model_gives_the_simulators_walker_boxes() -> Result<()> {
    let sim = SimConfig {
        scene: SceneKind::Crossing,
        view: ViewKind::Oblique,
        frames: 3,
        ..Default::default()
    };
    let run = simulate_in_memory(&sim, 3)?;
    let (w, h) = (run.frames[0].image.width(), run.frames[0].image.height());
    let cam = Pinhole::from_calibration(&run.calibration, w, h)?;
    let mut n = 0;
    for t in &run.truth {
        let b = t.bbox;
        let inside = b.left > 1.0
            && b.top > 1.0
            && b.right() < f64::from(w) - 1.0
            && b.bottom() < f64::from(h) - 1.0;
        if t.class != ObjectClass::Pedestrian || !inside {
            continue;
        }
        let cfg = WalkerBoxConfig {
            depth_m: t.length_m,
            width_m: t.width_m,
            ..WalkerBoxConfig::default()
        };
        let m = walker_box(
            &cam,
            &cfg,
            (t.x_m, t.y_m),
            t.heading_deg.to_radians(),
            t.height_m,
        )
        .expect("in front");
        for (got, want) in [
            (m.left, b.left),
            (m.top, b.top),
            (m.width, b.width),
            (m.height, b.height),
        ] {
            assert!((got - want).abs() < 0.05, "walker {}: {m:?} {b:?}", t.id);
        }
        n += 1;
    }
    assert!(n >= 20, "{n} walkers checked");
    Ok(())
}

/// A walker's boxes, their widths guessed 30 % too wide or too narrow in turn, take the
/// body's width for the walk and the height fitted to the boxes (1.8 m, not the prior);
/// without `smooth_centres` the centres stay.
#[test]
fn a_walkers_boxes_take_the_bodys_shape_for_their_walk() -> Result<()> {
    let truth = walker(1, 1..=40, (-3.0, 5.0, 1.4), 0.0, |_| 1.0);
    let guessed = walker(1, 1..=40, (-3.0, 5.0, 1.4), 0.0, |f| {
        if f % 2 == 0 { 1.3 } else { 0.7 }
    });
    let kept = WalkerBoxConfig {
        smooth_centres: false,
        ..Default::default()
    };
    let (out, changed) = run_with(&guessed, 40, kept, &[])?;
    assert_eq!(changed, 40);
    for ((got, want), before) in boxes(&out, 1).iter().zip(&truth).zip(&guessed) {
        let w = want.bbox;
        assert!(
            (got.width - w.width).abs() < 0.02 * w.width,
            "{got:?} {w:?}"
        );
        assert!(
            (got.height - w.height).abs() < 0.01 * w.height,
            "{got:?} {w:?}"
        );
        let (c, c0) = (got.centre(), before.bbox.centre());
        assert!(c.distance(c0) < 1e-9, "centre moved");
    }
    // The same walker walking along y shows another width: the heading matters.
    let across = walker(2, 1..=40, (0.0, 5.0, 0.0), 0.0, |_| 1.0);
    let along = walker_box(
        &camera(),
        &WalkerBoxConfig::default(),
        (0.0, 5.0),
        std::f64::consts::FRAC_PI_2,
        1.8,
    )
    .expect("in front");
    assert!((across[0].bbox.width - along.width).abs() > 0.1 * along.width);
    Ok(())
}

/// A walker's boxes jittered about the body's image (up to 1.5 px, as a detector's are)
/// take their centres from the smoothed path: within a fifth of the jitter of the truth's,
/// whether the detections or (a run without them) the track's own boxes are measured. A
/// detection 8 px off is left out. The sizes are those the stage gives without the path.
#[test]
fn a_walkers_centres_come_from_the_smoothed_path() -> Result<()> {
    let n = 60;
    let truth = walker(1, 1..=n, (-4.0, 5.0, 1.4), 0.3, |_| 1.0);
    let jitter = |f: u32| {
        let p = f64::from(f);
        (1.5 * (2.3 * p).sin(), 1.2 * (1.7 * p + 0.5).cos())
    };
    let jittered: Vec<TrackPoint> = truth
        .iter()
        .map(|p| {
            let (dx, dy) = jitter(p.frame);
            let c = p.bbox.centre();
            let b = BBox::from_centre(Point::new(c.x + dx, c.y + dy), p.bbox.width, p.bbox.height);
            point(p.frame, 1, ObjectClass::Pedestrian, b)
        })
        .collect();
    let error = |out: &[FramePoints]| -> f64 {
        boxes(out, 1)
            .iter()
            .zip(&truth)
            .map(|(b, t)| b.centre().distance(t.bbox.centre()))
            .sum::<f64>()
            / f64::from(n)
    };
    let before = jittered
        .iter()
        .zip(&truth)
        .map(|(b, t)| b.bbox.centre().distance(t.bbox.centre()))
        .sum::<f64>()
        / f64::from(n);
    let mut seen: Vec<(u32, BBox)> = jittered.iter().map(|p| (p.frame, p.bbox)).collect();
    // Frame 30's detection lies 8 px off (a neighbour's): the track's box still overlaps it.
    let b = seen[29].1;
    seen[29].1 = BBox::from_centre(
        Point::new(b.centre().x + 8.0, b.centre().y),
        b.width,
        b.height,
    );
    let (own, changed) = run(&jittered, n)?;
    assert_eq!(changed, n as usize);
    let (detected, _) = run_with(&jittered, n, WalkerBoxConfig::default(), &seen)?;
    for out in [&own, &detected] {
        assert!(error(out) < 0.2 * before, "{} against {before}", error(out));
    }
    let at30 = boxes(&detected, 1)[29].centre();
    assert!(at30.distance(truth[29].bbox.centre()) < 0.5, "{at30:?}");
    let kept = WalkerBoxConfig {
        smooth_centres: false,
        ..Default::default()
    };
    let (sized, _) = run_with(&jittered, n, kept, &[])?;
    for (a, b) in boxes(&own, 1).iter().zip(boxes(&sized, 1)) {
        assert!((a.width - b.width).abs() < 1e-9 && (a.height - b.height).abs() < 1e-9);
    }
    Ok(())
}

/// A walker who walks and then stands keeps the direction of the walk; one never seen
/// walking, a car, and a box at the frame's edge are left as they were.
#[test]
fn standing_walkers_keep_their_walk_and_others_are_left_alone() -> Result<()> {
    let mut points = walker(1, 1..=20, (-3.0, 5.0, 1.4), 0.0, |_| 1.2);
    // Frames 21–40 standing where the walk ended, boxes 20 % too wide.
    let end = (-3.0 + 1.4 * 1.9, 5.0);
    let (cam, cfg) = (camera(), WalkerBoxConfig::default());
    let want = walker_box(&cam, &cfg, end, 0.0, 1.8).expect("in front");
    for f in 21..=40 {
        let b = BBox::from_centre(want.centre(), want.width * 1.2, want.height);
        points.push(point(f, 1, ObjectClass::Pedestrian, b));
    }
    let still = walker(2, 1..=40, (2.0, 8.0, 0.0), 0.0, |_| 1.2);
    let car: Vec<TrackPoint> = walker(3, 1..=40, (-3.0, 3.0, 1.4), 0.0, |_| 1.2)
        .into_iter()
        .map(|p| TrackPoint {
            class: ObjectClass::Car,
            ..p
        })
        .collect();
    let edge: Vec<TrackPoint> = (1..=40)
        .map(|f| {
            let b = BBox {
                left: 0.0,
                top: 200.0,
                width: 6.0 + 0.1 * f64::from(f),
                height: 40.0,
            };
            point(f, 4, ObjectClass::Pedestrian, b)
        })
        .collect();
    let all: Vec<TrackPoint> = [points, still.clone(), car.clone(), edge.clone()].concat();
    let (out, _) = run(&all, 40)?;
    let standing = &boxes(&out, 1)[30];
    assert!(
        (standing.width - want.width).abs() < 0.02 * want.width,
        "{standing:?} {want:?}"
    );
    for (id, before) in [(2, &still), (3, &car), (4, &edge)] {
        let after = boxes(&out, id);
        assert_eq!(after.len(), before.len());
        for (a, b) in after.iter().zip(before) {
            assert_eq!(*a, b.bbox, "track {id}");
        }
    }
    Ok(())
}

#[test]
fn bad_settings_and_views_without_perspective_are_refused() -> Result<()> {
    for (cfg, field) in [
        (
            WalkerBoxConfig {
                height_m: 0.0,
                ..Default::default()
            },
            "height_m",
        ),
        (
            WalkerBoxConfig {
                half_window_frames: 0,
                ..Default::default()
            },
            "half_window_frames",
        ),
        (
            WalkerBoxConfig {
                min_speed_mps: f64::NAN,
                ..Default::default()
            },
            "min_speed_mps",
        ),
        (
            WalkerBoxConfig {
                accel_noise: vec![],
                ..Default::default()
            },
            "accel_noise",
        ),
        (
            WalkerBoxConfig {
                accel_noise: vec![0.3, -1.0],
                ..Default::default()
            },
            "accel_noise",
        ),
        (
            WalkerBoxConfig {
                min_iou: 1.5,
                ..Default::default()
            },
            "min_iou",
        ),
        (
            WalkerBoxConfig {
                outlier_sigmas: 0.0,
                ..Default::default()
            },
            "outlier_sigmas",
        ),
        (
            WalkerBoxConfig {
                passes: 101,
                ..Default::default()
            },
            "passes",
        ),
    ] {
        let err = WalkerBoxStage::new(cfg, &calibration(), 640, 480).unwrap_err();
        assert!(err.to_string().contains(field), "{err}");
    }
    let nadir = Calibration::from_nadir(0.25, [0.0, 0.0], 0.0)?;
    let err = WalkerBoxStage::new(WalkerBoxConfig::default(), &nadir, 640, 480).unwrap_err();
    assert!(err.to_string().contains("no perspective"), "{err}");
    Ok(())
}
