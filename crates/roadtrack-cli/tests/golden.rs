//! Golden outputs: every method's output on the demo sequence and on the committed
//! fixtures must not change unless a change means to change them.
//!
//! First recorded before the pipeline refactor (issue 12) with the commands below, which
//! this test runs again through the real binary. Text outputs are kept whole under
//! `tests/golden/outputs/<case>/`; binary outputs (simulated images, rendered PNGs) as
//! FNV-1a digests in `<case>/digests.txt`. Regenerate after a deliberate change with
//! `UPDATE_GOLDEN=1 cargo test -p roadtrack-cli --test golden` and commit the diff.

mod common;
use common::{bin, fixture};

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn golden_dir(case: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden/outputs")
        .join(case)
}

/// Runs `roadtrack` with `args` in `dir`; fails the test with stderr when it fails.
fn run(dir: &Path, args: &[&str]) {
    let o = bin()
        .current_dir(dir)
        .arg("-q")
        .args(args)
        .output()
        .expect("run roadtrack");
    assert!(
        o.status.success(),
        "roadtrack {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// 64-bit FNV-1a: a stable digest for binary outputs (not for security).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// Digest lines `name fnv` for every file under `dir` (sorted by relative path).
fn digests(dir: &Path, prefix: &str, out: &mut BTreeMap<String, u64>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("read_dir")
        .map(|e| e.expect("entry").path())
        .collect();
    entries.sort();
    for p in entries {
        let name = format!("{prefix}{}", p.file_name().expect("name").to_string_lossy());
        if p.is_dir() {
            digests(&p, &format!("{name}/"), out);
        } else {
            out.insert(name, fnv1a(&std::fs::read(&p).expect("read")));
        }
    }
}

/// Compares `texts` (file name → path of the output) and `binary` digests with the case's
/// golden folder, or rewrites it under `UPDATE_GOLDEN=1`.
fn check(case: &str, texts: &[(&str, PathBuf)], binary: &BTreeMap<String, u64>) {
    let gdir = golden_dir(case);
    let digest_text: String = binary
        .iter()
        .map(|(k, v)| format!("{k} {v:016x}\n"))
        .collect();
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::create_dir_all(&gdir).expect("mkdir golden");
        for (name, path) in texts {
            std::fs::copy(path, gdir.join(name)).expect("copy golden");
        }
        if !binary.is_empty() {
            std::fs::write(gdir.join("digests.txt"), &digest_text).expect("write digests");
        }
        return;
    }
    let mut failures = Vec::new();
    for (name, path) in texts {
        let got = std::fs::read_to_string(path).expect("read output");
        let want = std::fs::read_to_string(gdir.join(name))
            .unwrap_or_else(|e| panic!("golden {case}/{name}: {e} (run with UPDATE_GOLDEN=1)"));
        if got != want {
            let line = got
                .lines()
                .zip(want.lines())
                .position(|(a, b)| a != b)
                .map_or_else(
                    || {
                        format!(
                            "lengths differ: {} vs {} lines",
                            got.lines().count(),
                            want.lines().count()
                        )
                    },
                    |i| {
                        format!(
                            "line {}: got {:?}, golden {:?}",
                            i + 1,
                            got.lines().nth(i).unwrap_or(""),
                            want.lines().nth(i).unwrap_or("")
                        )
                    },
                );
            failures.push(format!("{case}/{name}: {line}"));
        }
    }
    if !binary.is_empty() {
        let want = std::fs::read_to_string(gdir.join("digests.txt")).unwrap_or_default();
        for (got, want) in digest_text.lines().zip(want.lines()) {
            if got != want {
                failures.push(format!("{case}/digests.txt: got {got:?}, golden {want:?}"));
            }
        }
        if digest_text.lines().count() != want.lines().count() {
            failures.push(format!("{case}/digests.txt: different file lists"));
        }
    }
    assert!(
        failures.is_empty(),
        "outputs changed:\n{}",
        failures.join("\n")
    );
}

const METHODS: [&str; 4] = ["relaxation", "mrf", "pf", "phd"];

/// The demo's sequence (intersection, oblique, 150 frames, seed 0) tracked by every method
/// as published with its calibration (MOT tracks, trajectories CSV with metres and speeds,
/// GeoJSON), and with the default life cycle (MOT tracks).
#[test]
fn every_method_on_the_demo_sequence_is_unchanged() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    run(
        d,
        &[
            "simulate",
            "--scene",
            "intersection",
            "--view",
            "oblique",
            "--frames",
            "150",
            "--seed",
            "0",
            "-o",
            "seq",
        ],
    );
    let mut texts = Vec::new();
    for m in METHODS {
        let (t, c, g) = (
            format!("{m}.txt"),
            format!("{m}.csv"),
            format!("{m}.geojson"),
        );
        run(
            d,
            &[
                "track",
                "seq",
                "--method",
                m,
                "--as-published",
                "--seed",
                "0",
                "--calibration",
                "seq/calibration.toml",
                "-o",
                &t,
                "--trajectories",
                &c,
                "--geojson",
                &g,
            ],
        );
        // The default: the method with the shared life cycle (and relaxation's second
        // assignment).
        let l = format!("{m}_lifecycle.txt");
        run(d, &["track", "seq", "--method", m, "--seed", "0", "-o", &l]);
        for f in [t, c, g, l] {
            let p = d.join(&f);
            texts.push((f, p));
        }
    }
    let mut binary = BTreeMap::new();
    digests(&d.join("seq"), "seq/", &mut binary);
    let texts: Vec<(&str, PathBuf)> = texts.iter().map(|(n, p)| (n.as_str(), p.clone())).collect();
    check("demo_sequence", &texts, &binary);
}

/// The committed 10-frame fixture: detection, every method, the MRF's object maps, the
/// CNN likelihood with the tiny ONNX classifier, and an overlay render.
#[test]
fn every_method_on_the_tiny_fixture_is_unchanged() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let seq = fixture("tiny_sequence");
    let seq = seq.to_str().expect("utf-8 path");
    let mut names: Vec<String> = vec!["detections.csv".into()];
    run(d, &["detect", seq, "-o", "detections.csv"]);
    for m in METHODS {
        let t = format!("{m}.txt");
        run(
            d,
            &[
                "track",
                seq,
                "--method",
                m,
                "--as-published",
                "--seed",
                "3",
                "-o",
                &t,
            ],
        );
        names.push(t);
    }
    run(
        d,
        &[
            "track",
            seq,
            "--method",
            "mrf",
            "--as-published",
            "-o",
            "mrf_maps.txt",
            "--object-maps",
            "maps",
        ],
    );
    names.push("maps/object_maps.csv".into());
    #[cfg(feature = "cnn")]
    {
        let model = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../roadtrack-cnn/tests/fixtures/tiny_classifier.onnx");
        let model = model.to_str().expect("utf-8 path");
        for m in ["pf", "phd"] {
            let t = format!("{m}_cnn.txt");
            run(
                d,
                &[
                    "track",
                    seq,
                    "--method",
                    m,
                    "--likelihood",
                    "cnn",
                    "--model",
                    model,
                    "--as-published",
                    "-o",
                    &t,
                ],
            );
            names.push(t);
        }
    }
    run(
        d,
        &["render", seq, "--tracks", "relaxation.txt", "-o", "overlay"],
    );
    let mut binary = BTreeMap::new();
    digests(&d.join("overlay"), "overlay/", &mut binary);
    digests(&d.join("maps"), "maps/", &mut binary);
    let texts: Vec<(String, PathBuf)> = names
        .iter()
        .map(|n| (n.replace('/', "_"), d.join(n)))
        .collect();
    let texts: Vec<(&str, PathBuf)> = texts.iter().map(|(n, p)| (n.as_str(), p.clone())).collect();
    check("tiny_fixture", &texts, &binary);
}

/// Two-frame relaxation matching on the three committed problems.
#[test]
fn relaxation_matches_on_the_fixtures_are_unchanged() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let mut texts = Vec::new();
    for case in ["1-platoon", "2-two-way", "3-one-leaves"] {
        let f1 = fixture(&format!("relaxation/{case}/frame1.csv"));
        let f2 = fixture(&format!("relaxation/{case}/frame2.csv"));
        let out = format!("{case}.csv");
        run(
            d,
            &[
                "match",
                f1.to_str().expect("utf-8"),
                f2.to_str().expect("utf-8"),
                "-o",
                &out,
            ],
        );
        texts.push((out.clone(), d.join(out)));
    }
    let texts: Vec<(&str, PathBuf)> = texts.iter().map(|(n, p)| (n.as_str(), p.clone())).collect();
    check("relaxation_fixtures", &texts, &BTreeMap::new());
}
