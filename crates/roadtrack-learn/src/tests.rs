//! A tiny training run learns and is reproducible (the burn/tract parity test is in
//! roadtrack-cli's tests/cnn_detector.rs, which has both crates).

use roadtrack::error::Result;

use crate::arch::CenterNetShape;
use crate::data::DataConfig;
use crate::train::{Progress, TrainConfig, train};

fn tiny_shape() -> CenterNetShape {
    crate::parity::tiny_shape()
}

fn tiny_config(steps: usize) -> TrainConfig {
    TrainConfig {
        steps,
        batch: 4,
        learning_rate: 5e-3,
        seed: 3,
        pool_frames: 4,
        refresh_every: 8,
        shape: tiny_shape(),
        data: DataConfig {
            width: 192,
            height: 144,
            frames_per_episode: 2,
            crop: 48,
            ..DataConfig::default()
        },
        ..TrainConfig::default()
    }
}

#[test]
fn tiny_training_run_lowers_the_loss_and_is_reproducible() -> Result<()> {
    let cfg = tiny_config(40);
    let mut losses = Vec::new();
    let mut checkpoints = Vec::new();
    let a = train(&cfg, 20, &mut |p| {
        match p {
            Progress::Step(l) => losses.push(l.total),
            Progress::Checkpoint { step, .. } => checkpoints.push(step),
        }
        Ok(())
    })?;
    assert_eq!(losses.len(), 40);
    assert_eq!(checkpoints, vec![20, 40]);
    let first: f32 = losses[..5].iter().sum::<f32>() / 5.0;
    let last: f32 = losses[30..].iter().sum::<f32>() / 10.0;
    assert!(
        last < 0.85 * first,
        "loss did not fall: first steps {first}, last steps {last} ({losses:?})"
    );
    let b = train(&cfg, 0, &mut |_| Ok(()))?;
    assert_eq!(a.to_json()?, b.to_json()?, "same seed, different model");
    let c = train(&TrainConfig { seed: 4, ..cfg }, 0, &mut |_| Ok(()))?;
    assert_ne!(a.to_json()?, c.to_json()?, "the seed changes nothing");
    Ok(())
}

#[test]
fn burn_still_computes_the_parity_fixture() -> Result<()> {
    // The fixture's outputs are burn's; roadtrack-cnn's test checks tract against them.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../roadtrack-cnn/tests/fixtures/centernet_parity.json");
    let text = std::fs::read_to_string(&path).map_err(|e| roadtrack::Error::io(&path, e))?;
    let f: crate::parity::ParityFixture = serde_json::from_str(&text)
        .map_err(|e| roadtrack::Error::Invalid(format!("{}: {e}", path.display())))?;
    assert_eq!(
        f,
        crate::parity::make_fixture(11),
        "the fixture is stale: regenerate it"
    );
    let (heat, boxes) = crate::parity::burn_forward(&f.weights, &f.input, f.h, f.w);
    assert_eq!(heat, f.heatmap);
    assert_eq!(boxes, f.boxes);
    Ok(())
}

#[test]
fn zoomed_out_crops_shrink_objects_by_the_drawn_scale() {
    use crate::data::{Object, TrainFrame, make_sample};
    use rand::SeedableRng;
    // One 200 × 80 px car on a 640 × 480 frame (a car near an oblique camera): ordinary
    // crops (0.7–1.4 frame px per crop px) see it at 143–286 crop px, larger than a crop;
    // zoomed-out ones (1.4–3.2) at 62–143.
    let frame = TrainFrame {
        image: image::RgbImage::from_pixel(640, 480, image::Rgb([90, 90, 90])),
        objects: vec![Object {
            bbox: roadtrack::geometry::BBox::new(220.0, 200.0, 200.0, 80.0),
            channel: 0,
            visibility: 1.0,
        }],
    };
    let prep = crate::train::training_preprocessing();
    let widths = |share: f64| -> Vec<f64> {
        let data = DataConfig {
            zoom_out_share: share,
            ..DataConfig::default()
        };
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(9);
        let mut out = Vec::new();
        for _ in 0..200 {
            let s = make_sample(&frame, &mut rng, &data, &prep);
            let plane = (data.crop / 4) * (data.crop / 4);
            if let Some(i) = (0..plane).find(|&i| s.reg_mask[i] > 0.0) {
                out.push(4.0 * f64::from(s.reg[i]).exp());
            }
        }
        out
    };
    let ordinary = widths(0.0);
    let zoomed = widths(1.0);
    assert!(ordinary.len() > 50 && zoomed.len() > 50);
    let within = |v: &[f64], lo: f64, hi: f64| v.iter().all(|&w| w >= lo - 1e-3 && w <= hi + 1e-3);
    assert!(within(&ordinary, 200.0 / 1.4, 200.0 / 0.7), "{ordinary:?}");
    assert!(within(&zoomed, 200.0 / 3.2, 200.0 / 1.4), "{zoomed:?}");
    // Zoomed-out crops are area-sampled: a uniform frame stays uniform.
    let data = DataConfig {
        zoom_out_share: 1.0,
        ..DataConfig::default()
    };
    let s = make_sample(
        &frame,
        &mut rand_pcg::Pcg64Mcg::seed_from_u64(1),
        &data,
        &prep,
    );
    let v0 = s.input[0];
    assert!(
        s.input[..data.crop * data.crop]
            .iter()
            .all(|&v| (v - v0).abs() < 1e-5)
    );
}

#[test]
fn boxes_are_clipped_to_the_crop_as_the_truth_is_to_the_frame() {
    use crate::data::{Object, TrainFrame, crop_box, make_sample};
    use rand::SeedableRng;
    use roadtrack::geometry::BBox;
    let data = DataConfig {
        clip_to_crop: true,
        ..DataConfig::default()
    };
    // A 40 × 20 box, its left half outside a crop at (100, 50), 1 frame px per crop px.
    let b = BBox::new(80.0, 60.0, 40.0, 20.0);
    let (x, y, w, h, f) = crop_box(&b, 100.0, 50.0, 1.0, 128.0, false, &data).unwrap();
    assert_eq!((x, y, w, h), (10.0, 20.0, 20.0, 20.0));
    assert!((f - 0.5).abs() < 1e-12);
    // Mirrored: the same box at the right edge.
    let (x, _, w, _, _) = crop_box(&b, 100.0, 50.0, 1.0, 128.0, true, &data).unwrap();
    assert_eq!((x, w), (118.0, 20.0));
    // Whole boxes (the default): centre outside the crop, no target at all.
    let whole = DataConfig {
        clip_to_crop: false,
        ..data
    };
    let mostly_out = BBox::new(70.0, 60.0, 40.0, 20.0);
    assert!(crop_box(&mostly_out, 100.0, 50.0, 1.0, 128.0, false, &whole).is_none());
    let (.., f) = crop_box(&mostly_out, 100.0, 50.0, 1.0, 128.0, false, &data).unwrap();
    assert!((f - 0.25).abs() < 1e-12);
    let inside = BBox::new(110.0, 60.0, 40.0, 20.0);
    assert_eq!(
        crop_box(&inside, 100.0, 50.0, 1.0, 128.0, false, &whole),
        crop_box(&inside, 100.0, 50.0, 1.0, 128.0, false, &data)
    );
    assert!(
        crop_box(
            &BBox::new(300.0, 60.0, 4.0, 4.0),
            100.0,
            50.0,
            1.0,
            128.0,
            false,
            &data
        )
        .is_none()
    );

    // A 200 × 80 px car, larger than any ordinary crop: with clipping every positive's box
    // lies inside its crop, and crops that hold only part of the car still get a target.
    let frame = TrainFrame {
        image: image::RgbImage::from_pixel(640, 480, image::Rgb([90, 90, 90])),
        objects: vec![Object {
            bbox: BBox::new(220.0, 200.0, 200.0, 80.0),
            channel: 0,
            visibility: 1.0,
        }],
    };
    let prep = crate::train::training_preprocessing();
    let boxes = |d: &DataConfig| -> Vec<[f64; 4]> {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        let g = d.crop / 4;
        let plane = g * g;
        let mut out = Vec::new();
        for _ in 0..300 {
            let s = make_sample(&frame, &mut rng, d, &prep);
            if let Some(i) = (0..plane).find(|&i| s.pos[i] > 0.0) {
                let (ix, iy) = ((i % g) as f64, (i / g) as f64);
                let w = 4.0 * f64::from(s.reg[i]).exp();
                let h = 4.0 * f64::from(s.reg[plane + i]).exp();
                let cx = 4.0 * (ix + f64::from(s.reg[2 * plane + i]));
                let cy = 4.0 * (iy + f64::from(s.reg[3 * plane + i]));
                out.push([cx - w / 2.0, cy - h / 2.0, cx + w / 2.0, cy + h / 2.0]);
            }
        }
        out
    };
    let ordinary = DataConfig {
        zoom_out_share: 0.0,
        ..data
    };
    let clipped = boxes(&ordinary);
    let side = ordinary.crop as f64 + 1e-3;
    assert!(
        clipped
            .iter()
            .all(|b| b.iter().all(|&v| (-1e-3..=side).contains(&v))),
        "{clipped:?}"
    );
    let kept_whole = boxes(&DataConfig {
        clip_to_crop: false,
        ..ordinary
    });
    assert!(kept_whole.iter().any(|b| b[0] < -1.0 || b[2] > side + 1.0));
    // The same crops (the targets draw nothing from the generator): the clipped ones add
    // the crops whose view of the car leaves its centre out.
    assert!(
        clipped.len() > kept_whole.len(),
        "{} against {}",
        clipped.len(),
        kept_whole.len()
    );
}

#[test]
fn edge_crops_cut_an_object_with_the_crop_edge() {
    use crate::data::{Object, TrainFrame, make_sample};
    use rand::SeedableRng;
    use roadtrack::geometry::BBox;
    // A 60 × 30 px car in the middle of the frame; ordinary scales only.
    let car = BBox::new(290.0, 220.0, 60.0, 30.0);
    let frame = |bbox: BBox| TrainFrame {
        image: image::RgbImage::from_pixel(640, 480, image::Rgb([90, 90, 90])),
        objects: vec![Object {
            bbox,
            channel: 0,
            visibility: 1.0,
        }],
    };
    let prep = crate::train::training_preprocessing();
    let data = DataConfig {
        clip_to_crop: true,
        zoom_out_share: 0.0,
        ..DataConfig::default()
    };
    // Per sample: the positive's box in crop px, if any.
    let targets = |f: &TrainFrame, d: &DataConfig| -> Vec<Option<[f64; 4]>> {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        let g = d.crop / 4;
        let plane = g * g;
        (0..200)
            .map(|_| {
                let s = make_sample(f, &mut rng, d, &prep);
                (0..plane).find(|&i| s.pos[i] > 0.0).map(|i| {
                    let (ix, iy) = ((i % g) as f64, (i / g) as f64);
                    let w = 4.0 * f64::from(s.reg[i]).exp();
                    let h = 4.0 * f64::from(s.reg[plane + i]).exp();
                    let cx = 4.0 * (ix + f64::from(s.reg[2 * plane + i]));
                    let cy = 4.0 * (iy + f64::from(s.reg[3 * plane + i]));
                    [cx - w / 2.0, cy - h / 2.0, cx + w / 2.0, cy + h / 2.0]
                })
            })
            .collect()
    };
    let side = data.crop as f64;
    let at_edge = |b: &[f64; 4]| b[0] < 0.5 || b[1] < 0.5 || b[2] > side - 0.5 || b[3] > side - 0.5;
    let cut_share = |t: &[Option<[f64; 4]>]| {
        t.iter().flatten().filter(|b| at_edge(b)).count() as f64 / t.len() as f64
    };
    let edge = DataConfig {
        edge_crop_share: 1.0,
        ..data
    };
    let with = targets(&frame(car), &edge);
    // Every edge crop holds the car, cut by the crop's edge, 40–90 % of it inside (crop
    // scale 0.7–1.4 frame px per crop px: 60 px wide is 43–86 crop px, 30 high 21–43).
    assert!(with.iter().all(Option::is_some), "{with:?}");
    for b in with.iter().flatten() {
        let (w, h) = (b[2] - b[0], b[3] - b[1]);
        // The car is 2:1: the uncut side gives the scale, the ratio the cut side's share.
        assert!(at_edge(b), "not cut: {b:?}");
        let share = (w / (2.0 * h)).min(2.0 * h / w);
        assert!((0.39..=0.91).contains(&share), "{share} {b:?}");
    }
    let without = targets(&frame(car), &data);
    assert!(cut_share(&with) > 0.95, "{}", cut_share(&with));
    assert!(cut_share(&without) < 0.5, "{}", cut_share(&without));
    // An object too small to cut (4 px) falls back to the ordinary crops, draw for draw
    // after the edge crop's own draws: the same share of crops holds it.
    let tiny = BBox::new(318.0, 233.0, 4.0, 4.0);
    let small_edge = targets(&frame(tiny), &edge);
    assert!(small_edge.iter().flatten().all(|b| !at_edge(b)));
}

#[test]
fn bad_crop_scales_are_refused_by_name() {
    for (data, field) in [
        (
            DataConfig {
                scale_range: (1.4, 0.7),
                ..DataConfig::default()
            },
            "scale_range",
        ),
        (
            DataConfig {
                zoom_out_max: 1.0,
                ..DataConfig::default()
            },
            "zoom_out",
        ),
        (
            DataConfig {
                min_in_crop: 1.5,
                ..DataConfig::default()
            },
            "min_in_crop",
        ),
        (
            DataConfig {
                edge_crop_share: -0.1,
                ..DataConfig::default()
            },
            "edge_crop_share",
        ),
        (
            DataConfig {
                edge_crop_min_px: 0.0,
                ..DataConfig::default()
            },
            "edge_crop_min_px",
        ),
        (
            DataConfig {
                box_class_weights: [1.0, -1.0, 1.0, 1.0],
                ..DataConfig::default()
            },
            "box_class_weights",
        ),
        (
            DataConfig {
                motorcycle_share: Some(1.0),
                ..DataConfig::default()
            },
            "motorcycle_share",
        ),
        (
            DataConfig {
                heavy_share: Some(-0.1),
                ..DataConfig::default()
            },
            "heavy_share",
        ),
        (
            DataConfig {
                motorcycle_share: Some(0.5),
                heavy_share: Some(0.5),
                ..DataConfig::default()
            },
            "motorcycle_share/heavy_share",
        ),
    ] {
        let cfg = TrainConfig {
            data,
            ..TrainConfig::default()
        };
        let err = cfg.validate().unwrap_err().to_string();
        assert!(err.contains(field), "{field}: {err}");
    }
}

#[test]
fn each_class_box_targets_carry_its_weight() {
    use crate::data::{Object, TrainFrame, make_sample};
    use rand::SeedableRng;
    // A car (channel 0) and a lorry (channel 1) side by side in the middle of the frame:
    // every crop that holds a centre weighs its four box targets by the class's weight.
    let frame = TrainFrame {
        image: image::RgbImage::from_pixel(640, 480, image::Rgb([90, 90, 90])),
        objects: vec![
            Object {
                bbox: roadtrack::geometry::BBox::new(300.0, 230.0, 16.0, 8.0),
                channel: 0,
                visibility: 1.0,
            },
            Object {
                bbox: roadtrack::geometry::BBox::new(330.0, 230.0, 30.0, 10.0),
                channel: 1,
                visibility: 1.0,
            },
        ],
    };
    let prep = crate::train::training_preprocessing();
    let masks = |weights: [f32; 4]| -> Vec<(usize, f32)> {
        let data = DataConfig {
            box_class_weights: weights,
            ..DataConfig::default()
        };
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        let plane = (data.crop / 4) * (data.crop / 4);
        let mut out = Vec::new();
        for _ in 0..40 {
            let s = make_sample(&frame, &mut rng, &data, &prep);
            for i in 0..plane {
                if s.reg_mask[i] > 0.0 {
                    let class = (0..4).find(|&k| s.pos[k * plane + i] > 0.0).unwrap();
                    // The same weight on all four targets (size and offset).
                    for j in 1..4 {
                        assert_eq!(s.reg_mask[j * plane + i], s.reg_mask[i]);
                    }
                    out.push((class, s.reg_mask[i]));
                }
            }
        }
        out
    };
    let plain = masks([1.0; 4]);
    assert!(plain.iter().any(|m| m.0 == 0) && plain.iter().any(|m| m.0 == 1));
    assert!(plain.iter().all(|m| m.1 == 1.0));
    let weighted = masks([1.0, 3.0, 2.0, 0.5]);
    // Same crops (same seed): the same cells, each with its class's weight.
    assert_eq!(weighted.len(), plain.len());
    for (class, w) in weighted {
        assert_eq!(w, [1.0, 3.0, 2.0, 0.5][class]);
    }
}

#[test]
fn a_second_stage_starts_from_the_first_stages_weights() -> Result<()> {
    let first = tiny_config(40);
    let mut first_losses = Vec::new();
    let w = train(&first, 0, &mut |p| {
        if let Progress::Step(l) = p {
            first_losses.push(l.total);
        }
        Ok(())
    })?;
    let second = TrainConfig {
        init: Some(std::sync::Arc::new(w.clone())),
        sim_seed_base: 2000,
        ..tiny_config(10)
    };
    let mut second_losses = Vec::new();
    let w2 = train(&second, 0, &mut |p| {
        if let Progress::Step(l) = p {
            second_losses.push(l.total);
        }
        Ok(())
    })?;
    // Started from trained weights, the second stage's first steps are where the first
    // stage ended, not where it began.
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let (began, ended, resumed) = (
        mean(&first_losses[..5]),
        mean(&first_losses[30..]),
        mean(&second_losses[..5]),
    );
    assert!(
        resumed < began - 0.5 * (began - ended),
        "second stage began at {resumed}; the first went {began} -> {ended}"
    );
    assert_eq!(w2.shape, w.shape);
    assert_ne!(
        w2.to_json()?,
        w.to_json()?,
        "the second stage did not train"
    );
    Ok(())
}

#[test]
fn starting_weights_with_other_preprocessing_are_refused_by_name() -> Result<()> {
    let mut w = train(&tiny_config(1), 0, &mut |_| Ok(()))?;
    w.preprocessing.mean = [0.5; 3];
    let cfg = TrainConfig {
        init: Some(std::sync::Arc::new(w)),
        ..tiny_config(1)
    };
    let err = cfg.validate().expect_err("other preprocessing").to_string();
    assert!(err.contains("init"), "{err}");
    Ok(())
}

#[test]
fn the_vehicle_shares_set_the_episodes_mix_and_nothing_else() {
    use crate::data::random_sim_config;
    use rand::SeedableRng;
    let draw = |motorcycle: Option<f64>, heavy: Option<f64>| {
        let data = DataConfig {
            motorcycle_share: motorcycle,
            heavy_share: heavy,
            ..DataConfig::default()
        };
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(12);
        (0..5)
            .map(|_| random_sim_config(&mut rng, &data))
            .collect::<Vec<_>>()
    };
    let plain = draw(None, None);
    let sim = roadtrack_sim::SimConfig::default().vehicles;
    assert_eq!(plain[0].vehicles.motorcycle.share, sim.motorcycle.share);
    for (m, h) in [(None, Some(0.3)), (Some(0.2), Some(0.3)), (Some(0.3), None)] {
        for (a, b) in plain.iter().zip(draw(m, h)) {
            let v = &b.vehicles;
            let all = v.car.share + v.truck.share + v.bus.share + v.motorcycle.share;
            let heavy = (v.truck.share + v.bus.share) / all;
            let moto = v.motorcycle.share / all;
            // Each given share is met; one not given keeps its place beside the cars.
            match h {
                Some(h) => assert!((heavy - h).abs() < 1e-12, "{heavy}"),
                None => assert!(
                    ((v.truck.share + v.bus.share) / v.car.share
                        - (sim.truck.share + sim.bus.share) / sim.car.share)
                        .abs()
                        < 1e-12
                ),
            }
            if let (Some(m), None) = (m, h) {
                // The motorcycle share alone, as it was computed before the lorries', to
                // the bit (the documented motorcycle fine-tune draws the same episodes).
                let others = v.car.share + v.truck.share + v.bus.share;
                assert_eq!(v.motorcycle.share, others * m / (1.0 - m));
            }
            match m {
                Some(m) => assert!((moto - m).abs() < 1e-12, "{moto}"),
                None => assert_eq!(v.motorcycle.share, sim.motorcycle.share),
            }
            assert_eq!(v.car.share, sim.car.share);
            assert!((v.truck.share / v.bus.share - sim.truck.share / sim.bus.share).abs() < 1e-12);
            // The same draws otherwise.
            let mut b = b.clone();
            b.vehicles = a.vehicles.clone();
            assert_eq!(format!("{a:?}"), format!("{b:?}"));
        }
    }
}

#[test]
fn sample_records_give_back_the_sample() -> Result<()> {
    use crate::data::{Object, TrainFrame, make_sample};
    use crate::record::{decode, encode};
    use rand::SeedableRng;
    // A textured frame with vehicles and walkers of every class, two of them barely visible
    // (ignored around them: zero negative weights).
    let image = image::RgbImage::from_fn(320, 240, |x, y| {
        image::Rgb([
            (x * 7 % 256) as u8,
            (y * 5 % 256) as u8,
            ((x + y) % 256) as u8,
        ])
    });
    let objects = (0..12)
        .map(|k| Object {
            bbox: roadtrack::geometry::BBox::new(
                20.0 + 23.0 * k as f64,
                30.0 + 13.0 * k as f64,
                8.0 + 3.0 * k as f64,
                6.0 + 2.0 * k as f64,
            ),
            channel: k % 4,
            visibility: if k % 5 == 0 { 0.1 } else { 1.0 },
        })
        .collect();
    let frame = TrainFrame { image, objects };
    let data = DataConfig::default();
    let prep = crate::train::training_preprocessing();
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
    let (mut with_pos, mut with_ignored) = (0, 0);
    for _ in 0..40 {
        let s = make_sample(&frame, &mut rng, &data, &prep);
        let mut bytes = encode(&s, data.crop, &prep);
        let len = bytes.len();
        bytes.extend_from_slice(b"RTS1 next record");
        let (d, used) = decode(&bytes, &prep)?;
        assert_eq!(used, len);
        assert_eq!(
            (&d.pos, &d.neg_weight, d.n_pos),
            (&s.pos, &s.neg_weight, s.n_pos)
        );
        assert_eq!((&d.reg, &d.reg_mask), (&s.reg, &s.reg_mask));
        // The input is stored as 0–255 values: within half a grey level.
        let step = 0.5 * prep.input_scale / prep.std[0] + 1e-6;
        assert!(
            d.input
                .iter()
                .zip(&s.input)
                .all(|(a, b)| (a - b).abs() <= step)
        );
        with_pos += usize::from(s.n_pos > 0);
        let ignored = s
            .neg_weight
            .iter()
            .zip(&s.pos)
            .any(|(&w, &p)| w == 0.0 && p == 0.0);
        with_ignored += usize::from(ignored);
        // Cut short or not a record: refused, never a panic.
        assert!(decode(&bytes[..len - 1], &prep).is_err());
        assert!(decode(&bytes[len..], &prep).is_err());
    }
    assert!(
        with_pos > 10 && with_ignored > 0,
        "{with_pos} {with_ignored}"
    );
    Ok(())
}

#[test]
fn the_sample_workers_mix_is_read_and_checked_as_the_trainer_checks_it() -> Result<()> {
    let env = |pairs: &'static [(&'static str, &'static str)]| {
        move |k: &str| {
            pairs
                .iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| (*v).to_string())
        }
    };
    assert_eq!(DataConfig::with_mix_from(env(&[]))?, DataConfig::default());
    let d =
        DataConfig::with_mix_from(env(&[("MOTORCYCLE_SHARE", "0.3"), ("HEAVY_SHARE", " 0.2")]))?;
    assert_eq!((d.motorcycle_share, d.heavy_share), (Some(0.3), Some(0.2)));
    for (pairs, named) in [
        (&[("MOTORCYCLE_SHARE", "abc")][..], "MOTORCYCLE_SHARE"),
        (&[("HEAVY_SHARE", "1")][..], "heavy_share"),
        (
            &[("MOTORCYCLE_SHARE", "0.6"), ("HEAVY_SHARE", "0.5")][..],
            "motorcycle_share/heavy_share",
        ),
    ] {
        let err = DataConfig::with_mix_from(env(pairs))
            .unwrap_err()
            .to_string();
        assert!(err.contains(named), "{named}: {err}");
    }
    Ok(())
}
