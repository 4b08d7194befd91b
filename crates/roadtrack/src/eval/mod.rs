//! Evaluation of tracker output against ground truth (`roadtrack evaluate`).
//!
//! - [`evaluate`]: CLEAR MOT, identity and HOTA metrics with TrackEval's exact definitions
//!   and MOTChallenge preprocessing ([`preprocess`]), per class and combined
//!   (see `docs/EVALUATION.md` for the multi-class rules);
//! - [`ospa`]: OSPA and GOSPA distances between point sets, for the filters;
//! - [`papers`]: the measures of the three papers (correct-match rate, position and speed
//!   RMSE, detection table, occlusion separation success).
//!
//! Inputs are the rows the MOTChallenge readers return ([`crate::io::mot`]); the metrics go
//! through them frame by frame and keep only per-frame matrices and per-id-pair counts.

mod clear;
#[cfg(test)]
mod golden_tests;
mod hota;
mod identity;
pub mod ospa;
pub mod papers;
mod preprocess;

pub use clear::ClearMetrics;
pub use hota::{HotaCurves, HotaMetrics, N_ALPHA, alphas};
pub use identity::IdentityMetrics;

use crate::class::ObjectClass;
use crate::error::{Error, Result};
use crate::io::mot::{MotGtRow, MotTrackRow};
use crate::track_point::TrackPoint;
use preprocess::{GtBox, Selection, TrBox};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashSet};

/// FxHash (rustc's hasher): the id-pair maps are hashed millions of times and need no
/// protection against adversarial keys. Iteration order never reaches a result unsorted.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct FxHasher(u64);

impl std::hash::Hasher for FxHasher {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u64(&mut self, w: u64) {
        self.0 = (self.0.rotate_left(5) ^ w).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_usize(&mut self, w: usize) {
        self.write_u64(w as u64);
    }
    fn finish(&self) -> u64 {
        self.0
    }
}

/// A hash map with [`FxHasher`].
pub(crate) type FastMap<K, V> =
    std::collections::HashMap<K, V, std::hash::BuildHasherDefault<FxHasher>>;

/// Which classes are evaluated and how tracker boxes are assigned to them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum ClassMode {
    /// MOTChallenge (TrackEval `MotChallenge2DBox`, MOT17): only pedestrians (class 1) are
    /// evaluated; every tracker box takes part whatever its class.
    #[default]
    #[cfg_attr(feature = "clap", value(help = "TrackEval MOT17: pedestrians only"))]
    Pedestrian,
    /// Each class of [`EvalConfig::classes`] that occurs in the ground truth or the tracks
    /// is evaluated on its own with the tracker boxes of that class; the headline numbers
    /// combine the classes by summing counts (TrackEval's "detection averaged" combination),
    /// and [`EvalReport::class_averaged`] holds the mean over classes.
    #[cfg_attr(
        feature = "clap",
        value(help = "Each class evaluated on its own, then combined")
    )]
    PerClass,
    /// The classes of [`EvalConfig::classes`] are merged into one; every tracker box takes
    /// part whatever its class.
    #[cfg_attr(
        feature = "clap",
        value(
            name = "agnostic",
            alias = "class-agnostic",
            help = "All listed classes merged into one"
        )
    )]
    ClassAgnostic,
}

/// Parameters of [`evaluate`]. `Default` is TrackEval's MOT17 pedestrian evaluation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EvalConfig {
    /// How classes are handled. Default [`ClassMode::Pedestrian`].
    pub mode: ClassMode,
    /// MOT17 class numbers evaluated in [`ClassMode::PerClass`] and
    /// [`ClassMode::ClassAgnostic`]. Default `[1, 3, 4, 5, 6]` (pedestrian, car, bicycle,
    /// motorbike, other vehicle — what `roadtrack simulate` writes).
    pub classes: Vec<u32>,
    /// Ground-truth classes whose matched tracker boxes are removed before evaluation.
    /// Default `[2, 7, 8, 12]` (person on vehicle, static person, distractor, reflection), as
    /// TrackEval for MOT17.
    pub distractor_classes: Vec<u32>,
    /// Run MOTChallenge preprocessing (distractor removal and the class filter). Default
    /// true; false is TrackEval's `DO_PREPROC = False`: every `consider = 1` row is
    /// evaluated and no tracker box is removed.
    pub preprocess: bool,
    /// IoU a match needs in CLEAR MOT and identity. Default 0.5 (TrackEval).
    pub iou_threshold: f64,
    /// Length of the sequence in frames (`seqLength` of `seqinfo.ini`); `None` = the last
    /// frame found in either input. Only `CLR_Frames` and `FP_per_frame` depend on it.
    pub num_frames: Option<u32>,
}

impl Default for EvalConfig {
    fn default() -> Self {
        Self {
            mode: ClassMode::Pedestrian,
            classes: vec![1, 3, 4, 5, 6],
            distractor_classes: vec![2, 7, 8, 12],
            preprocess: true,
            iou_threshold: 0.5,
            num_frames: None,
        }
    }
}

impl crate::config::Validate for EvalConfig {
    fn validate(&self) -> crate::error::Result<()> {
        EvalConfig::validate(self)
    }
}

impl EvalConfig {
    /// Checks ranges.
    ///
    /// # Errors
    /// A threshold outside `(0, 1]`, an empty class list in a mode that uses it, a class
    /// listed both as evaluated and as distractor.
    pub fn validate(&self) -> Result<()> {
        if !(self.iou_threshold > 0.0 && self.iou_threshold <= 1.0) {
            return Err(Error::config(
                "EvalConfig",
                "iou_threshold",
                format!("{} is outside (0, 1]", self.iou_threshold),
            ));
        }
        if self.mode != ClassMode::Pedestrian && self.classes.is_empty() {
            return Err(Error::config(
                "EvalConfig",
                "classes",
                "no class to evaluate",
            ));
        }
        if let Some(c) = self
            .evaluated_classes()
            .iter()
            .find(|c| self.distractor_classes.contains(c))
        {
            return Err(Error::config(
                "EvalConfig",
                "classes",
                format!("class {c} is both evaluated and a distractor"),
            ));
        }
        if self.num_frames == Some(0) {
            return Err(Error::config(
                "EvalConfig",
                "num_frames",
                "must be at least 1",
            ));
        }
        if let Some(n) = self.num_frames {
            crate::limits::at_most(n, crate::limits::MAX_FRAME, "frames in a sequence")
                .map_err(|m| Error::config("EvalConfig", "num_frames", m))?;
        }
        Ok(())
    }

    fn evaluated_classes(&self) -> Vec<u32> {
        match self.mode {
            ClassMode::Pedestrian => vec![1],
            _ => self.classes.clone(),
        }
    }
}

/// CLEAR MOT, identity and HOTA results for one class (or one combination of classes).
///
/// Serialised flat, with TrackEval's key names (`MOTA`, `IDF1`, `HOTA`, `HOTA(0)`, …) and the
/// HOTA curves under `per_alpha`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// CLEAR MOT.
    #[serde(flatten)]
    pub clear: ClearMetrics,
    /// Identity.
    #[serde(flatten)]
    pub identity: IdentityMetrics,
    /// HOTA.
    #[serde(flatten)]
    pub hota: HotaMetrics,
    /// Ground-truth boxes evaluated (after preprocessing).
    pub gt_dets: u64,
    /// Tracker boxes evaluated (after preprocessing).
    pub tracker_dets: u64,
    /// Ground-truth ids evaluated.
    pub gt_ids: u64,
    /// Tracker ids evaluated.
    pub tracker_ids: u64,
}

impl Metrics {
    fn combine(parts: &[&Metrics], class_average: bool) -> Metrics {
        let c: Vec<&ClearMetrics> = parts.iter().map(|m| &m.clear).collect();
        let i: Vec<&IdentityMetrics> = parts.iter().map(|m| &m.identity).collect();
        let h: Vec<&HotaMetrics> = parts.iter().map(|m| &m.hota).collect();
        Metrics {
            clear: if class_average {
                ClearMetrics::combine_class_average(&c)
            } else {
                ClearMetrics::combine_sum(&c)
            },
            identity: if class_average {
                IdentityMetrics::combine_class_average(&i)
            } else {
                IdentityMetrics::combine_sum(&i)
            },
            hota: if class_average {
                HotaMetrics::combine_class_average(&h)
            } else {
                HotaMetrics::combine_sum(&h)
            },
            gt_dets: parts.iter().map(|m| m.gt_dets).sum(),
            tracker_dets: parts.iter().map(|m| m.tracker_dets).sum(),
            gt_ids: parts.iter().map(|m| m.gt_ids).sum(),
            tracker_ids: parts.iter().map(|m| m.tracker_ids).sum(),
        }
    }
}

/// The result of [`evaluate`]: headline metrics at the top level (the keys INTERFACES.md
/// lists for `roadtrack evaluate --json`), then per class.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalReport {
    /// The class mode used.
    pub mode: ClassMode,
    /// Frames in the sequence.
    pub num_frames: u32,
    /// Headline metrics: the pedestrian class, the merged classes, or (per class) all
    /// classes combined by summing counts.
    #[serde(flatten)]
    pub summary: Metrics,
    /// Metrics per evaluated class name (`pedestrian`, `car`, …; `all` when classes are
    /// merged).
    pub per_class: BTreeMap<String, Metrics>,
    /// Per class only: every score averaged over the classes (TrackEval's "class averaged").
    pub class_averaged: Option<Metrics>,
}

/// Name of a MOT17 class number in reports.
pub fn class_name(mot17_id: u32) -> String {
    match mot17_id {
        6 => "non_mot_vehicle".to_owned(),
        7 => "static_person".to_owned(),
        9 => "static_vehicle".to_owned(),
        10 => "occluder".to_owned(),
        11 => "occluder_on_ground".to_owned(),
        c => ObjectClass::from_mot17_id(i64::from(c)).name().to_owned(),
    }
}

fn check_box(what: &str, frame: u32, id: u64, b: &crate::BBox) -> Result<()> {
    let finite = [b.left, b.top, b.width, b.height]
        .iter()
        .all(|v| v.is_finite());
    if !finite || b.width < 0.0 || b.height < 0.0 {
        return Err(Error::Invalid(format!(
            "{what}: frame {frame}, id {id}: box {:?} has a negative or non-finite value",
            (b.left, b.top, b.width, b.height)
        )));
    }
    if frame == 0 {
        return Err(Error::Invalid(format!(
            "{what}: id {id} is in frame 0; frames start at 1"
        )));
    }
    Ok(())
}

/// Sorts by (frame, id) (stable; a no-op on reader output) and rejects duplicates.
fn sort_and_check<T>(what: &str, rows: &mut [T], key: impl Fn(&T) -> (u32, u64)) -> Result<()> {
    if !rows.windows(2).all(|w| key(&w[0]) <= key(&w[1])) {
        rows.sort_by_key(&key);
    }
    if let Some(w) = rows.windows(2).find(|w| key(&w[0]) == key(&w[1])) {
        let (f, id) = key(&w[0]);
        return Err(Error::Invalid(format!(
            "{what}: id {id} appears twice in frame {f}"
        )));
    }
    Ok(())
}

/// Evaluates class-less tracks (MOTChallenge tracks files carry no class) against ground
/// truth.
///
/// Rows may come in any order (they are grouped by frame, and by id within a frame).
///
/// # Errors
/// An id twice in one frame, a negative or non-finite box, frame 0, a row after
/// `num_frames`, a ground-truth class above 12 while preprocessing (TrackEval rejects them),
/// [`ClassMode::PerClass`] (it needs classified tracks: use [`evaluate_classified`]), an
/// invalid config.
pub fn evaluate(gt: &[MotGtRow], tracks: &[MotTrackRow], cfg: &EvalConfig) -> Result<EvalReport> {
    if cfg.mode == ClassMode::PerClass {
        return Err(Error::Invalid(
            "per-class evaluation needs the tracker's classes (a trajectories CSV); \
             MOTChallenge tracks files have none: evaluate pedestrians or class-agnostic"
                .to_owned(),
        ));
    }
    let tr: Vec<TrBox> = tracks
        .iter()
        .map(|r| TrBox {
            frame: r.frame,
            id: r.id,
            bbox: r.bbox,
            class: None,
        })
        .collect();
    evaluate_boxes(gt, tr, cfg)
}

/// Evaluates tracks whose class is known: `track_classes[i]` is the MOT17 class number of
/// `tracks[i]` (see [`ObjectClass::mot17_id`]). Needed for [`ClassMode::PerClass`].
///
/// # Errors
/// As [`evaluate`] (per-class mode allowed), and `track_classes` of the wrong length.
pub fn evaluate_classified(
    gt: &[MotGtRow],
    tracks: &[MotTrackRow],
    track_classes: &[u32],
    cfg: &EvalConfig,
) -> Result<EvalReport> {
    if track_classes.len() != tracks.len() {
        return Err(Error::Invalid(format!(
            "{} track classes for {} track rows",
            track_classes.len(),
            tracks.len()
        )));
    }
    let tr: Vec<TrBox> = tracks
        .iter()
        .zip(track_classes)
        .map(|(r, &c)| TrBox {
            frame: r.frame,
            id: r.id,
            bbox: r.bbox,
            class: Some(c),
        })
        .collect();
    evaluate_boxes(gt, tr, cfg)
}

/// Tracks rows and their MOT17 classes from tracker output points (for example a
/// trajectories CSV read with [`crate::io::trajectories::read_trajectories`]), ready for
/// [`evaluate_classified`].
pub fn rows_from_points(points: &[TrackPoint]) -> (Vec<MotTrackRow>, Vec<u32>) {
    points
        .iter()
        .map(|p| {
            (
                MotTrackRow {
                    frame: p.frame,
                    id: p.id,
                    bbox: p.bbox,
                    conf: p.score,
                },
                p.class.mot17_id(),
            )
        })
        .unzip()
}

fn evaluate_boxes(gt: &[MotGtRow], mut tr: Vec<TrBox>, cfg: &EvalConfig) -> Result<EvalReport> {
    cfg.validate()?;
    let mut gtb: Vec<GtBox> = gt
        .iter()
        .map(|r| GtBox {
            frame: r.frame,
            id: r.id,
            bbox: r.bbox,
            consider: r.consider,
            class: r.class,
        })
        .collect();
    for r in &gtb {
        check_box("ground truth", r.frame, r.id, &r.bbox)?;
        if cfg.preprocess && !(1..=12).contains(&r.class) {
            return Err(Error::Invalid(format!(
                "ground truth: frame {}, id {}: class {} is not a MOT17 class (1–12); \
                 TrackEval rejects it when preprocessing",
                r.frame, r.id, r.class
            )));
        }
    }
    for r in &tr {
        check_box("tracks", r.frame, r.id, &r.bbox)?;
    }
    sort_and_check("ground truth", &mut gtb, |r| (r.frame, r.id))?;
    sort_and_check("tracks", &mut tr, |r| (r.frame, r.id))?;
    let last = gtb
        .iter()
        .map(|r| r.frame)
        .chain(tr.iter().map(|r| r.frame))
        .max()
        .unwrap_or(0);
    // The per-frame tables below have one entry per frame; the readers bound frames, rows
    // built in code are checked here.
    crate::limits::at_most(last, crate::limits::MAX_FRAME, "largest frame number")
        .map_err(|m| Error::Invalid(format!("a row's frame: {m}")))?;
    let num_frames = match cfg.num_frames {
        Some(n) if n < last => {
            return Err(Error::Invalid(format!(
                "a row is in frame {last}, after the sequence's last frame {n}"
            )));
        }
        Some(n) => n,
        None => last,
    };
    let run = |gt_classes: &[u32], tracker_class: Option<u32>| -> Result<Metrics> {
        let sel = Selection {
            gt_classes,
            tracker_class,
            distractors: &cfg.distractor_classes,
            preprocess: cfg.preprocess,
        };
        let seq = preprocess::preprocess(&gtb, &tr, num_frames, &sel)?;
        Ok(Metrics {
            clear: clear::clear(&seq, cfg.iou_threshold)?,
            identity: identity::identity(&seq, cfg.iou_threshold)?,
            hota: hota::hota(&seq)?,
            gt_dets: seq.n_gt_dets as u64,
            tracker_dets: seq.n_tr_dets as u64,
            gt_ids: seq.n_gt_ids as u64,
            tracker_ids: seq.n_tr_ids as u64,
        })
    };
    let mut per_class = BTreeMap::new();
    let (summary, class_averaged) = match cfg.mode {
        ClassMode::Pedestrian => {
            let m = run(&[1], None)?;
            per_class.insert(class_name(1), m.clone());
            (m, None)
        }
        ClassMode::ClassAgnostic => {
            let m = run(&cfg.classes, None)?;
            per_class.insert("all".to_owned(), m.clone());
            (m, None)
        }
        ClassMode::PerClass => {
            let present: HashSet<u32> = gtb
                .iter()
                .map(|r| r.class)
                .chain(tr.iter().filter_map(|r| r.class))
                .collect();
            let mut classes: Vec<u32> = cfg
                .classes
                .iter()
                .copied()
                .filter(|c| present.contains(c))
                .collect();
            classes.sort_unstable();
            classes.dedup();
            let mut parts = Vec::new();
            for c in classes {
                let m = run(&[c], Some(c))?;
                per_class.insert(class_name(c), m.clone());
                parts.push(m);
            }
            let refs: Vec<&Metrics> = parts.iter().collect();
            (
                Metrics::combine(&refs, false),
                Some(Metrics::combine(&refs, true)),
            )
        }
    };
    Ok(EvalReport {
        mode: cfg.mode,
        num_frames,
        summary,
        per_class,
        class_averaged,
    })
}

/// A readable table of the report: one row per class (and the combinations), the headline
/// columns of MOTChallenge leaderboards.
pub fn format_table(report: &EvalReport) -> String {
    let mut rows: Vec<(String, &Metrics)> = report
        .per_class
        .iter()
        .map(|(k, m)| (k.clone(), m))
        .collect();
    if report.mode == ClassMode::PerClass {
        rows.push(("combined".to_owned(), &report.summary));
        if let Some(ca) = &report.class_averaged {
            rows.push(("class average".to_owned(), ca));
        }
    }
    let pct = |x: f64| format!("{:.3}", 100.0 * x);
    let header = [
        "class", "HOTA", "DetA", "AssA", "LocA", "MOTA", "MOTP", "IDF1", "IDP", "IDR", "TP", "FP",
        "FN", "IDSW", "Frag", "MT", "PT", "ML",
    ];
    let mut table: Vec<Vec<String>> = vec![header.iter().map(|s| (*s).to_owned()).collect()];
    for (name, m) in rows {
        let c = &m.clear;
        table.push(vec![
            name,
            pct(m.hota.HOTA),
            pct(m.hota.DetA),
            pct(m.hota.AssA),
            pct(m.hota.LocA),
            pct(c.MOTA),
            pct(c.MOTP),
            pct(m.identity.IDF1),
            pct(m.identity.IDP),
            pct(m.identity.IDR),
            c.CLR_TP.to_string(),
            c.CLR_FP.to_string(),
            c.CLR_FN.to_string(),
            c.IDSW.to_string(),
            c.Frag.to_string(),
            c.MT.to_string(),
            c.PT.to_string(),
            c.ML.to_string(),
        ]);
    }
    let widths: Vec<usize> = (0..header.len())
        .map(|j| {
            table
                .iter()
                .map(|r| r[j].chars().count())
                .max()
                .unwrap_or(0)
        })
        .collect();
    let mut out = format!(
        "{} frames, mode {:?}; scores in %\n",
        report.num_frames, report.mode
    );
    for (i, r) in table.iter().enumerate() {
        let cells: Vec<String> = r
            .iter()
            .enumerate()
            .map(|(j, s)| {
                if j == 0 {
                    format!("{s:<w$}", w = widths[j])
                } else {
                    format!("{s:>w$}", w = widths[j])
                }
            })
            .collect();
        out.push_str(cells.join("  ").trim_end());
        out.push('\n');
        if i == 0 {
            out.push_str(&"-".repeat(widths.iter().sum::<usize>() + 2 * (widths.len() - 1)));
            out.push('\n');
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BBox;

    fn gt(frame: u32, id: u64, left: f64) -> MotGtRow {
        MotGtRow {
            frame,
            id,
            bbox: BBox::new(left, 10.0, 20.0, 40.0),
            consider: true,
            class: 1,
            visibility: 1.0,
        }
    }

    fn tr(frame: u32, id: u64, left: f64) -> MotTrackRow {
        MotTrackRow {
            frame,
            id,
            bbox: BBox::new(left, 10.0, 20.0, 40.0),
            conf: 1.0,
        }
    }

    fn two_objects() -> Vec<MotGtRow> {
        (1..=10)
            .flat_map(|f| [gt(f, 1, 0.0), gt(f, 2, 100.0)])
            .collect()
    }

    #[test]
    fn tracker_equal_to_truth_scores_perfectly() -> Result<()> {
        let g = two_objects();
        let t: Vec<MotTrackRow> = g
            .iter()
            .map(|r| tr(r.frame, r.id + 7, r.bbox.left))
            .collect();
        let r = evaluate(&g, &t, &EvalConfig::default())?;
        let m = &r.summary;
        assert_eq!(
            (m.clear.MOTA, m.clear.MOTP, m.identity.IDF1),
            (1.0, 1.0, 1.0)
        );
        assert_eq!(
            (m.hota.HOTA, m.hota.DetA, m.hota.AssA, m.hota.LocA),
            (1.0, 1.0, 1.0, 1.0)
        );
        assert_eq!(
            (m.clear.TP, m.clear.FP, m.clear.FN, m.clear.IDSW),
            (20, 0, 0, 0)
        );
        assert_eq!((m.clear.MT, r.num_frames), (2, 10));
        Ok(())
    }

    #[test]
    fn an_id_swap_is_one_switch_per_object_and_halves_association() -> Result<()> {
        let g = two_objects();
        let t: Vec<MotTrackRow> = g
            .iter()
            .map(|r| {
                let swapped = r.frame > 5;
                let id = if swapped { 3 - r.id } else { r.id };
                tr(r.frame, id, r.bbox.left)
            })
            .collect();
        let m = evaluate(&g, &t, &EvalConfig::default())?.summary;
        assert_eq!(m.clear.IDSW, 2);
        assert_eq!(m.clear.MOTA, (20.0 - 2.0) / 20.0);
        assert_eq!((m.identity.IDTP, m.identity.IDF1), (10, 0.5));
        // Each match's tracker and ground-truth ids share 5 of 15 frames: AssA = 1/3.
        assert!((m.hota.AssA - 1.0 / 3.0).abs() < 1e-12);
        Ok(())
    }

    #[test]
    fn row_order_does_not_matter() -> Result<()> {
        let g = two_objects();
        let t: Vec<MotTrackRow> = g
            .iter()
            .map(|r| tr(r.frame, r.id, r.bbox.left + 3.0))
            .collect();
        let a = evaluate(&g, &t, &EvalConfig::default())?;
        let (mut g2, mut t2) = (g.clone(), t.clone());
        g2.reverse();
        t2.rotate_left(7);
        assert_eq!(evaluate(&g2, &t2, &EvalConfig::default())?, a);
        Ok(())
    }

    #[test]
    fn bad_inputs_are_clear_errors() {
        let g = two_objects();
        let cfg = EvalConfig::default();
        let cases: Vec<(Vec<MotGtRow>, Vec<MotTrackRow>, &str)> = vec![
            (
                g.clone(),
                vec![tr(1, 4, 0.0), tr(1, 4, 50.0)],
                "id 4 appears twice in frame 1",
            ),
            (
                vec![gt(2, 1, 0.0), gt(2, 1, 9.0)],
                vec![],
                "id 1 appears twice in frame 2",
            ),
            (
                g.clone(),
                vec![MotTrackRow {
                    frame: 1,
                    id: 1,
                    bbox: BBox::new(0.0, 0.0, -1.0, 5.0),
                    conf: 1.0,
                }],
                "negative or non-finite",
            ),
            (g.clone(), vec![tr(0, 1, 0.0)], "frame 0"),
            (
                vec![MotGtRow {
                    class: 13,
                    ..gt(1, 1, 0.0)
                }],
                vec![],
                "not a MOT17 class",
            ),
        ];
        for (g, t, msg) in cases {
            let e = evaluate(&g, &t, &cfg).expect_err(msg).to_string();
            assert!(e.contains(msg), "{e} does not say {msg:?}");
        }
        let short = EvalConfig {
            num_frames: Some(5),
            ..EvalConfig::default()
        };
        let e = evaluate(&g, &[], &short)
            .expect_err("frame beyond")
            .to_string();
        assert!(e.contains("after the sequence's last frame 5"), "{e}");
        let per_class = EvalConfig {
            mode: ClassMode::PerClass,
            ..EvalConfig::default()
        };
        assert!(evaluate(&g, &[], &per_class).is_err());
        assert!(evaluate_classified(&g, &[tr(1, 1, 0.0)], &[], &per_class).is_err());
    }

    #[test]
    fn empty_inputs_follow_trackeval() -> Result<()> {
        let cfg = EvalConfig::default();
        let none = evaluate(&[], &[], &cfg)?;
        assert_eq!(
            (
                none.num_frames,
                none.summary.clear.MOTA,
                none.summary.clear.MLR
            ),
            (0, 0.0, 1.0)
        );
        let g = two_objects();
        let no_tracks = evaluate(&g, &[], &cfg)?.summary;
        assert_eq!(
            (
                no_tracks.clear.FN,
                no_tracks.clear.ML,
                no_tracks.identity.IDFN
            ),
            (20, 2, 20)
        );
        assert_eq!((no_tracks.hota.HOTA, no_tracks.hota.LocA), (0.0, 1.0));
        let t: Vec<MotTrackRow> = g.iter().map(|r| tr(r.frame, r.id, r.bbox.left)).collect();
        let no_gt = evaluate(&[], &t, &cfg)?.summary;
        // TrackEval returns early: MOTA stays 0 rather than −FP.
        assert_eq!(
            (no_gt.clear.FP, no_gt.clear.MOTA, no_gt.identity.IDFP),
            (20, 0.0, 20)
        );
        Ok(())
    }

    #[test]
    fn per_class_counts_a_misclassified_box_in_both_classes() -> Result<()> {
        let mut g = two_objects();
        for r in g.iter_mut().filter(|r| r.id == 2) {
            r.class = 3;
        }
        let t: Vec<MotTrackRow> = g.iter().map(|r| tr(r.frame, r.id, r.bbox.left)).collect();
        // The car's tracker boxes are labelled pedestrian in frames 1–2.
        let classes: Vec<u32> = g
            .iter()
            .map(|r| if r.frame <= 2 { 1 } else { r.class })
            .collect();
        let cfg = EvalConfig {
            mode: ClassMode::PerClass,
            ..EvalConfig::default()
        };
        let r = evaluate_classified(&g, &t, &classes, &cfg)?;
        let (ped, car) = (&r.per_class["pedestrian"], &r.per_class["car"]);
        assert_eq!((ped.clear.TP, ped.clear.FP, ped.clear.FN), (10, 2, 0));
        assert_eq!((car.clear.TP, car.clear.FP, car.clear.FN), (8, 0, 2));
        assert_eq!(
            (r.summary.clear.TP, r.summary.clear.FP, r.summary.clear.FN),
            (18, 2, 2)
        );
        let ca = r.class_averaged.as_ref().map(|m| m.clear.MOTA);
        assert_eq!(ca, Some((ped.clear.MOTA + car.clear.MOTA) / 2.0));
        // Class-agnostic: every box matches.
        let agn = EvalConfig {
            mode: ClassMode::ClassAgnostic,
            ..EvalConfig::default()
        };
        assert_eq!(
            evaluate_classified(&g, &t, &classes, &agn)?
                .summary
                .clear
                .MOTA,
            1.0
        );
        Ok(())
    }

    #[test]
    fn report_has_the_interface_keys_and_a_table() -> Result<()> {
        let g = two_objects();
        let r = evaluate(&g, &[tr(1, 1, 0.0)], &EvalConfig::default())?;
        let v = serde_json::to_value(&r).map_err(|e| Error::Invalid(e.to_string()))?;
        for k in [
            "MOTA", "MOTP", "FP", "FN", "IDSW", "IDF1", "IDP", "IDR", "HOTA", "DetA", "AssA",
            "LocA",
        ] {
            assert!(v.get(k).is_some_and(|x| x.is_number()), "missing key {k}");
        }
        let t = format_table(&r);
        assert!(
            t.contains("pedestrian") && t.contains("HOTA") && t.contains("IDSW"),
            "{t}"
        );
        Ok(())
    }

    #[test]
    fn config_round_trips_through_toml_and_rejects_typos() {
        let c = EvalConfig::default();
        let text = toml::to_string(&c).unwrap_or_default();
        assert_eq!(toml::from_str::<EvalConfig>(&text).ok(), Some(c));
        assert!(toml::from_str::<EvalConfig>("iou_treshold = 0.4").is_err());
        let bad = EvalConfig {
            classes: vec![1, 8],
            mode: ClassMode::PerClass,
            ..EvalConfig::default()
        };
        assert!(bad.validate().is_err());
    }
}
