//! Fuzz tests of the readers outside roadtrack-core (issue 15, part 5): the detections file
//! of `--detector file` ([`FileDetector::open`]) and the simulator's external trajectories
//! ([`ExternalTrajectories::read`]). Seeded structured mutations of valid files plus raw
//! bytes (see `fuzzkit`).
//!
//! Each must not panic and must return `Ok` or an error naming the file: [`Error::Parse`]
//! with the path and a line of the file, [`Error::Format`] with the path, or (for detections
//! past the input's last frame) [`Error::Invalid`] whose message starts with the path.
//!
//! `cargo test -p roadtrack --test fuzz_inputs -- --ignored` runs the deep variant.
// Choice: the simulator's reader is fuzzed here, where proptest and roadtrack-sim are
// already dev-dependencies, rather than adding proptest to roadtrack-sim.

#[path = "../../roadtrack-core/tests/fuzzkit/mod.rs"]
mod fuzzkit;

use fuzzkit::{DEEP, Syntax, file_error, run};
use roadtrack::Error;
use roadtrack::detect::file::FileDetector;
use roadtrack_sim::{ExternalTrajectories, SimConfig};

const DETECTIONS_CSV: &[&str] = &[
    "frame,id,x,y,w,h,r,g,b,class,score\n1,1,10.5,20,4,6,10,20,30,car,0.9\n1,2,30,40,5,5,0,0,255,person,1\n3,1,11,21,4,6,10,20,30,car,0.8\n",
    "x,y\n1,2\n",
];

const DETECTIONS_MOT: &[&str] = &[
    "1,-1,10,20,30,40,0.9,-1,-1,-1\n1,-1,50,60,10,10,0.5,-1,-1,-1\n3,-1,11,21,30,40,1,-1,-1,-1\n",
];

fn file_detector(name: &str, file: &str, seeds: &[&str], cases: u32) {
    let dir = tempfile::tempdir().expect("temporary folder");
    let path = dir.path().join(file);
    run(name, cases, seeds, Syntax::Csv, |bytes| {
        fuzzkit::write_case(&path, bytes)?;
        // The input has 5 frames: detections after frame 5 belong to another input.
        match FileDetector::open(&path, Some(5)) {
            Ok(_) => Ok(()),
            Err(Error::Invalid(m)) if m.starts_with(&path.display().to_string()) => Ok(()),
            Err(e) => file_error(&e, &path, bytes),
        }
    });
}

/// 2 000 cases.
#[test]
fn fuzz_file_detector_csv() {
    file_detector("file_detector_csv", "dets.csv", DETECTIONS_CSV, 2000);
}

/// 2 000 cases.
#[test]
fn fuzz_file_detector_mot() {
    file_detector("file_detector_mot", "det.txt", DETECTIONS_MOT, 2000);
}

const EXTERNAL: &[&str] = &[
    "time_s,id,class,x_m,y_m,heading_deg,length_m,width_m\n0,1,car,0,0,0,4.5,1.8\n1,1,car,10,0,0,4.5,1.8\n0.5,2,person,5,5,90,0.5,0.5\n",
    "time_s,id,class,x_m,y_m,heading_deg,length_m,width_m,r,g,b,height_m\n0,1,truck,0,0,0,8,2.5,200,10,10,3.5\n2,1,truck,20,0,10,8,2.5,200,10,10,3.5\n",
];

fn external(cases: u32) {
    let dir = tempfile::tempdir().expect("temporary folder");
    let path = dir.path().join("sumo.csv");
    let config = SimConfig::default();
    run(
        "external_trajectories",
        cases,
        EXTERNAL,
        Syntax::Csv,
        |bytes| {
            fuzzkit::write_case(&path, bytes)?;
            match ExternalTrajectories::read(&path) {
                Ok(t) => {
                    // Using what was read must not panic either.
                    let _ = t.frames_spanned(config.fps);
                    let _ = t.states_at(0.5, &config, 1);
                    Ok(())
                }
                Err(e) => file_error(&e, &path, bytes),
            }
        },
    );
}

/// 2 000 cases.
#[test]
fn fuzz_external_trajectories() {
    external(2000);
}

/// The deep run: 100 × the cases of every reader above.
#[test]
#[ignore = "deep fuzzing, minutes; run with --ignored"]
fn fuzz_inputs_deep() {
    file_detector("file_detector_csv", "dets.csv", DETECTIONS_CSV, 2000 * DEEP);
    file_detector("file_detector_mot", "det.txt", DETECTIONS_MOT, 2000 * DEEP);
    external(2000 * DEEP);
}
