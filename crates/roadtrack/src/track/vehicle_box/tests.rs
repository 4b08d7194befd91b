use super::*;
use crate::geometry::Point;
use crate::track::boxes_of as boxes;
use crate::track_point::TrackPoint;
use roadtrack_sim::{SceneKind, SimConfig, ViewKind, simulate_in_memory};
use std::collections::BTreeMap;

/// A camera 8 m up at (0, −20) looking along `+y`, 0.25 rad down, f = 512 px, its principal
/// point at the centre of 640 × 480 px: the ground homography of a view along a road.
fn calibration() -> Calibration {
    crate::track::solid::looking_along_y(8.0, 20.0, 0.25)
}

fn camera() -> Pinhole {
    Pinhole::from_calibration(&calibration(), 640, 480).expect("a perspective view")
}

const CAR: [f64; 3] = [4.5, 1.78, 1.45];

/// The true box of a car driving away along `y = lane` at 14 m/s from `y0`, at frame `f`
/// (10 frames/s).
fn car_box(lane: f64, y0: f64, f: u32) -> BBox {
    let y = y0 + 1.4 * f64::from(f - 1);
    vehicle_box(
        &camera(),
        Shape::Car,
        CAR,
        (lane, y),
        std::f64::consts::FRAC_PI_2,
    )
    .expect("in front")
}

/// A deterministic detector error for frame `f`: centre offsets of up to 0.6 px and widths
/// 10 % too wide, as the learned detector's far boxes are.
fn jittered(b: BBox, f: u32) -> BBox {
    let phase = f64::from(f) * 2.39996;
    let c = b.centre();
    BBox::from_centre(
        Point::new(c.x + 0.6 * phase.sin(), c.y + 0.5 * (1.7 * phase).cos()),
        b.width * 1.1,
        b.height * (1.0 + 0.05 * (0.9 * phase).sin()),
    )
}

fn point(frame: u32, id: u64, class: ObjectClass, b: BBox) -> TrackPoint {
    crate::track::point_at(frame, id, class, b)
}

/// Runs the stage on `points` over `n` frames, the detector having found `dets(frame)`.
fn run(
    config: VehicleBoxConfig,
    points: &[TrackPoint],
    n: u32,
    dets: impl Fn(u32) -> Vec<BBox>,
) -> Result<(Vec<FramePoints>, usize)> {
    let mut stage = VehicleBoxStage::new(config, &calibration(), 640, 480)?;
    let out = crate::track::run_box_stage(&mut stage, points, n, dets)?;
    Ok((out, stage.changed()))
}

/// The vehicles seen through the camera recovered from a simulated oblique road's (and
/// intersection's) calibration, at each vehicle's true place, heading and size, are their
/// `gt.txt` boxes: cars, lorries, buses and motorcycles.
#[test]
fn the_vehicle_model_gives_the_simulators_boxes() -> Result<()> {
    let mut seen = BTreeMap::new();
    for (scene, seed) in [(SceneKind::Road, 2), (SceneKind::Intersection, 3)] {
        let sim = SimConfig {
            scene,
            view: ViewKind::Oblique,
            frames: 1,
            ..Default::default()
        };
        let run = simulate_in_memory(&sim, seed)?;
        let (w, h) = (run.frames[0].image.width(), run.frames[0].image.height());
        let cam = Pinhole::from_calibration(&run.calibration, w, h)?;
        let cfg = VehicleBoxConfig::default();
        for t in &run.truth {
            let b = t.bbox;
            let inside = b.left > 1.0
                && b.top > 1.0
                && b.right() < f64::from(w) - 1.0
                && b.bottom() < f64::from(h) - 1.0;
            let Some((shape, _)) = cfg.vehicle(&t.class) else {
                continue;
            };
            if !inside {
                continue;
            }
            let dims = [t.length_m, t.width_m, t.height_m];
            let m = vehicle_box(
                &cam,
                shape,
                dims,
                (t.x_m, t.y_m),
                t.heading_deg.to_radians(),
            )
            .expect("in front");
            for (got, want) in [
                (m.left, b.left),
                (m.top, b.top),
                (m.width, b.width),
                (m.height, b.height),
            ] {
                assert!(
                    (got - want).abs() < 0.05,
                    "{} {}: {m:?} {b:?}",
                    t.class.name(),
                    t.id
                );
            }
            *seen.entry(t.class.name().to_string()).or_insert(0) += 1;
        }
    }
    for class in ["car", "truck", "bus", "motorcycle"] {
        assert!(seen.get(class).is_some_and(|&n| n >= 1), "{seen:?}");
    }
    Ok(())
}

fn mean_iou(got: &[BBox], want: &[BBox]) -> f64 {
    got.iter().zip(want).map(|(a, b)| a.iou(b)).sum::<f64>() / want.len() as f64
}

/// A car driving away, its boxes off by up to 0.6 px and 10 % too wide, is boxed from its
/// smoothed path: the boxes come close to the truth's, far and near alike.
#[test]
fn a_cars_noisy_boxes_are_redrawn_from_its_path() -> Result<()> {
    let n = 60;
    let truth: Vec<BBox> = (1..=n).map(|f| car_box(1.75, 10.0, f)).collect();
    let seen: Vec<BBox> = truth
        .iter()
        .zip(1..)
        .map(|(b, f)| jittered(*b, f))
        .collect();
    // The tracker's boxes are the detections, one frame in five missed and interpolated.
    let points: Vec<TrackPoint> = (1..=n)
        .map(|f| point(f, 7, ObjectClass::Car, seen[f as usize - 1]))
        .collect();
    let (out, changed) = run(VehicleBoxConfig::default(), &points, n, |f| {
        if f % 5 == 0 {
            Vec::new()
        } else {
            vec![seen[f as usize - 1]]
        }
    })?;
    assert_eq!(changed, n as usize);
    let got = boxes(&out, 7);
    let (before, after) = (mean_iou(&seen, &truth), mean_iou(&got, &truth));
    assert!(before < 0.9 && after > 0.95, "IoU {before} → {after}");
    // The far end (the car under 20 px) gains too.
    let far: Vec<usize> = (0..n as usize).filter(|&i| truth[i].width < 20.0).collect();
    assert!(far.len() >= 10, "{} far boxes", far.len());
    let pick = |v: &[BBox]| far.iter().map(|&i| v[i]).collect::<Vec<_>>();
    let far_truth = pick(&truth);
    let (b, a) = (
        mean_iou(&pick(&seen), &far_truth),
        mean_iou(&pick(&got), &far_truth),
    );
    assert!(a > b + 0.05 && a > 0.9, "far IoU {b} → {a}");
    Ok(())
}

/// Three detections 5 px off (a neighbour's box in part) are left out: with the outlier
/// test the boxes there stay on the car; without it they are pulled towards them. (At the
/// default `min_iou` of 0.7 they would not be matched at all.)
#[test]
fn outlying_detections_are_left_out() -> Result<()> {
    let n = 40;
    let truth: Vec<BBox> = (1..=n).map(|f| car_box(-1.75, 2.0, f)).collect();
    let off = |f: u32| (19..=21).contains(&f);
    let seen: Vec<BBox> = truth
        .iter()
        .zip(1..)
        .map(|(b, f)| {
            if off(f) {
                BBox::from_centre(
                    Point::new(b.centre().x + 5.0, b.centre().y),
                    b.width,
                    b.height,
                )
            } else {
                *b
            }
        })
        .collect();
    let points: Vec<TrackPoint> = (1..=n)
        .map(|f| point(f, 1, ObjectClass::Car, truth[f as usize - 1]))
        .collect();
    let error = |config: VehicleBoxConfig| -> Result<f64> {
        let (out, _) = run(config, &points, n, |f| vec![seen[f as usize - 1]])?;
        let got = boxes(&out, 1);
        Ok((19..=21)
            .map(|f: usize| got[f - 1].centre().distance(truth[f - 1].centre()))
            .fold(0.0, f64::max))
    };
    // The gate at 0.5, which these detections pass (IoU about 0.6), so that the outlier
    // test alone decides.
    let gate = VehicleBoxConfig {
        min_iou: 0.5,
        ..VehicleBoxConfig::default()
    };
    let with = error(gate.clone())?;
    let without = error(VehicleBoxConfig {
        outlier_sigmas: 1e9,
        ..gate
    })?;
    // Measured: 0.00004 px with the test, 0.85 px without.
    assert!(with < 0.05 && without > 0.5, "{with} px, {without} px");
    Ok(())
}

/// Walkers, a car that never moves, a car at the frame's edge, a car the detector barely
/// saw and an unknown object are left as they were; a run without detections measures the
/// tracks' own boxes.
#[test]
fn what_the_model_cannot_box_is_left_alone() -> Result<()> {
    let n = 30;
    let moving = |id: u64, class: ObjectClass, lane: f64, y0: f64| -> Vec<TrackPoint> {
        (1..=n)
            .map(|f| point(f, id, class.clone(), jittered(car_box(lane, y0, f), f)))
            .collect()
    };
    let walker = moving(1, ObjectClass::Pedestrian, 1.75, 10.0);
    let unknown = moving(2, ObjectClass::Unknown, 1.75, 10.0);
    let parked: Vec<TrackPoint> = (1..=n)
        .map(|f| point(f, 3, ObjectClass::Car, jittered(car_box(-4.0, 15.0, 1), f)))
        .collect();
    let edge: Vec<TrackPoint> = (1..=n)
        .map(|f| {
            let b = BBox {
                left: 0.0,
                top: 300.0,
                width: 60.0 + f64::from(f),
                height: 40.0,
            };
            point(f, 4, ObjectClass::Car, b)
        })
        .collect();
    let glimpsed = moving(5, ObjectClass::Truck, -1.75, 40.0);
    let all: Vec<TrackPoint> = [
        walker.clone(),
        unknown.clone(),
        parked.clone(),
        edge.clone(),
        glimpsed.clone(),
    ]
    .concat();
    // The detector saw every object but the lorry, which it saw twice.
    let dets = |f: u32| -> Vec<BBox> {
        all.iter()
            .filter(|p| p.frame == f && (p.id != 5 || f <= 2))
            .map(|p| p.bbox)
            .collect()
    };
    let (out, changed) = run(VehicleBoxConfig::default(), &all, n, dets)?;
    assert_eq!(changed, 0);
    for (id, before) in [
        (1, &walker),
        (2, &unknown),
        (3, &parked),
        (4, &edge),
        (5, &glimpsed),
    ] {
        let want: Vec<BBox> = before.iter().map(|p| p.bbox).collect();
        assert_eq!(boxes(&out, id), want, "track {id}");
    }
    // Without detections the moving car's own boxes are measured, and it is redrawn.
    let car = moving(6, ObjectClass::Car, 1.75, 10.0);
    let (out, changed) = run(VehicleBoxConfig::default(), &car, n, |_| Vec::new())?;
    assert_eq!(changed, n as usize);
    let truth: Vec<BBox> = (1..=n).map(|f| car_box(1.75, 10.0, f)).collect();
    let before: Vec<BBox> = car.iter().map(|p| p.bbox).collect();
    assert!(mean_iou(&boxes(&out, 6), &truth) > mean_iou(&before, &truth) + 0.05);
    Ok(())
}

/// Bad fields are refused, naming them; a view with no perspective has no camera.
#[test]
fn bad_settings_are_refused_naming_the_field() {
    for (cfg, field) in [
        (
            VehicleBoxConfig {
                truck_m: [9.0, -2.0, 3.0],
                ..Default::default()
            },
            "truck_m",
        ),
        (
            VehicleBoxConfig {
                accel_noise: vec![0.01, 0.0],
                ..Default::default()
            },
            "accel_noise",
        ),
        (
            VehicleBoxConfig {
                min_iou: 1.5,
                ..Default::default()
            },
            "min_iou",
        ),
        (
            VehicleBoxConfig {
                passes: 1000,
                ..Default::default()
            },
            "passes",
        ),
    ] {
        let e = VehicleBoxStage::new(cfg, &calibration(), 640, 480).unwrap_err();
        assert!(e.to_string().contains(field), "{e}");
    }
    let nadir = Calibration::from_homography([[4.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 1.0]])
        .expect("a valid homography");
    assert!(VehicleBoxStage::new(VehicleBoxConfig::default(), &nadir, 640, 480).is_err());
}
