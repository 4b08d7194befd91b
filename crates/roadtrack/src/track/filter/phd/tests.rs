//! Tests of the labelled SMC-PHD filter: the label rules, the update and resampling steps,
//! and the tracker on synthetic scenes.

use super::super::SurveillanceRegion;
use super::super::motion::ConstantVelocity;
use super::super::resample::ResamplingScheme;
use super::*;
use crate::error::Error;
use crate::frame::Frame;
use crate::geometry::BBox;
use crate::likelihood::{ColourLikelihood, ColourLikelihoodConfig};
use crate::track_point::TrackPoint;

#[test]
fn defaults_are_the_papers() {
    // Table 9 of seed 004 (METHODS.md §3 "Paper parameters").
    let c = PhdConfig::default();
    assert_eq!(c.particles_per_object, 70);
    assert_eq!((c.survival_prob, c.detection_prob), (0.9, 0.88));
    assert_eq!(c.motion, ConstantVelocity::proportional(0.3, 1.0));
    assert_eq!((c.birth_rate, c.birth_grid_points), (2.0, 140));
    assert_eq!(c.likelihood_threshold, 0.05);
    assert_eq!((c.border_margin, c.exit_speed), (4.0, 5.0));
    assert_eq!(c.split_distance, 50.0);
    assert_eq!(c.mesh_likelihood_threshold, 0.08);
    assert_eq!(c.merge_distance, 40.0);
    assert_eq!(c.resampling, ResamplingScheme::Stratified);
    assert!(c.validate().is_ok());
}

#[test]
fn committed_config_file_equals_the_defaults() -> Result<()> {
    let path = std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../configs/phd.toml"
    ));
    assert_eq!(PhdConfig::from_toml_file(path)?, PhdConfig::default());
    Ok(())
}

fn filter() -> Result<LabelledPhd> {
    LabelledPhd::new(
        PhdConfig::default(),
        SurveillanceRegion::new(0.0, 0.0, 640.0, 480.0),
        1,
    )
}

/// Adds `n` particles of `label` in a small cross around `c`, all with `h`.
fn blob(f: &mut LabelledPhd, c: Point, v: Point, n: usize, label: u32, h: f64, w: f64) {
    for k in 0..n {
        let d = (k % 5) as f64 - 2.0;
        let pos = if k % 2 == 0 {
            Point::new(c.x + d, c.y)
        } else {
            Point::new(c.x, c.y + d)
        };
        f.particles.push(pos, v, w, label);
        let last = f.particles.len() - 1;
        f.particles.h[last] = h;
    }
    f.next_label = f.next_label.max(label + 1);
}

fn labels(f: &LabelledPhd) -> Vec<u32> {
    let mut l = f.particles.label.clone();
    l.sort_unstable();
    l.dedup();
    l
}

#[test]
fn a_label_with_two_distant_clusters_splits() -> Result<()> {
    let mut f = filter()?;
    blob(
        &mut f,
        Point::new(100.0, 100.0),
        Point::default(),
        40,
        1,
        0.9,
        0.02,
    );
    blob(
        &mut f,
        Point::new(200.0, 100.0),
        Point::default(),
        20,
        1,
        0.9,
        0.02,
    );
    f.update_labels();
    assert_eq!(labels(&f), vec![1, 2]);
    // The heavier (first) cluster keeps label 1.
    assert!(f.particles.label[..40].iter().all(|&l| l == 1));
    assert!(f.particles.label[40..].iter().all(|&l| l == 2));
    // Clusters closer than α_spawned stay one label.
    let mut g = filter()?;
    blob(
        &mut g,
        Point::new(100.0, 100.0),
        Point::default(),
        30,
        1,
        0.9,
        0.02,
    );
    blob(
        &mut g,
        Point::new(130.0, 100.0),
        Point::default(),
        30,
        1,
        0.9,
        0.02,
    );
    g.update_labels();
    assert_eq!(labels(&g), vec![1]);
    Ok(())
}

#[test]
fn labels_closer_than_beta_center_merge_into_the_oldest() -> Result<()> {
    let mut f = filter()?;
    blob(
        &mut f,
        Point::new(100.0, 100.0),
        Point::default(),
        30,
        3,
        0.9,
        0.03,
    );
    blob(
        &mut f,
        Point::new(125.0, 100.0),
        Point::default(),
        30,
        5,
        0.9,
        0.03,
    );
    blob(
        &mut f,
        Point::new(400.0, 300.0),
        Point::default(),
        30,
        7,
        0.9,
        0.03,
    );
    let before = f.expected_count();
    f.update_labels();
    assert_eq!(labels(&f), vec![3, 7]);
    assert_eq!(
        f.expected_count(),
        before,
        "merging must not change weights"
    );
    Ok(())
}

#[test]
fn unlikely_particles_lose_their_label_and_exiting_labels_end() -> Result<()> {
    let mut f = filter()?;
    blob(
        &mut f,
        Point::new(100.0, 100.0),
        Point::default(),
        10,
        1,
        0.01,
        0.1,
    );
    // Near the left border, moving left at 8 px/frame > α_speed = 5.
    blob(
        &mut f,
        Point::new(3.0, 200.0),
        Point::new(-8.0, 0.0),
        10,
        2,
        0.9,
        0.1,
    );
    // Near the border but moving inward: stays.
    blob(
        &mut f,
        Point::new(3.0, 400.0),
        Point::new(8.0, 0.0),
        10,
        3,
        0.9,
        0.1,
    );
    f.rule_likelihood();
    f.rule_border_exit();
    assert!(f.particles.label[..10].iter().all(|&l| l == 0));
    assert!(f.particles.label[10..20].iter().all(|&l| l == 0));
    assert!(f.particles.label[20..].iter().all(|&l| l == 3));
    Ok(())
}

#[test]
fn mesh_cells_with_likely_unlabelled_particles_get_a_new_label() -> Result<()> {
    let mut f = filter()?;
    blob(
        &mut f,
        Point::new(100.0, 100.0),
        Point::default(),
        10,
        0,
        0.5,
        0.01,
    );
    blob(
        &mut f,
        Point::new(300.0, 300.0),
        Point::default(),
        10,
        0,
        0.01,
        0.01,
    );
    f.rule_mesh_birth();
    assert!(f.particles.label[..10].iter().all(|&l| l == 1));
    assert!(f.particles.label[10..].iter().all(|&l| l == 0));
    Ok(())
}

#[test]
fn image_update_follows_eqs_11_to_13_per_label() -> Result<()> {
    let mut f = filter()?;
    blob(
        &mut f,
        Point::new(100.0, 100.0),
        Point::default(),
        10,
        1,
        0.8,
        0.09,
    );
    blob(
        &mut f,
        Point::new(300.0, 100.0),
        Point::default(),
        10,
        2,
        0.0,
        0.05,
    );
    f.update_image();
    let (pd, kappa) = (0.88, 0.1);
    let c1 = 10.0 * 0.09 * 0.8;
    let w1: f64 = f.particles.w[..10].iter().sum();
    let expected1 = (1.0 - pd) * 0.9 + pd * c1 / (kappa + c1);
    assert!((w1 - expected1).abs() < 1e-12, "{w1} vs {expected1}");
    let w2: f64 = f.particles.w[10..].iter().sum();
    assert!(
        (w2 - (1.0 - pd) * 0.5).abs() < 1e-12,
        "undetected label keeps (1 − p_D)·W"
    );
    Ok(())
}

#[test]
fn point_update_gives_one_unit_per_measurement_without_clutter() -> Result<()> {
    // Vo et al.: Σ ŵ = (1 − p_D)·W + Σ_j C_j/(κ + C_j) → ≈ (1 − p_D) + 1 when κ ≪ C.
    let mut f = filter()?;
    blob(
        &mut f,
        Point::new(100.0, 100.0),
        Point::default(),
        50,
        1,
        0.0,
        0.02,
    );
    f.update_points(&[Point::new(100.5, 100.0)], 2.0, 1e-9);
    let w = f.expected_count();
    assert!((w - (0.12 + 1.0)).abs() < 1e-6, "{w}");
    Ok(())
}

fn bernoulli_filter(region: SurveillanceRegion) -> Result<LabelledPhd> {
    LabelledPhd::new(
        PhdConfig {
            label_update: LabelUpdate::Bernoulli,
            ..PhdConfig::default()
        },
        region,
        1,
    )
}

#[test]
fn bernoulli_labels_keep_their_existence_through_a_missed_detection() -> Result<()> {
    // Points, p_D = 0.88: a label of predicted weight r = 0.9 whose target is not
    // measured keeps r(1 − p_D)/(1 − r·p_D) = 0.4821 (the PHD form: (1 − p_D)·r = 0.108);
    // a measured one goes to ≈ 1 and never above; unlabelled particles keep the PHD update.
    let region = SurveillanceRegion::new(0.0, 0.0, 640.0, 480.0);
    let mut f = bernoulli_filter(region)?;
    let c = Point::new(100.0, 100.0);
    blob(&mut f, c, Point::default(), 50, 1, 0.0, 0.9 / 50.0);
    blob(
        &mut f,
        Point::new(400.0, 100.0),
        Point::default(),
        50,
        2,
        0.0,
        0.9 / 50.0,
    );
    blob(
        &mut f,
        Point::new(100.5, 100.0),
        Point::default(),
        10,
        0,
        0.0,
        1e-4,
    );
    f.particles.label[100..].iter_mut().for_each(|l| *l = 0);
    let kappa_rate = 1.0;
    f.update_points(&[Point::new(100.5, 100.0)], 2.0, kappa_rate);
    let sum = |l: u32| -> f64 {
        (0..f.particles.len())
            .filter(|&i| f.particles.label[i] == l)
            .map(|i| f.particles.w[i])
            .sum()
    };
    let (r, pd) = (0.9, 0.88);
    let missed = r * (1.0 - pd) / (1.0 - r * pd);
    assert!((sum(2) - missed).abs() < 1e-9, "{} vs {missed}", sum(2));
    assert!(sum(1) > 0.99 && sum(1) <= 1.0, "{}", sum(1));
    // The births share the measurement with label 1 as in the PHD: κ + C(z) over all.
    assert!(sum(0) < 2e-3, "{}", sum(0));
    Ok(())
}

#[test]
fn bernoulli_image_update_weighs_the_label_likelihood_against_kappa() -> Result<()> {
    let mut f = bernoulli_filter(SurveillanceRegion::new(0.0, 0.0, 640.0, 480.0))?;
    blob(
        &mut f,
        Point::new(100.0, 100.0),
        Point::default(),
        10,
        1,
        0.3,
        0.09,
    );
    blob(
        &mut f,
        Point::new(300.0, 100.0),
        Point::default(),
        10,
        2,
        0.015,
        0.09,
    );
    f.update_image();
    let (pd, kappa, r) = (0.88, 0.1, 0.9);
    let expect = |h: f64| {
        let ratio = (1.0 - pd) + pd * h / kappa;
        r * ratio / (1.0 - r + r * ratio)
    };
    let w1: f64 = f.particles.w[..10].iter().sum();
    let w2: f64 = f.particles.w[10..].iter().sum();
    assert!((w1 - expect(0.3)).abs() < 1e-12, "{w1}");
    assert!((w2 - expect(0.015)).abs() < 1e-12, "{w2}");
    // h̄ = 0.3 > κ: the object's label stays near 1 (the paper's form: 0.75); h̄ = 0.015
    // (background, h̄ < κ): it loses weight at every frame.
    assert!(w1 > 0.95 && w2 < 0.7, "{w1} {w2}");
    Ok(())
}

#[test]
fn per_label_resampling_keeps_every_weight_and_gives_each_label_rho() -> Result<()> {
    let mut f = filter()?;
    blob(
        &mut f,
        Point::new(100.0, 100.0),
        Point::default(),
        33,
        1,
        0.9,
        1.7 / 33.0,
    );
    blob(
        &mut f,
        Point::new(300.0, 100.0),
        Point::default(),
        5,
        2,
        0.9,
        0.004 / 5.0,
    );
    blob(
        &mut f,
        Point::new(500.0, 100.0),
        Point::default(),
        5,
        3,
        0.9,
        1e-6,
    );
    f.resample();
    let of = |l: u32| -> (usize, f64) {
        let idx: Vec<usize> = (0..f.particles.len())
            .filter(|&i| f.particles.label[i] == l)
            .collect();
        (idx.len(), idx.iter().map(|&i| f.particles.w[i]).sum())
    };
    assert_eq!(of(1).0, 119); // ⌈70·1.7⌉
    assert!((of(1).1 - 1.7).abs() < 1e-12);
    assert_eq!(of(2).0, 70);
    assert!((of(2).1 - 0.004).abs() < 1e-12);
    assert_eq!(of(3).0, 0, "label below prune_weight is dropped");
    Ok(())
}

/// Coloured squares moving over a checkerboard.
fn squares(n_frames: u32) -> (Vec<Frame>, Vec<Point>) {
    let cfg = roadtrack_sim::testkit::SquareSceneConfig {
        width: 320,
        height: 240,
        targets: 3,
        frames: n_frames,
        ..Default::default()
    };
    let (frames, dets) = roadtrack_sim::testkit::square_scene(&cfg);
    (frames, dets.iter().map(|d| d.pos_px).collect())
}

/// A colour likelihood whose window matches the 24 px squares and that stays above
/// α_mesh a few px off centre (a broad score, like the paper's classifier).
fn matched_colour() -> ColourLikelihoodConfig {
    ColourLikelihoodConfig {
        window: crate::likelihood::Window::new(24, 24, crate::likelihood::BorderPolicy::Clamp),
        sharpness: 5.0,
        ..Default::default()
    }
}

/// The 15-frame squares scene and a PHD tracker with `config` started from one detection
/// per square in frame 1.
fn squares_started_from_detections(config: PhdConfig) -> Result<(Vec<Frame>, PhdTracker)> {
    let (frames, starts) = squares(15);
    let boxes: Vec<BBox> = starts
        .iter()
        .map(|&p| BBox::from_centre(p, 20.0, 20.0))
        .collect();
    let lik = ColourLikelihood::from_boxes(matched_colour(), &frames[0].image, &boxes)?;
    let mut t = PhdTracker::new(config, Box::new(lik), 3)?;
    let dets: Vec<crate::detection::Detection> = starts
        .iter()
        .enumerate()
        .map(|(k, &p)| crate::detection::Detection::at(1, k as u64 + 1, p))
        .collect();
    t.start_from_detections(&dets);
    Ok((frames, t))
}

#[test]
fn phd_weight_sum_tracks_the_object_count_from_detections() -> Result<()> {
    let (frames, mut t) = squares_started_from_detections(PhdConfig::default())?;
    for f in &frames {
        let out = t.step(f)?;
        // With C(y) per label and no p_D in it (eq. 13), a detected object's weight W
        // settles where W = (1 − p_D)·p_s·W + p_D·C/(κ + C), C = p_s·W·h̄: at most 0.88
        // with the paper's values (h̄ = 1), lower when a label's mean likelihood h̄ < 1.
        let n = t.expected_count();
        assert!(
            (2.1..=3.3).contains(&n),
            "frame {}: expected count {n:.2}",
            f.index
        );
        let ids: Vec<u64> = out.iter().map(|p| p.id).collect();
        assert_eq!(ids, vec![1, 2, 3], "frame {}", f.index);
    }
    Ok(())
}

#[test]
fn bernoulli_labels_hold_one_object_each_from_detections() -> Result<()> {
    // The scene of the test above with LabelUpdate::Bernoulli: each tracked object's label
    // settles near 1 instead of (1 − p_D)·p_s·W + p_D·C/(κ + C). (Reported scores are the
    // label weights capped at 1.)
    let cfg = PhdConfig {
        label_update: LabelUpdate::Bernoulli,
        ..PhdConfig::default()
    };
    let (frames, mut t) = squares_started_from_detections(cfg)?;
    for f in &frames {
        let out = t.step(f)?;
        let ids: Vec<u64> = out.iter().map(|p| p.id).collect();
        assert_eq!(ids, vec![1, 2, 3], "frame {}", f.index);
        // (The paper's form above: at most 0.88 per label.) The rest of Σw is unlabelled grid
        // birth mass, PHD-updated as before (≈ 0.4 here).
        let w: Vec<f64> = out.iter().map(|p| p.score).collect();
        assert!(w.iter().all(|&w| w > 0.9), "frame {}: {w:?}", f.index);
        let n = t.expected_count();
        assert!((3.0..=3.6).contains(&n), "frame {}: Σw {n:.2}", f.index);
    }
    Ok(())
}

#[test]
fn phd_tracker_finds_objects_from_grid_births_alone() -> Result<()> {
    let (frames, starts) = squares(20);
    let boxes: Vec<BBox> = starts
        .iter()
        .map(|&p| BBox::from_centre(p, 20.0, 20.0))
        .collect();
    let lik = ColourLikelihood::from_boxes(matched_colour(), &frames[0].image, &boxes)?;
    let mut t = PhdTracker::new(PhdConfig::default(), Box::new(lik), 3)?;
    let mut counts = Vec::new();
    for f in &frames {
        t.step(f)?;
        counts.push(t.expected_count());
    }
    // Births on the 140-point grid (spacing ≈ 23 px here) reach each 24 px object only
    // when a grid point falls near it; bar: at least two of the three within 20 frames
    // and never a phantom object.
    let last = counts[counts.len() - 1];
    assert!(last > 1.6 && counts.iter().all(|&c| c < 3.6), "{counts:?}");
    Ok(())
}

#[test]
fn phd_tracker_is_deterministic_at_any_thread_count() -> Result<()> {
    let (frames, starts) = squares(6);
    let boxes: Vec<BBox> = starts
        .iter()
        .map(|&p| BBox::from_centre(p, 20.0, 20.0))
        .collect();
    let lik =
        ColourLikelihood::from_boxes(ColourLikelihoodConfig::default(), &frames[0].image, &boxes)?;
    let run = |threads: usize| -> Result<Vec<TrackPoint>> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| Error::Invalid(e.to_string()))?;
        pool.install(|| {
            let mut t = PhdTracker::new(PhdConfig::default(), Box::new(lik.clone()), 5)?;
            let mut out = Vec::new();
            for f in &frames {
                out.extend(t.step(f)?);
            }
            Ok(out)
        })
    };
    assert_eq!(run(1)?, run(4)?);
    Ok(())
}

#[test]
fn kmeans_separates_two_groups() {
    let pts: Vec<Point> = (0..10)
        .map(|i| {
            if i < 5 {
                Point::new(i as f64, 0.0)
            } else {
                Point::new(100.0 + i as f64, 0.0)
            }
        })
        .collect();
    let a = kmeans(&pts, &[1.0; 10], 2);
    assert!(a[..5].iter().all(|&x| x == a[0]) && a[5..].iter().all(|&x| x == a[5]) && a[0] != a[5]);
}

#[test]
fn one_steps_births_never_exceed_max_particles() -> Result<()> {
    let cfg = PhdConfig {
        max_particles: 1_000,
        ..PhdConfig::default()
    };
    let region = SurveillanceRegion::new(0.0, 0.0, 500.0, 500.0);
    let points: Vec<crate::geometry::Point> = (0..50)
        .map(|i| crate::geometry::Point::new(10.0 * f64::from(i), 250.0))
        .collect();
    // 50 points × 70 000 particles asked for: 1 000 at most, 20 per point.
    let mut f = LabelledPhd::new(cfg.clone(), region, 1)?;
    f.add_births_at(&points, 70_000, 4.0);
    assert_eq!(f.particles().len(), 1_000);
    let mut f = LabelledPhd::new(cfg.clone(), region, 1)?;
    f.add_measurement_births(&points, 70_000, 4.0, 0.0);
    assert!(f.particles().len() <= 1_000, "{}", f.particles().len());
    // Below the cap the count asked for is the count drawn.
    let mut f = LabelledPhd::new(cfg, region, 1)?;
    f.add_births_at(&points[..2], 70, 4.0);
    assert_eq!(f.particles().len(), 140);
    Ok(())
}

#[test]
fn particle_counts_above_the_limits_are_refused() {
    for (cfg, field) in [
        (
            PhdConfig {
                particles_per_object: 200_000,
                max_particles: 400_000,
                ..PhdConfig::default()
            },
            "particles_per_object",
        ),
        (
            PhdConfig {
                max_particles: 100_000_000,
                ..PhdConfig::default()
            },
            "max_particles",
        ),
    ] {
        let e = cfg.validate().expect_err(field).to_string();
        assert!(e.contains(field) && e.contains("exceeds the limit"), "{e}");
    }
}
