//! End-to-end test of `roadtrack analyze` against the simulator's truth.

use roadtrack_sim::{SceneKind, SimConfig, ViewKind};
use std::collections::{BTreeMap, BTreeSet};
use std::process::Command;

/// Arm rectangles (x0, x1, y0, y1) in ground metres of the simulated intersection, centred
/// on (0, 0) with arms along ±x and ±y, kept inside the aerial view (±105 × ±79 m).
const ARMS: [(&str, [f64; 4]); 4] = [
    ("N", [-12.0, 12.0, 16.0, 70.0]),
    ("S", [-12.0, 12.0, -70.0, -16.0]),
    ("E", [16.0, 95.0, -12.0, 12.0]),
    ("W", [-95.0, -16.0, -12.0, 12.0]),
];

/// (time s, x m, y m) of one object.
type Samples = Vec<(f64, f64, f64)>;

fn arm_of(x: f64, y: f64) -> Option<&'static str> {
    ARMS.iter()
        .find(|(_, r)| x >= r[0] && x <= r[1] && y >= r[2] && y <= r[3])
        .map(|(n, _)| *n)
}

#[test]
fn counts_and_turning_movements_on_a_simulated_intersection_equal_the_truth() {
    let dir = tempfile::tempdir().expect("tempdir");
    let seq = dir.path().join("seq");
    let cfg = SimConfig {
        scene: SceneKind::Intersection,
        view: ViewKind::Aerial,
        frames: 300,
        ..Default::default()
    };
    roadtrack_sim::simulate(&cfg, 11, &seq, &mut |_, _| {}).expect("simulate");

    // Reference, straight from truth.csv (ground metres of every object): first and last
    // arm of each vehicle, and crossings of the line y = 30 across the north arm.
    let text = std::fs::read_to_string(seq.join("truth.csv")).expect("truth");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).expect(n);
    let (ci, cc, cx, cy, ct) = (
        col("id"),
        col("class"),
        col("x_m"),
        col("y_m"),
        col("time_s"),
    );
    let mut tracks: BTreeMap<u64, (String, Samples)> = BTreeMap::new();
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        let e = tracks
            .entry(f[ci].parse().expect("id"))
            .or_insert_with(|| (f[cc].to_owned(), Vec::new()));
        e.1.push((
            f[ct].parse().expect("t"),
            f[cx].parse().expect("x"),
            f[cy].parse().expect("y"),
        ));
    }
    let mut od_ref: BTreeMap<(String, String, String), u64> = BTreeMap::new();
    let mut incomplete_ref: BTreeMap<String, u64> = BTreeMap::new();
    let mut north_in = 0u64;
    let mut north_out = 0u64;
    for (class, s) in tracks.values_mut() {
        if class == "pedestrian" {
            continue;
        }
        s.sort_by(|a, b| a.0.total_cmp(&b.0));
        let first = s.iter().find_map(|p| arm_of(p.1, p.2));
        let last = s.iter().rev().find_map(|p| arm_of(p.1, p.2));
        // A trip counts when it was first and last seen in different arms; the same arm
        // is an incomplete track, reported apart.
        match (first, last) {
            (Some(o), Some(d)) if o != d => {
                *od_ref
                    .entry((o.to_owned(), d.to_owned(), class.clone()))
                    .or_default() += 1;
            }
            (Some(o), Some(_)) => *incomplete_ref.entry(o.to_owned()).or_default() += 1,
            _ => {}
        }
        let (mut went_in, mut went_out) = (false, false);
        for w in s.windows(2) {
            let (a, b) = (w[0], w[1]);
            if (a.2 - 30.0) * (b.2 - 30.0) < 0.0 {
                let x = a.1 + (b.1 - a.1) * (30.0 - a.2) / (b.2 - a.2);
                if x.abs() <= 12.0 {
                    if b.2 < a.2 {
                        went_in = true
                    } else {
                        went_out = true
                    }
                }
            }
        }
        north_in += u64::from(went_in);
        north_out += u64::from(went_out);
    }
    assert!(
        od_ref.values().sum::<u64>() >= 5,
        "scene too quiet: {od_ref:?}"
    );

    // roadtrack analyze on the ground-truth boxes (gt.txt) through the calibration.
    let mut zones = String::from("coordinates = \"ground\"\n[stitch]\nmax_gap_s = 0.0\n");
    zones.push_str("[[line]]\nname = \"north\"\na = [12.0, 30.0]\nb = [-12.0, 30.0]\n");
    for (n, r) in ARMS {
        zones.push_str(&format!(
            "[[zone]]\nname = \"{n}\"\npolygon = [[{a}, {c}], [{b}, {c}], [{b}, {d}], [{a}, {d}]]\n",
            a = r[0], b = r[1], c = r[2], d = r[3]
        ));
    }
    let zfile = dir.path().join("zones.toml");
    std::fs::write(&zfile, zones).expect("zones");
    // gt.txt has MOT17 classes; analyse vehicles only, as the reference does.
    let gt = roadtrack::io::mot::read_gt(&seq.join("gt/gt.txt")).expect("gt");
    let vehicles: Vec<roadtrack::track_point::TrackPoint> = gt
        .iter()
        .filter(|r| r.class != 1)
        .map(|r| {
            let mut p = r.to_track_point(10.0);
            p.class = roadtrack::ObjectClass::Car;
            p
        })
        .collect();
    let traj = dir.path().join("gt_vehicles.csv");
    roadtrack::io::trajectories::write_trajectories(&traj, &vehicles).expect("write");
    let out = dir.path().join("analysis");
    let o = Command::new(env!("CARGO_BIN_EXE_roadtrack"))
        .arg("analyze")
        .arg(&traj)
        .arg("--calibration")
        .arg(seq.join("calibration.toml"))
        .arg("--zones")
        .arg(&zfile)
        .arg("-o")
        .arg(&out)
        .arg("--json")
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let a: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    // Classes are merged to "car" above (gt.txt cannot tell trucks from buses), so compare
    // the totals per origin and destination.
    let mut od_got: BTreeMap<(String, String), u64> = BTreeMap::new();
    for r in a["od"].as_array().expect("od") {
        *od_got
            .entry((
                r["origin"].as_str().expect("o").into(),
                r["destination"].as_str().expect("d").into(),
            ))
            .or_default() += r["count"].as_u64().expect("n");
    }
    let mut od_ref_total: BTreeMap<(String, String), u64> = BTreeMap::new();
    for ((o, d, _), n) in &od_ref {
        *od_ref_total.entry((o.clone(), d.clone())).or_default() += n;
    }
    assert_eq!(od_got, od_ref_total);
    let mut incomplete_got: BTreeMap<String, u64> = BTreeMap::new();
    for r in a["od_incomplete"].as_array().expect("od_incomplete") {
        assert_eq!(r["origin"], r["destination"], "{r}");
        *incomplete_got
            .entry(r["origin"].as_str().expect("o").into())
            .or_default() += r["count"].as_u64().expect("n");
    }
    assert_eq!(incomplete_got, incomplete_ref);
    let count = |dir: &str| {
        a["counts"]
            .as_array()
            .expect("counts")
            .iter()
            .filter(|c| c["direction"] == dir)
            .map(|c| c["count"].as_u64().expect("n"))
            .sum::<u64>()
    };
    // Line from (12, 30) to (−12, 30) points −x; southbound (inbound) traffic crosses it
    // from its right to its left.
    assert_eq!(
        (count("right_to_left"), count("left_to_right")),
        (north_in, north_out)
    );
    let files: BTreeSet<String> = std::fs::read_dir(&out)
        .expect("dir")
        .map(|e| e.expect("e").file_name().to_string_lossy().into_owned())
        .collect();
    for f in [
        "counts.csv",
        "od.csv",
        "speeds.csv",
        "headways.csv",
        "lanes.csv",
        "analysis.json",
    ] {
        assert!(files.contains(f), "{f} missing: {files:?}");
    }
}

/// `track --calibration` drops boxes that stand above the horizon (they have no ground
/// position) instead of failing the run: a detection in the sky of the oblique view, in
/// every frame, leaves no track, and the rest are tracked and put on the ground.
#[test]
fn track_with_calibration_drops_boxes_above_the_horizon() {
    let dir = tempfile::tempdir().expect("tempdir");
    let seq = dir.path().join("seq");
    let cfg = SimConfig {
        scene: SceneKind::Intersection,
        view: ViewKind::Oblique,
        frames: 10,
        ..Default::default()
    };
    roadtrack_sim::simulate(&cfg, 3, &seq, &mut |_, _| {}).expect("simulate");
    let mut det = std::fs::read_to_string(seq.join("det/det.txt")).expect("det.txt");
    for f in 1..=10 {
        det += &format!("{f},-1,300,5,20,10,0.99,-1,-1,-1\n");
    }
    let det_path = dir.path().join("det.txt");
    std::fs::write(&det_path, det).expect("write");
    let tracks = dir.path().join("t.txt");
    let o = Command::new(env!("CARGO_BIN_EXE_roadtrack"))
        .arg("track")
        .arg(&seq)
        .args(["--method", "relaxation", "-q", "--detections"])
        .arg(&det_path)
        .arg("--calibration")
        .arg(seq.join("calibration.toml"))
        .arg("--trajectories")
        .arg(dir.path().join("t.csv"))
        .arg("-o")
        .arg(&tracks)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows = std::fs::read_to_string(&tracks).expect("tracks");
    assert!(rows.lines().count() > 10, "{rows}");
    for l in rows.lines() {
        let top: f64 = l
            .split(',')
            .nth(3)
            .expect("bb_top")
            .parse()
            .expect("number");
        assert!(top > 20.0, "a box in the sky was kept: {l}");
    }
}
