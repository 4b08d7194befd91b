//! Tests of the demo (`super`).

use super::*;

/// Experiment, not a check (docs/EXPERIMENTS.md "Demo"): the turning-movement error of
/// each method's demo tracks under `[stitch] max_overlap_s` values. `DEMO_DIRS` names
/// demo output folders (`roadtrack demo --seed S --no-video -o D`); run with
/// `DEMO_DIRS=D0,D1,D2 cargo test -p roadtrack-cli --bin roadtrack
/// turning_error_by_stitch_overlap -- --ignored --nocapture`.
#[test]
#[ignore = "experiment over demo folders named by DEMO_DIRS"]
fn turning_error_by_stitch_overlap() -> Result<()> {
    let dirs = std::env::var("DEMO_DIRS").unwrap_or_default();
    for dir in dirs.split(',').filter(|d| !d.is_empty()).map(Path::new) {
        let seq = dir.join("sequence");
        let calibration = Calibration::load(&seq.join("calibration.toml"))?;
        let mut truth = io::read_truth_points(&seq, DEFAULT_FPS)?;
        analysis::ground::attach_calibration(&mut truth, &calibration, None, 0.5)?;
        let truth = analysis::analyze(&truth, &intersection_site())?;
        for m in methods() {
            let points = roadtrack::io::trajectories::read_trajectories(
                &dir.join(m.name()).join("trajectories.csv"),
            )?;
            let mut row = format!("{} {:<10}", dir.display(), m.name());
            for overlap in [0.0, 0.5, 1.0, 2.0, 3.0, 5.0] {
                let mut site = intersection_site();
                site.stitch.max_overlap_s = overlap;
                let a = analysis::analyze(&points, &site)?;
                let err = report::movement_error(&a, &truth).unwrap_or(f64::NAN);
                let (c, t) = (report::line_counts(&a), report::line_counts(&truth));
                let off: u64 = t
                    .iter()
                    .map(|(k, n)| n.abs_diff(*c.get(k).unwrap_or(&0)))
                    .sum();
                let lines = off as f64 / t.values().sum::<u64>().max(1) as f64;
                row += &format!(
                    " | {overlap}: {} {:.0} % (lines {:.0} %)",
                    report::trips(&a),
                    100.0 * err,
                    100.0 * lines
                );
            }
            println!("{row}");
        }
    }
    Ok(())
}

/// The built-in relaxation settings are the intersection file's, not the paper's.
#[test]
fn demo_relaxation_reads_the_intersection_config() -> Result<()> {
    let built_in = demo_relaxation()?;
    assert_ne!(
        built_in.relaxation,
        RelaxationTrackerConfig::default().relaxation
    );
    Ok(())
}

/// The built-in MRF settings are the intersection file's, not the defaults.
#[test]
fn demo_mrf_reads_the_intersection_config() -> Result<()> {
    let built_in = demo_mrf()?;
    assert_eq!(built_in.max_missed_frames, 40);
    assert_ne!(MrfConfig::default().max_missed_frames, 40);
    assert!(!built_in.write_unmatched);
    assert!(MrfConfig::default().write_unmatched);
    assert_eq!(built_in.appearance_scale, 20.0);
    assert_ne!(MrfConfig::default().appearance_scale, 20.0);
    assert_eq!(built_in.min_match_score, 1.0);
    assert_eq!(MrfConfig::default().min_match_score, 0.0);
    Ok(())
}

/// The built-in filter settings are the pedestrian file's, not the defaults.
#[test]
fn demo_filters_read_the_video_config() -> Result<()> {
    let built_in = demo_filters()?;
    let defaults = FilterTrackConfig::default();
    assert_eq!(built_in.pf.initial_speed_sigma, 6.0);
    assert_ne!(defaults.pf.initial_speed_sigma, 6.0);
    assert_eq!(built_in.phd.survival_prob, 0.99);
    assert_ne!(defaults.phd.survival_prob, 0.99);
    Ok(())
}

/// The demo's sequence of `frames` frames (seed 0) in a temporary folder, its calibration,
/// and the learned detector's flags.
#[cfg(feature = "cnn")]
fn cnn_demo_sequence(
    frames: u32,
) -> Result<(tempfile::TempDir, PathBuf, Calibration, DetectorArgs)> {
    let dir = tempfile::tempdir()?;
    let seq = dir.path().join("sequence");
    roadtrack_sim::simulate(
        &demo_sim_config(frames, DEFAULT_FPS),
        0,
        &seq,
        &mut |_, _| {},
    )?;
    let calibration = Calibration::load(&seq.join("calibration.toml"))?;
    let args = DetectorArgs {
        detector: Some(crate::common::DetectorArg::Cnn),
        ..Default::default()
    };
    Ok((dir, seq, calibration, args))
}

/// `--detector cnn`: the detections found once, beside the readers, are what each
/// method's own detector finds, frame by frame, whichever runs ahead; the background
/// detector is not shared.
#[cfg(feature = "cnn")]
#[test]
fn the_demo_detects_once_what_each_method_would_detect() -> Result<()> {
    use roadtrack::detect::Detector as _;
    let (_dir, seq, calibration, detector) = cnn_demo_sequence(12)?;
    let cfg = DemoConfig {
        detector,
        ..Default::default()
    };
    let options = SourceOptions::default();
    let mut shared = shared_detector(&cfg, &seq, &calibration)?.context("cnn runs once")?;
    let found = std::sync::Arc::new(Found::default());
    // The reader starts first and waits for every frame.
    let reader = {
        let found = std::sync::Arc::clone(&found);
        let seq = seq.clone();
        let cfg = cfg.clone();
        let options = options.clone();
        std::thread::spawn(move || -> Result<usize> {
            let spec = cfg
                .detector
                .spec(&seq, None, || Ok(Default::default()))?
                .context("a detector")?;
            let info = source::open(&seq, &options)?.info.clone();
            let mut own = spec.build(&seq, &options, &info)?;
            let mut replayed = replay(found);
            let mut last = None;
            let mut boxes = 0;
            for frame in source::open(&seq, &options)? {
                let frame = frame?;
                let got = replayed.detect(&frame)?;
                assert_eq!(got, own.detect(&frame)?, "frame {}", frame.index);
                boxes += got.detections.len();
                last = Some(frame);
            }
            // Past the last frame: an error, not a wait.
            assert!(replayed.detect(&last.context("frames")?).is_err());
            Ok(boxes)
        })
    };
    detect_into(
        shared.as_mut(),
        source::open(&seq, &options)?,
        &found,
        &mut |_| {},
    )?;
    let boxes = reader
        .join()
        .map_err(|_| anyhow::anyhow!("the reader panicked"))??;
    assert_eq!(found.len(), 12);
    assert!(boxes > 0);
    assert!(shared_detector(&DemoConfig::default(), &seq, &calibration)?.is_none());
    Ok(())
}

/// `demo --zoom-small PX` enlarges the far rows only, by the simulator's calibration, as
/// `detect --zoom-small PX --calibration` does: the shared detector finds what that
/// one finds, and not what the whole frame enlarged finds.
#[cfg(feature = "cnn")]
#[test]
fn the_demo_zooms_the_far_rows_by_its_calibration() -> Result<()> {
    let (_dir, seq, calibration, mut args) = cnn_demo_sequence(3)?;
    args.onnx.no_flip = true;
    args.onnx.zoom_small = Some(32.0);
    let cfg = DemoConfig {
        detector: args.clone(),
        ..Default::default()
    };
    let options = SourceOptions::default();
    let info = source::open(&seq, &options)?.info.clone();
    let build = |c: Option<&Calibration>| -> Result<Box<dyn roadtrack::detect::Detector>> {
        let spec = args
            .spec(&seq, c, || Ok(Default::default()))?
            .context("a detector")?;
        Ok(spec.build(&seq, &options, &info)?)
    };
    let mut shared = shared_detector(&cfg, &seq, &calibration)?.context("cnn")?;
    let (mut rows, mut whole) = (build(Some(&calibration))?, build(None)?);
    let mut differs = false;
    for frame in source::open(&seq, &options)? {
        let frame = frame?;
        let got = shared.detect(&frame)?;
        assert_eq!(got, rows.detect(&frame)?, "frame {}", frame.index);
        differs |= got != whole.detect(&frame)?;
    }
    assert!(differs, "the whole frame enlarged gave the same boxes");
    Ok(())
}

/// A detector that fails ends the detections: a method waiting for them gets the
/// detector's message, not a wait without end.
#[test]
fn a_failing_detector_releases_the_methods_waiting_for_it() -> Result<()> {
    let found = std::sync::Arc::new(Found::default());
    let waiting = {
        let found = std::sync::Arc::clone(&found);
        std::thread::spawn(move || {
            let mut replayed = replay(found);
            let frame = roadtrack::Frame {
                index: 1,
                time_s: 0.0,
                image: image::RgbImage::new(4, 4),
            };
            replayed(&frame)
        })
    };
    let mut failing = |_: &roadtrack::Frame| -> roadtrack::Result<FrameDetections> {
        Err(roadtrack::Error::Invalid("model.onnx: bad output".into()))
    };
    let frames = (1..=3).map(|index| {
        Ok(roadtrack::Frame {
            index,
            time_s: 0.0,
            image: image::RgbImage::new(4, 4),
        })
    });
    assert!(detect_into(&mut failing, frames, &found, &mut |_| {}).is_err());
    let got = waiting
        .join()
        .map_err(|_| anyhow::anyhow!("the reader panicked"))?;
    let message = got.err().context("an error")?.to_string();
    assert!(
        message.contains("frame 1") && message.contains("bad output"),
        "{message}"
    );
    Ok(())
}

/// The arms begin past the crosswalks: a car entering from the south 14 m out (where
/// the demo's camera first sees that arm) and leaving north is a trip; a pedestrian on
/// the corner, between two crosswalks, is in no arm.
#[test]
fn the_site_counts_a_trip_first_seen_just_past_the_crosswalk() -> Result<()> {
    use roadtrack::track_point::GroundState;
    let point = |id: u64, f: u32, x: f64, y: f64| TrackPoint {
        frame: f,
        time_s: f64::from(f - 1) / 10.0,
        id,
        class: if id == 1 {
            roadtrack::ObjectClass::Car
        } else {
            roadtrack::ObjectClass::Pedestrian
        },
        bbox: roadtrack::geometry::BBox::from_centre(
            roadtrack::geometry::Point::new(x, y),
            4.0,
            4.0,
        ),
        score: 1.0,
        ground: Some(GroundState {
            x_m: x,
            y_m: y,
            speed_mps: 1.0,
            heading_deg: 0.0,
        }),
    };
    let mut points: Vec<TrackPoint> = (1..=45u32)
        .map(|f| point(1, f, 1.75, -14.0 + f64::from(f - 1)))
        .collect();
    points.extend((1..=20u32).map(|f| point(2, f, -9.0, -9.0 + 0.05 * f64::from(f))));
    let a = analysis::analyze(&points, &intersection_site())?;
    let od: Vec<(&str, &str)> =
        a.od.iter()
            .map(|r| (r.origin.as_str(), r.destination.as_str()))
            .collect();
    assert_eq!(od, [("S", "N")]);
    assert!(a.od_incomplete.is_empty());
    assert_eq!(a.od_unassigned, 1);
    // The counting lines stay 16 m out: first seen inside the south one, the car
    // crosses the north one only.
    let lines: Vec<&str> = a.counts.iter().map(|c| c.line.as_str()).collect();
    assert_eq!(lines, ["north"]);
    Ok(())
}

#[test]
fn the_default_demo_holds_a_whole_signal_cycle() {
    let sim = demo_sim_config(DEFAULT_FRAMES, DEFAULT_FPS);
    let cycle = cycle_s(&sim);
    assert!(cycle > 0.0);
    assert!(
        f64::from(DEFAULT_FRAMES) / DEFAULT_FPS >= cycle,
        "{cycle} s"
    );
}
