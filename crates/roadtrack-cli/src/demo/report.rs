//! The demo's report page: the best method first, then every method's scores, line counts
//! and turning movements beside the truth's, then a section per method.

use super::{MethodResult, MethodRun};
use roadtrack::analysis::Analysis;
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;

/// What the demo ran, for the page and `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Facts {
    /// Frames simulated.
    pub frames: u32,
    /// Frame rate, frames/s.
    pub fps: f64,
    /// Seed.
    pub seed: u64,
    /// Signal cycle, s.
    pub cycle_s: f64,
    /// The detector, as `--detector` names it.
    pub detector: String,
    /// Whether `--detector` was given (else each method's own background detector).
    pub detector_given: bool,
    /// The detector's flags, e.g. `--detector cnn --no-flip`.
    pub detector_flags: String,
    /// Whether the detector is the demo's default (no `--detector` given).
    pub detector_default: bool,
    /// Seconds the detector took when it ran once for every method (`--detector cnn`,
    /// `onnx`); `None` when each method ran its own.
    pub detect_seconds: Option<f64>,
}

/// `summary.json`.
#[derive(Debug, Serialize)]
pub struct Summary<'a> {
    /// What ran.
    #[serde(flatten)]
    pub facts: &'a Facts,
    /// The truth's complete trips.
    pub truth_trips: u64,
    /// The truth's objects first and last seen in one arm.
    pub truth_incomplete: u64,
    /// Per method, best first.
    pub methods: &'a [MethodResult],
}

/// Complete trips per movement (origin, destination), all classes together.
// Choice: the comparison is class-agnostic, as the scores are: trackers fed detections
// without classes (the background detector, det.txt) call every object `unknown`.
pub fn movements(a: &Analysis) -> BTreeMap<(String, String), u64> {
    let mut m = BTreeMap::new();
    for o in &a.od {
        *m.entry((o.origin.clone(), o.destination.clone()))
            .or_default() += o.count;
    }
    m
}

/// Complete trips, all classes.
pub fn trips(a: &Analysis) -> u64 {
    a.od.iter().map(|o| o.count).sum()
}

/// Σ over movements of |count − truth's count| / the truth's complete trips; `None` when
/// the truth has none.
pub fn movement_error(a: &Analysis, truth: &Analysis) -> Option<f64> {
    let total = trips(truth);
    if total == 0 {
        return None;
    }
    let (m, t) = (movements(a), movements(truth));
    let keys: BTreeSet<&(String, String)> = m.keys().chain(t.keys()).collect();
    let off: u64 = keys
        .into_iter()
        .map(|k| {
            m.get(k)
                .copied()
                .unwrap_or(0)
                .abs_diff(t.get(k).copied().unwrap_or(0))
        })
        .sum();
    Some(off as f64 / total as f64)
}

/// Line crossings per (line, direction), all classes.
pub fn line_counts(a: &Analysis) -> BTreeMap<(String, String), u64> {
    let mut m = BTreeMap::new();
    for c in &a.counts {
        *m.entry((c.line.clone(), c.direction.clone())).or_default() += c.count;
    }
    m
}

fn percent(x: Option<f64>) -> String {
    x.map_or("–".into(), |e| format!("{:.0} %", 100.0 * e))
}

/// The report page.
pub(super) fn page(facts: &Facts, truth: &Analysis, runs: &[MethodRun]) -> String {
    let mut page = String::new();
    let _ = writeln!(page, "# roadtrack demo\n");
    if let Some(best) = runs.first() {
        let r = &best.result;
        let _ = writeln!(
            page,
            "**Best method: {}** — HOTA {:.3}, MOTA {:.3}, IDF1 {:.3}; {} complete trips \
             against the truth's {} (turning-movement error {}).\n",
            r.method,
            r.hota,
            r.mota,
            r.idf1,
            r.trips,
            trips(truth),
            percent(r.movement_error)
        );
    }
    let default = if facts.detector_default {
        " (the demo's default: the learned detector without the mirror image, to keep \
         the run short; `--detector background` gives each method its own background \
         detector)"
    } else {
        ""
    };
    let detector = match (facts.detector_given, facts.detect_seconds) {
        (true, Some(t)) => format!(
            "`{}`{default}, run once for every method, beside them ({t:.1} s; the methods' \
             times below include their waits for it)",
            facts.detector_flags
        ),
        (true, None) => format!("`{}`{default}", facts.detector_flags),
        (false, _) => "each method's own background detector".into(),
    };
    let _ = writeln!(
        page,
        "Simulated signalised intersection, oblique camera, {} frames at {} fps ({:.0} s; the \
         signal cycle is {:.0} s), seed {}; detections: {detector}. Ground truth in \
         `sequence/gt/gt.txt`; calibration in `sequence/calibration.toml`. Scores are \
         class-agnostic, TrackEval definitions; methods best first (by HOTA). The four \
         methods run at once, sharing the cores and one decoding of the frames: a method's \
         time is its wall time beside the others.\n",
        facts.frames,
        facts.fps,
        f64::from(facts.frames) / facts.fps,
        facts.cycle_s,
        facts.seed
    );
    let _ = writeln!(
        page,
        "| method | tracks | MOTA | IDF1 | HOTA | ID switches | trips | turning error | time (s) |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for r in runs.iter().map(|r| &r.result) {
        let _ = writeln!(
            page,
            "| {} | {} | {:.3} | {:.3} | {:.3} | {} | {} | {} | {:.1} |",
            r.method,
            r.tracks,
            r.mota,
            r.idf1,
            r.hota,
            r.idsw,
            r.trips,
            percent(r.movement_error),
            r.seconds
        );
    }
    let header = |page: &mut String, first: &str| {
        let _ = write!(page, "| {first} | truth |");
        for r in runs {
            let _ = write!(page, " {} |", r.result.method);
        }
        let _ = write!(page, "\n| --- | --- |");
        for _ in runs {
            let _ = write!(page, " --- |");
        }
        page.push('\n');
    };

    // Turning movements beside the truth's.
    let _ = writeln!(
        page,
        "\n## Turning movements\n\nComplete trips (first seen in one arm, last seen in \
         another; an arm is its road and footways from {} m out, past the crosswalks), all \
         classes; the turning error is Σ |count − truth| over the movements \
         divided by the truth's trips. Objects first and last seen in one arm (still queued, \
         turned back out of view, or a track broken at the junction) are not turning \
         movements: they are counted apart, below the line.\n",
        super::ARM_START_M
    );
    header(&mut page, "movement");
    let per_run: Vec<BTreeMap<(String, String), u64>> =
        runs.iter().map(|r| movements(&r.analysis)).collect();
    let t = movements(truth);
    let keys: BTreeSet<&(String, String)> = t
        .keys()
        .chain(per_run.iter().flat_map(|m| m.keys()))
        .collect();
    if keys.is_empty() {
        let _ = write!(page, "| (no complete trip) | 0 |");
        for _ in runs {
            let _ = write!(page, " 0 |");
        }
        page.push('\n');
    }
    for k in keys {
        let _ = write!(
            page,
            "| {} → {} | {} |",
            k.0,
            k.1,
            t.get(k).copied().unwrap_or(0)
        );
        for m in &per_run {
            let _ = write!(page, " {} |", m.get(k).copied().unwrap_or(0));
        }
        page.push('\n');
    }
    let _ = write!(page, "| **complete trips** | **{}** |", trips(truth));
    for r in runs {
        let _ = write!(page, " **{}** |", r.result.trips);
    }
    let _ = write!(page, "\n| turning error | – |");
    for r in runs {
        let _ = write!(page, " {} |", percent(r.result.movement_error));
    }
    let incomplete = |a: &Analysis| a.od_incomplete.iter().map(|o| o.count).sum::<u64>();
    let _ = write!(
        page,
        "\n| incomplete (one arm only) | {} |",
        incomplete(truth)
    );
    for r in runs {
        let _ = write!(page, " {} |", incomplete(&r.analysis));
    }
    page.push('\n');

    // Line counts beside the truth's.
    let _ = writeln!(
        page,
        "\n## Counts\n\nObjects crossing each counting line (16 m from the centre on each \
         arm), per direction, all classes; each object at most once per line and direction, \
         fragments stitched first.\n"
    );
    header(&mut page, "line, direction");
    let per_run: Vec<BTreeMap<(String, String), u64>> =
        runs.iter().map(|r| line_counts(&r.analysis)).collect();
    let t = line_counts(truth);
    let keys: BTreeSet<&(String, String)> = t
        .keys()
        .chain(per_run.iter().flat_map(|m| m.keys()))
        .collect();
    for k in keys {
        let _ = write!(
            page,
            "| {} {} | {} |",
            k.0,
            k.1.replace('_', " "),
            t.get(k).copied().unwrap_or(0)
        );
        for m in &per_run {
            let _ = write!(page, " {} |", m.get(k).copied().unwrap_or(0));
        }
        page.push('\n');
    }

    let _ = writeln!(
        page,
        "\nGround-truth turning movements by class:\n\n| origin | destination | class | count |\n| --- | --- | --- | --- |"
    );
    od_table(&mut page, truth);

    for run in runs {
        let name = &run.result.method;
        let _ = writeln!(page, "\n## {name}\n");
        let _ = writeln!(page, "![{name} overlay]({name}/overlay_frame.png)\n");
        let whole = match &run.overlay {
            Some(f) => format!("`{name}/{f}`"),
            None => format!(
                "`roadtrack render sequence --tracks {name}/tracks.txt --truth sequence -o \
                 {name}.mp4`"
            ),
        };
        let _ = writeln!(
            page,
            "Left: tracks; right: ground truth (frame {}). Full sequence: {whole}.\n",
            facts.frames / 2
        );
        let _ = writeln!(page, "![{name} trajectories]({name}/trajectories.png)\n");
        let _ = writeln!(
            page,
            "Turning movements (complete trips per origin → destination arm):\n"
        );
        let _ = writeln!(
            page,
            "| origin | destination | class | count |\n| --- | --- | --- | --- |"
        );
        od_table(&mut page, &run.analysis);
        let _ = writeln!(page, "\n```text\n{}```", run.metrics);
    }
    page
}

/// The complete trips of `a` as table rows (under a header already written), then the
/// objects first and last seen in one arm, apart: they are not turning movements.
fn od_table(out: &mut String, a: &Analysis) {
    if a.od.is_empty() {
        let _ = writeln!(out, "| (no complete trip in the observed time) | | | 0 |");
    }
    for o in &a.od {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} |",
            o.origin, o.destination, o.class, o.count
        );
    }
    if !a.od_incomplete.is_empty() {
        let list: Vec<String> = a
            .od_incomplete
            .iter()
            .map(|o| format!("{} {} in {}", o.count, o.class, o.origin))
            .collect();
        let _ = writeln!(
            out,
            "\nIncomplete (first and last seen in the same arm, not counted): {}.",
            list.join(", ")
        );
    }
}
