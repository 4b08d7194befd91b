//! MOTChallenge preprocessing (TrackEval `MotChallenge2DBox.get_preprocessed_seq_data`) and
//! its multi-class extension: turns ground-truth and tracker rows into per-frame id lists and
//! IoU matrices for one evaluated class (or set of classes).
//!
//! Per frame, in TrackEval's order:
//! 1. take the tracker boxes that compete for the evaluated class (all of them, or in
//!    per-class mode those of that class);
//! 2. match them to *every* ground-truth box of the frame (any class, `consider` 0 or 1):
//!    IoU below `0.5 − ε` is set to 0, a maximum-IoU linear assignment is solved, and
//!    pairs with IoU above ε are matches; tracker boxes matched to a distractor-class box
//!    are removed;
//! 3. keep the ground-truth rows with `consider = 1` whose class is evaluated;
//! 4. relabel ground-truth and tracker ids to `0..n` in increasing id order.
//!
//! Rows within a frame are ordered by id (the readers sort them so); TrackEval keeps file
//! order. The two agree whenever the files list each frame's rows by increasing id, and only
//! exactly tied assignments could differ otherwise.

use crate::assignment::max_score_assignment;
use crate::error::{Error, Result};
use crate::geometry::BBox;
use std::collections::BTreeMap;

/// `np.finfo(float).eps`, the tolerance TrackEval uses in its comparisons.
pub(crate) const EPS: f64 = f64::EPSILON;

/// One box entering preprocessing.
#[derive(Debug, Clone, Copy)]
pub(crate) struct GtBox {
    pub frame: u32,
    pub id: u64,
    pub bbox: BBox,
    pub consider: bool,
    pub class: u32,
}

/// One tracker box entering preprocessing.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TrBox {
    pub frame: u32,
    pub id: u64,
    pub bbox: BBox,
    /// MOT17 class number, when the tracker classifies.
    pub class: Option<u32>,
}

/// One frame after preprocessing: contiguous ids and the IoU matrix (gt-major).
#[derive(Debug, Clone, Default)]
pub(crate) struct EvalFrame {
    pub gt: Vec<usize>,
    pub tr: Vec<usize>,
    /// `sim[g * tr.len() + t]` = IoU of `gt[g]` and `tr[t]`.
    pub sim: Vec<f64>,
}

impl EvalFrame {
    pub fn similarity(&self, g: usize, t: usize) -> f64 {
        self.sim[g * self.tr.len() + t]
    }
}

/// A preprocessed sequence for one evaluated class (TrackEval's `data` dict).
#[derive(Debug, Clone, Default)]
pub(crate) struct EvalSequence {
    pub frames: Vec<EvalFrame>,
    pub n_gt_ids: usize,
    pub n_tr_ids: usize,
    pub n_gt_dets: usize,
    pub n_tr_dets: usize,
}

impl EvalSequence {
    pub fn n_timesteps(&self) -> usize {
        self.frames.len()
    }
}

/// Which boxes take part in one evaluation.
pub(crate) struct Selection<'a> {
    /// Ground-truth classes evaluated (kept after preprocessing).
    pub gt_classes: &'a [u32],
    /// `Some(c)`: only tracker boxes of class `c`; `None`: every tracker box.
    pub tracker_class: Option<u32>,
    /// Classes whose matched tracker boxes are removed.
    pub distractors: &'a [u32],
    /// Run steps 2 (distractor removal) and the class filter of step 3. Without it every
    /// `consider = 1` ground-truth row is kept, as TrackEval with `DO_PREPROC = False`.
    pub preprocess: bool,
}

/// TrackEval's `_calculate_box_ious` for xywh boxes, one pair.
pub(crate) fn box_iou(a: &BBox, b: &BBox) -> f64 {
    let (ax1, ay1) = (a.left + a.width, a.top + a.height);
    let (bx1, by1) = (b.left + b.width, b.top + b.height);
    let iw = (ax1.min(bx1) - a.left.max(b.left)).max(0.0);
    let ih = (ay1.min(by1) - a.top.max(b.top)).max(0.0);
    let mut inter = iw * ih;
    let area_a = (ax1 - a.left) * (ay1 - a.top);
    let area_b = (bx1 - b.left) * (by1 - b.top);
    let mut union = area_a + area_b - inter;
    if area_a <= EPS || area_b <= EPS || union <= EPS {
        inter = 0.0;
    }
    if union <= EPS {
        union = 1.0;
    }
    inter / union
}

/// Rows of one frame: `(frame, range)` over a slice sorted by frame.
pub(crate) fn frame_ranges<T>(
    rows: &[T],
    frame_of: impl Fn(&T) -> u32,
) -> Vec<(u32, std::ops::Range<usize>)> {
    let mut out = Vec::new();
    let mut start = 0;
    while start < rows.len() {
        let f = frame_of(&rows[start]);
        let mut end = start + 1;
        while end < rows.len() && frame_of(&rows[end]) == f {
            end += 1;
        }
        out.push((f, start..end));
        start = end;
    }
    out
}

/// Preprocesses one class over `n_frames` frames. `gt` and `tr` are sorted by (frame, id).
pub(crate) fn preprocess(
    gt: &[GtBox],
    tr: &[TrBox],
    n_frames: u32,
    sel: &Selection<'_>,
) -> Result<EvalSequence> {
    let gt_ranges = frame_ranges(gt, |r| r.frame);
    let tr_ranges = frame_ranges(tr, |r| r.frame);
    let (mut gi, mut ti) = (0, 0);
    // Frames with raw (file) ids first; relabelled at the end.
    let mut raw_frames: Vec<(Vec<u64>, Vec<u64>, Vec<f64>)> = Vec::with_capacity(n_frames as usize);
    let mut gt_ids = BTreeMap::new();
    let mut tr_ids = BTreeMap::new();
    for frame in 1..=n_frames {
        let g_rows: &[GtBox] = match gt_ranges.get(gi) {
            Some((f, r)) if *f == frame => {
                gi += 1;
                &gt[r.clone()]
            }
            _ => &[],
        };
        let t_all: &[TrBox] = match tr_ranges.get(ti) {
            Some((f, r)) if *f == frame => {
                ti += 1;
                &tr[r.clone()]
            }
            _ => &[],
        };
        let t_rows: Vec<&TrBox> = t_all
            .iter()
            .filter(|t| sel.tracker_class.is_none() || t.class == sel.tracker_class)
            .collect();
        let (ng, nt) = (g_rows.len(), t_rows.len());
        let mut sim = vec![0.0; ng * nt];
        for (g, gb) in g_rows.iter().enumerate() {
            for (t, tb) in t_rows.iter().enumerate() {
                sim[g * nt + t] = box_iou(&gb.bbox, &tb.bbox);
            }
        }
        let mut remove = vec![false; nt];
        // Without a distractor in the frame the assignment cannot remove anything.
        let any_distractor = g_rows.iter().any(|g| sel.distractors.contains(&g.class));
        if sel.preprocess && any_distractor && ng > 0 && nt > 0 {
            let scores: Vec<f64> = sim
                .iter()
                .map(|&s| if s < 0.5 - EPS { 0.0 } else { s })
                .collect();
            for (g, t) in max_score_assignment(&scores, ng, nt)? {
                if scores[g * nt + t] > EPS && sel.distractors.contains(&g_rows[g].class) {
                    remove[t] = true;
                }
            }
        }
        let keep_g: Vec<usize> = (0..ng)
            .filter(|&g| {
                let r = &g_rows[g];
                r.consider && (!sel.preprocess || sel.gt_classes.contains(&r.class))
            })
            .collect();
        let keep_t: Vec<usize> = (0..nt).filter(|&t| !remove[t]).collect();
        let mut fsim = Vec::with_capacity(keep_g.len() * keep_t.len());
        for &g in &keep_g {
            for &t in &keep_t {
                fsim.push(sim[g * nt + t]);
            }
        }
        let fg: Vec<u64> = keep_g.iter().map(|&g| g_rows[g].id).collect();
        let ft: Vec<u64> = keep_t.iter().map(|&t| t_rows[t].id).collect();
        for &id in &fg {
            gt_ids.insert(id, 0usize);
        }
        for &id in &ft {
            tr_ids.insert(id, 0usize);
        }
        raw_frames.push((fg, ft, fsim));
    }
    if gi != gt_ranges.len() || ti != tr_ranges.len() {
        return Err(Error::Invalid(format!(
            "evaluation: rows beyond the last frame {n_frames}"
        )));
    }
    for (i, v) in gt_ids.values_mut().enumerate() {
        *v = i;
    }
    for (i, v) in tr_ids.values_mut().enumerate() {
        *v = i;
    }
    let mut seq = EvalSequence {
        n_gt_ids: gt_ids.len(),
        n_tr_ids: tr_ids.len(),
        ..Default::default()
    };
    for (fg, ft, sim) in raw_frames {
        seq.n_gt_dets += fg.len();
        seq.n_tr_dets += ft.len();
        seq.frames.push(EvalFrame {
            gt: fg.iter().map(|id| gt_ids[id]).collect(),
            tr: ft.iter().map(|id| tr_ids[id]).collect(),
            sim,
        });
    }
    Ok(seq)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn g(frame: u32, id: u64, left: f64, class: u32, consider: bool) -> GtBox {
        GtBox {
            frame,
            id,
            bbox: BBox::new(left, 0.0, 10.0, 10.0),
            consider,
            class,
        }
    }

    fn t(frame: u32, id: u64, left: f64) -> TrBox {
        TrBox {
            frame,
            id,
            bbox: BBox::new(left, 0.0, 10.0, 10.0),
            class: None,
        }
    }

    const PED: Selection<'static> = Selection {
        gt_classes: &[1],
        tracker_class: None,
        distractors: &[2, 7, 8, 12],
        preprocess: true,
    };

    #[test]
    fn iou_follows_trackeval_on_degenerate_boxes() {
        let a = BBox::new(0.0, 0.0, 10.0, 10.0);
        assert_eq!(box_iou(&a, &BBox::new(5.0, 0.0, 10.0, 10.0)), 50.0 / 150.0);
        assert_eq!(box_iou(&a, &BBox::new(2.0, 2.0, 0.0, 4.0)), 0.0);
        assert_eq!(box_iou(&BBox::default(), &BBox::default()), 0.0);
    }

    #[test]
    fn tracker_box_on_a_distractor_is_removed_and_ignored_gt_is_dropped() -> Result<()> {
        let gt = [
            g(1, 1, 0.0, 1, true),
            g(1, 2, 100.0, 8, true),  // distractor
            g(1, 3, 200.0, 1, false), // consider = 0
            g(1, 4, 300.0, 3, true),  // car: not evaluated, not a distractor
        ];
        let tr = [
            t(1, 10, 0.0),
            t(1, 11, 101.0),
            t(1, 12, 200.0),
            t(1, 13, 300.0),
        ];
        let s = preprocess(&gt, &tr, 1, &PED)?;
        assert_eq!(
            (s.n_gt_dets, s.n_tr_dets, s.n_gt_ids, s.n_tr_ids),
            (1, 3, 1, 3)
        );
        // Tracker 11 (on the distractor) is gone; 12 (on the ignored row) and 13 (on the car)
        // stay and will count as false positives, as in TrackEval.
        assert_eq!(s.frames[0].tr, [0, 1, 2]);
        assert_eq!(s.frames[0].similarity(0, 0), 1.0);
        Ok(())
    }

    #[test]
    fn ids_are_relabelled_in_increasing_order_and_empty_frames_kept() -> Result<()> {
        let gt = [g(1, 7, 0.0, 1, true), g(3, 5, 0.0, 1, true)];
        let tr = [t(3, 40, 0.0)];
        let s = preprocess(&gt, &tr, 4, &PED)?;
        assert_eq!(s.n_timesteps(), 4);
        assert_eq!(s.frames[0].gt, [1]);
        assert_eq!(s.frames[2].gt, [0]);
        assert!(s.frames[1].gt.is_empty() && s.frames[3].tr.is_empty());
        Ok(())
    }

    #[test]
    fn rows_after_the_last_frame_are_an_error() {
        let gt = [g(5, 1, 0.0, 1, true)];
        assert!(preprocess(&gt, &[], 4, &PED).is_err());
    }
}
