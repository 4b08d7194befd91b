//! End-to-end tests of `roadtrack filter` on the committed point scenario
//! (`crates/roadtrack/tests/golden/filter/`, README there: seed 7, the scenario's true
//! model).

mod common;
use common::stderr;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn golden(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../roadtrack/tests/golden/filter")
        .join(name)
}

/// The scenario's true model (`PointScenarioConfig::default()`), as flags.
const MODEL: [&str; 16] = [
    "--region",
    "0,0,500,500",
    "--detection-prob",
    "0.9",
    "--survival-prob",
    "0.99",
    "--clutter-rate",
    "10",
    "--birth-rate",
    "0.05",
    "--measurement-sigma",
    "2",
    "--process-sigma",
    "0.1",
    "--birth-speed-sigma",
    "2",
];

fn filter(input: &Path, out: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_roadtrack"))
        .arg("-q")
        .arg("filter")
        .arg(input)
        .arg("-o")
        .arg(out)
        .args(extra)
        .output()
        .expect("run roadtrack")
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).expect("read output")
}

#[test]
fn the_committed_scenario_reproduces_the_committed_estimates_byte_for_byte() {
    let d = tempfile::tempdir().expect("tempdir");
    let out = d.path().join("estimates.csv");
    let mut args = MODEL.to_vec();
    args.extend(["--seed", "7"]);
    let o = filter(&golden("measurements.csv"), &out, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        read(&out) == read(&golden("estimates.csv")),
        "estimates differ from tests/golden/filter/estimates.csv"
    );
    // The same model from a TOML config gives the same bytes; a flag overrides the file.
    let toml = d.path().join("f.toml");
    std::fs::write(
        &toml,
        "region = { x0 = 0.0, y0 = 0.0, x1 = 500.0, y1 = 500.0 }\n\
         detection_prob = 0.9\nsurvival_prob = 0.99\nclutter_rate = 10.0\n\
         birth_rate = 0.05\nmeasurement_sigma = 2.0\nprocess_sigma = 0.1\n\
         birth_speed_sigma = 2.0\nparticles_per_target = 5\n",
    )
    .expect("write toml");
    let from_toml = d.path().join("t.csv");
    let o = filter(
        &golden("measurements.csv"),
        &from_toml,
        &[
            "--config",
            toml.to_str().expect("utf-8"),
            "--particles-per-target",
            "70",
            "--seed",
            "7",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        read(&from_toml) == read(&out),
        "TOML config differs from flags"
    );
}

#[test]
fn same_seed_same_bytes_and_every_step_has_a_row_set() {
    let d = tempfile::tempdir().expect("tempdir");
    let outs: Vec<PathBuf> = ["a.csv", "b.csv", "c.csv"]
        .iter()
        .map(|n| d.path().join(n))
        .collect();
    let mut args = MODEL.to_vec();
    args.extend(["--particles-per-target", "20", "--seed", "3"]);
    for out in &outs[..2] {
        let o = filter(&golden("measurements.csv"), out, &args);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    assert_eq!(read(&outs[0]), read(&outs[1]));
    let mut other = MODEL.to_vec();
    other.extend(["--particles-per-target", "20", "--seed", "4"]);
    assert!(
        filter(&golden("measurements.csv"), &outs[2], &other)
            .status
            .success()
    );
    assert_ne!(read(&outs[0]), read(&outs[2]), "the seed changes the run");
    let text = String::from_utf8(read(&outs[0])).expect("utf-8");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("step,label,x,y,vx,vy,weight"));
    let steps: std::collections::BTreeSet<u64> = lines
        .map(|l| {
            l.split(',')
                .next()
                .and_then(|s| s.parse().ok())
                .expect("step")
        })
        .collect();
    // Targets are present throughout the 100 steps; every step gets estimates.
    assert!(steps.len() > 90, "{} steps with estimates", steps.len());
    // `-o -` writes the same to standard output.
    let o = filter(&golden("measurements.csv"), Path::new("-"), &args);
    assert_eq!(o.stdout, read(&outs[0]));
}

#[test]
fn bad_region_and_bad_input_are_reported() {
    let d = tempfile::tempdir().expect("tempdir");
    let out = d.path().join("e.csv");
    for (region, what) in [
        ("10,0,5,100", "X1 > X0"),
        ("0,0,100", "4 numbers"),
        ("0,0,a,100", "not a number"),
    ] {
        let o = filter(&golden("measurements.csv"), &out, &["--region", region]);
        assert_eq!(o.status.code(), Some(2), "{region}: {}", stderr(&o));
        assert!(stderr(&o).contains(what), "{region}: {}", stderr(&o));
    }
    assert!(!out.exists(), "nothing written on error");
    let o = filter(
        &golden("measurements.csv"),
        &out,
        &["--detection-prob", "1.5"],
    );
    assert_eq!(
        o.status.code(),
        Some(2),
        "a bad flag value is a usage error"
    );
    assert!(stderr(&o).contains("--detection-prob"), "{}", stderr(&o));
    let bad = d.path().join("m.csv");
    std::fs::write(&bad, "step,x,y\n1,2,3\n2,x,4\n").expect("write");
    let o = filter(&bad, &out, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("m.csv:3"), "{}", stderr(&o));
    std::fs::write(&bad, "step,y\n1,2\n").expect("write");
    let o = filter(&bad, &out, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains('x'), "{}", stderr(&o));
}
