//! Whole-simulator tests: determinism, truth consistency, file formats, external
//! trajectories, pairs.

use super::*;
use roadtrack_core::error::Error;
use std::path::Path;

fn small(scene: SceneKind, view: ViewKind, frames: u32) -> SimConfig {
    SimConfig {
        scene,
        view,
        frames,
        width: 320,
        height: 240,
        oblique: ObliqueConfig {
            focal_px: Some(256.0),
            ..ObliqueConfig::default()
        },
        ..SimConfig::default()
    }
}

fn tmp() -> Result<tempfile::TempDir> {
    tempfile::tempdir().map_err(|e| Error::io("tempdir", e))
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("readable").flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p
                    .strip_prefix(dir)
                    .expect("inside")
                    .to_string_lossy()
                    .into_owned();
                out.push((rel, std::fs::read(&p).expect("readable")));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn same_seed_gives_byte_identical_folders_and_another_seed_does_not() -> Result<()> {
    let cfg = SimConfig {
        render: SimRenderConfig {
            camera_jitter_px: 1.0,
            ..SimRenderConfig::default()
        },
        ..small(SceneKind::Crossing, ViewKind::Oblique, 4)
    };
    // Same folder name in three places (seqinfo.ini records the name).
    let (a, b, c) = (tmp()?, tmp()?, tmp()?);
    let (a, b, c) = (
        a.path().join("seq"),
        b.path().join("seq"),
        c.path().join("seq"),
    );
    simulate(&cfg, 11, &a, &mut |_, _| {})?;
    simulate(&cfg, 11, &b, &mut |_, _| {})?;
    simulate(&cfg, 12, &c, &mut |_, _| {})?;
    let (fa, fb, fc) = (files(&a), files(&b), files(&c));
    let names: Vec<&str> = fa.iter().map(|f| f.0.as_str()).collect();
    for want in [
        "img1/000001.jpg",
        "img1/000004.jpg",
        "seqinfo.ini",
        "gt/gt.txt",
        "det/det.txt",
        "det/detections.csv",
        "truth.csv",
        "calibration.toml",
        "simulation.toml",
    ] {
        assert!(names.contains(&want), "{want} missing from {names:?}");
    }
    let differ: Vec<&str> = fa
        .iter()
        .zip(&fb)
        .filter(|(x, y)| x != y)
        .map(|(x, _)| x.0.as_str())
        .collect();
    assert!(
        fa.len() == fb.len() && differ.is_empty(),
        "same seed, different bytes: {differ:?}"
    );
    let truth =
        |f: &[(String, Vec<u8>)]| f.iter().find(|x| x.0 == "truth.csv").map(|x| x.1.clone());
    assert_ne!(truth(&fa), truth(&fc));
    // The in-memory run is the same simulation.
    let run = simulate_in_memory(&cfg, 11)?;
    let dir = tmp()?;
    write_truth_csv(&dir.path().join("t.csv"), &run.truth)?;
    assert_eq!(std::fs::read(dir.path().join("t.csv")).ok(), truth(&fa));
    Ok(())
}

#[test]
fn ground_truth_is_a_sequence_trackeval_accepts() -> Result<()> {
    let cfg = small(SceneKind::Intersection, ViewKind::Oblique, 6);
    let dir = tmp()?;
    let summary = simulate(&cfg, 3, dir.path(), &mut |_, _| {})?;
    assert!(summary.objects > 3, "{summary:?}");
    let text =
        std::fs::read_to_string(dir.path().join("gt/gt.txt")).map_err(|e| Error::io("gt", e))?;
    let mut seen = std::collections::HashSet::new();
    for line in text.lines() {
        let f: Vec<f64> = line
            .split(',')
            .map(|x| x.parse().expect("number"))
            .collect();
        assert_eq!(f.len(), 9, "{line}");
        assert!((1.0..=6.0).contains(&f[0]) && f[0].fract() == 0.0, "{line}");
        assert!(f[4] > 0.0 && f[5] > 0.0, "{line}");
        assert_eq!(f[6], 1.0);
        assert!(
            (1.0..=12.0).contains(&f[7]) && f[7].fract() == 0.0,
            "{line}"
        );
        assert!((0.0..=1.0).contains(&f[8]), "{line}");
        assert!(seen.insert((f[0] as u32, f[1] as u64)), "duplicate {line}");
    }
    let gt = roadtrack_core::io::mot::read_gt(&dir.path().join("gt/gt.txt"))?;
    assert_eq!(gt.len(), summary.truth_rows);
    let info = roadtrack_core::io::seqinfo::SeqInfo::read(&dir.path().join("seqinfo.ini"))?;
    assert_eq!(
        (info.seq_length, info.im_width, info.im_height),
        (6, 320, 240)
    );
    assert_eq!(info.im_ext, ".jpg");
    let dets =
        roadtrack_core::io::detections::read_detections(&dir.path().join("det/detections.csv"))?;
    assert_eq!(dets.len(), summary.detections);
    assert!(dets.iter().all(|d| d.colour_rgb.is_some()));
    let cal = Calibration::load(&dir.path().join("calibration.toml"))?;
    assert!(cal.metres_per_pixel().is_none());
    Ok(())
}

#[test]
fn boxes_agree_with_truth_projected_through_the_calibration() -> Result<()> {
    for (scene, view) in [
        (SceneKind::Road, ViewKind::Aerial),
        (SceneKind::Intersection, ViewKind::Aerial),
        (SceneKind::Crossing, ViewKind::Oblique),
        (SceneKind::Intersection, ViewKind::Oblique),
    ] {
        let cfg = small(scene, view, 3);
        let run = simulate_in_memory(&cfg, 5)?;
        let cal = &run.calibration;
        let mut checked = 0;
        for t in &run.truth {
            let p = cal
                .image_from_ground(t.x_m, t.y_m)
                .ok_or(Error::Invalid("behind the camera".into()))?;
            assert!(
                (p.x - t.x_px).abs() < 1e-6 && (p.y - t.y_px).abs() < 1e-6,
                "{t:?}"
            );
            let (x, y) = cal
                .ground_from_image(Point::new(t.x_px, t.y_px))
                .ok_or(Error::Invalid("above the horizon".into()))?;
            assert!((x - t.x_m).abs() < 1e-6 && (y - t.y_m).abs() < 1e-6);
            let b = t.bbox;
            let inside = b.left > 0.5 && b.top > 0.5 && b.right() < 319.5 && b.bottom() < 239.5;
            if !inside {
                continue;
            }
            checked += 1;
            if view == ViewKind::Aerial {
                // Nadir: the box is centred on the footprint centre and as wide as the
                // rotated footprint.
                let c = b.centre();
                assert!(
                    (c.x - t.x_px).abs() < 1e-6 && (c.y - t.y_px).abs() < 1e-6,
                    "{t:?}"
                );
                let k = cal.metres_per_pixel().unwrap_or(1.0);
                let (s, co) = t.heading_deg.to_radians().sin_cos();
                let w = (t.length_m * co.abs() + t.width_m * s.abs()) / k;
                assert!((b.width - w).abs() < 1e-6, "{} vs {w}", b.width);
            } else {
                // Perspective: the ground point lies inside the box, in its lower part.
                assert!(b.left <= t.x_px && t.x_px <= b.right(), "{t:?}");
                assert!(
                    b.top + 0.3 * b.height <= t.y_px && t.y_px <= b.bottom(),
                    "{t:?}"
                );
            }
        }
        assert!(
            checked > 2,
            "{scene:?}/{view:?}: only {checked} boxes checked"
        );
    }
    Ok(())
}

#[test]
fn crowded_crossing_has_partly_occluded_people() -> Result<()> {
    let cfg = small(SceneKind::Crossing, ViewKind::Oblique, 60);
    let run = simulate_in_memory(&cfg, 1)?;
    let people: Vec<&TruthRow> = run
        .truth
        .iter()
        .filter(|t| t.class == ObjectClass::Pedestrian)
        .collect();
    assert!(people.len() > 10, "{}", people.len());
    let vis: Vec<f64> = people.iter().map(|t| t.visibility).collect();
    let hidden = vis.iter().filter(|&&v| v < 0.7).count();
    assert!(
        hidden * 10 > vis.len(),
        "only {hidden} of {} pedestrian rows are < 70 % visible",
        vis.len()
    );
    assert!(
        run.truth
            .iter()
            .all(|t| (0.0..=1.0).contains(&t.visibility))
    );
    // In the nadir view nothing is ever hidden (objects never overlap on the ground,
    // except pedestrians, who may brush).
    let cfg = small(SceneKind::Road, ViewKind::Aerial, 3);
    let run = simulate_in_memory(&cfg, 1)?;
    assert!(run.truth.iter().all(|t| t.visibility == 1.0));
    Ok(())
}

#[test]
fn objects_cut_by_the_frame_edge_are_partly_visible_in_gt() -> Result<()> {
    // Vehicles drive in and out of an oblique intersection view: rows whose box touches
    // the image border are cut, rows well inside are whole; gt.txt's visibility is
    // truth's times the share inside the frame (MOT17's: border cropping hides).
    let cfg = small(SceneKind::Intersection, ViewKind::Oblique, 60);
    let run = simulate_in_memory(&cfg, 2)?;
    let (w, h) = (f64::from(cfg.width), f64::from(cfg.height));
    let gt = gt_rows(&run.truth);
    let (mut cut, mut whole) = (0, 0);
    for (t, g) in run.truth.iter().zip(&gt) {
        assert!((0.0..=1.0).contains(&t.in_frame), "{t:?}");
        assert_eq!(g.visibility, t.visibility * t.in_frame);
        let b = t.bbox;
        let margin = b
            .left
            .min(b.top)
            .min(w - b.left - b.width)
            .min(h - b.top - b.height);
        if margin > 1.0 {
            // The outline's hull can reach a little past the box only through rounding.
            assert!(t.in_frame > 1.0 - 1e-9, "whole, yet {t:?}");
            whole += 1;
        } else if margin < 1e-6 && t.in_frame < 1.0 {
            cut += 1;
        }
    }
    assert!(whole > 20 && cut > 5, "whole {whole}, cut {cut}");
    Ok(())
}

#[test]
fn from_trajectories_reproduces_the_committed_positions() -> Result<()> {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/sim_trajectories.csv"
    ));
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    for view in [ViewKind::Aerial, ViewKind::Oblique] {
        let cfg = small(SceneKind::Crossing, view, 1);
        let traj = ExternalTrajectories::read(path)?;
        let sim = Simulation::from_trajectories(&cfg, 0, traj, None)?;
        assert_eq!(sim.n_frames(), 41);
        let mut truth = Vec::new();
        for step in sim {
            truth.extend(step?.truth);
        }
        let mut n = 0;
        for line in text.lines().skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            let t: f64 = f[0].parse().expect("time");
            let id: u64 = f[1].parse().expect("id");
            let frame = (t * 10.0).round() as u32 + 1;
            let Some(row) = truth.iter().find(|r| r.frame == frame && r.id == id) else {
                continue;
            };
            n += 1;
            assert_eq!(row.x_m, f[3].parse::<f64>().expect("x"), "{line}");
            assert_eq!(row.y_m, f[4].parse::<f64>().expect("y"), "{line}");
            assert!(
                (row.heading_deg - f[5].parse::<f64>().expect("h")).abs() < 1e-9,
                "{line}"
            );
            assert_eq!(row.class, ObjectClass::from(f[2].to_owned()));
            if !f[8].is_empty() {
                let rgb: Vec<u8> = f[8..11].iter().map(|v| v.parse().expect("rgb")).collect();
                assert_eq!(row.colour_rgb.to_vec(), rgb);
            }
        }
        assert!(n >= 25, "{view:?}: only {n} samples were in view");
        if view == ViewKind::Oblique {
            continue;
        }
        // Between samples the motion is linear: the car at t = 0.3 s is at −27 m.
        let car = truth
            .iter()
            .find(|r| r.id == 1 && r.frame == 4)
            .ok_or(Error::Invalid("car".into()))?;
        assert!(
            (car.x_m - (-27.0)).abs() < 1e-9 && (car.speed_mps - 10.0).abs() < 1e-9,
            "{car:?}"
        );
    }
    Ok(())
}

#[test]
fn pairs_are_whole_road_problems_with_consistent_truth() -> Result<()> {
    let cfg = SimConfig::default();
    let pairs = PairsConfig {
        n_pairs: 2,
        drop_fraction: 0.1,
        warmup_s: 60.0,
        ..PairsConfig::default()
    };
    let dir = tmp()?;
    let summary = write_pairs(&cfg, &pairs, 4, dir.path(), &mut |_, _| {})?;
    assert!(summary.mean_vehicles_frame1 > 20.0, "{summary:?}");
    for p in ["pair_0001", "pair_0002"] {
        let d = dir.path().join(p);
        let f1 = roadtrack_core::io::detections::read_detections(&d.join("frame1.csv"))?;
        let f2 = roadtrack_core::io::detections::read_detections(&d.join("frame2.csv"))?;
        let truth = roadtrack_core::io::matches::read_matches(&d.join("truth.csv"))?;
        let xmax = f1.iter().map(|d| d.pos_px.x).fold(0.0, f64::max);
        assert!(xmax > 1500.0 && xmax <= 700.0 / 0.33 + 1e-6, "{xmax}");
        let by_id2: std::collections::HashMap<u64, &Detection> =
            f2.iter().map(|d| (d.id, d)).collect();
        let mut matched = 0;
        for row in &truth {
            if let (Some(i1), Some(i2)) = (row.id1, row.id2) {
                let a = f1
                    .iter()
                    .find(|d| d.id == i1)
                    .ok_or(Error::Invalid("id1".into()))?;
                let b = by_id2.get(&i2).ok_or(Error::Invalid("id2".into()))?;
                // Forward along the road by at most 1.5 s × 25 m/s, in a lane.
                let dx = b.pos_px.x - a.pos_px.x;
                assert!((0.0..=1.5 * 25.0 / 0.33).contains(&dx), "{dx}");
                assert!((b.pos_px.y - a.pos_px.y).abs() < 3.6 / 0.33);
                assert_eq!(a.class, b.class);
                matched += 1;
            }
        }
        assert!(matched > 15);
        assert_eq!(truth.iter().filter(|r| r.id1.is_some()).count(), f1.len());
    }
    Ok(())
}
