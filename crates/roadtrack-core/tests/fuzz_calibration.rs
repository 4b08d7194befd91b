//! Fuzz test of the calibration file reader (issue 15, part 5): seeded TOML mutations of the
//! three forms (nadir scale, homography, point pairs) plus raw bytes (see `fuzzkit`).
//!
//! [`Calibration::load`] must not panic (nor hang in the point-pair fit) and must return a
//! calibration whose matrices are finite, or an error naming the file
//! ([`Error::Toml`], [`Error::Format`], [`Error::Parse`]) or the offending field
//! ([`Error::InvalidConfig`]).
//!
//! `cargo test -p roadtrack-core --test fuzz_calibration -- --ignored` runs the deep variant.

mod fuzzkit;

use fuzzkit::{DEEP, Syntax, run};
use roadtrack_core::{Calibration, Error, Point};

const SEEDS: &[&str] = &[
    "metres_per_pixel = 0.33\norigin_m = [0.0, 40.0]\nrotation_deg = 0.0\n",
    "image_from_ground = [[10.0, 0.0, 320.0], [0.0, -10.0, 240.0], [0.0, 0.01, 1.0]]\n",
    "[[points]]\nimage = [0.0, 0.0]\nground = [0.0, 0.0]\n[[points]]\nimage = [100.0, 0.0]\nground = [10.0, 0.0]\n[[points]]\nimage = [100.0, 100.0]\nground = [10.0, 10.0]\n[[points]]\nimage = [0.0, 100.0]\nground = [0.0, 10.0]\n[[points]]\nimage = [50.0, 40.0]\nground = [5.0, 4.0]\n",
];

fn fuzz(cases: u32) {
    let dir = tempfile::tempdir().expect("temporary folder");
    let path = dir.path().join("calibration.toml");
    run("calibration_toml", cases, SEEDS, Syntax::Toml, |bytes| {
        fuzzkit::write_case(&path, bytes)?;
        match Calibration::load(&path) {
            Ok(c) => {
                let m = [c.image_from_ground_matrix(), c.ground_from_image_matrix()];
                if !m.iter().flatten().flatten().all(|v| v.is_finite()) {
                    return Err(format!("calibration with a non-finite matrix: {c:?}"));
                }
                // Using it must not panic either.
                let _ = c.ground_from_image(Point::new(10.0, 10.0));
                let _ = c.image_from_ground(1.0, 1.0);
                Ok(())
            }
            Err(Error::Toml { path: p, .. } | Error::Format { path: p, .. }) if p == path => Ok(()),
            Err(Error::Parse { path: p, line, .. }) if p == path && line >= 1 => Ok(()),
            Err(Error::InvalidConfig { .. }) => Ok(()),
            Err(e) => Err(format!("unexpected error kind: {e:?}")),
        }
    });
}

/// 3 000 cases.
#[test]
fn fuzz_calibration_toml() {
    fuzz(3000);
}

/// The deep run: 100 × 3 000 cases.
#[test]
#[ignore = "deep fuzzing, minutes; run with --ignored"]
fn fuzz_calibration_toml_deep() {
    fuzz(3000 * DEEP);
}

/// The inputs the fuzz test above found wrongly handled, with the outcome now expected.
#[test]
fn regressions() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let path = dir.path().join("calibration.toml");
    // Not UTF-8: was an I/O error ("cannot access"), as if the file were missing.
    fuzzkit::write_case(
        &path,
        b"\x80metres_per_pixel = 0.33\norigin_m = [0.0, 40.0]\nrotation_deg = 0.0\n",
    )
    .expect("write");
    match Calibration::load(&path) {
        Err(Error::Parse { path: p, line, .. }) => assert_eq!((p, line), (path, 1)),
        other => panic!("expected a parse error, got {other:?}"),
    }
}
