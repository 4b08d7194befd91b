//! The learned detector's views of a frame and what is read from them: the pyramid's
//! shrunk level and its merge, the test-time mirrors and their average, the zoomed rows,
//! the nested-box rule, and peak decoding of the heat maps. Free functions over
//! [`HeatMaps`] and candidates; [`super::CenterNetDetector`] calls them.

use image::RgbImage;
use tract_onnx::prelude::tract_ndarray;

use super::config::{CenterNetConfig, ZOOM_OVERLAP_IOU};
use super::detector::HeatMaps;
use super::{CLASSES, STRIDE, channel_class};
use crate::detector::decode::Candidate;
use roadtrack::calibration::Calibration;
use roadtrack::class::ObjectClass;
use roadtrack::detect::nested::nested_in;
use roadtrack::geometry::{BBox, Point};
use roadtrack::likelihood::ScoreMap;

/// `image` shrunk `k` times by averaging `k × k` blocks (a partial block at the right or
/// bottom edge is dropped): pixel `(x, y)` covers frame px `[kx, kx + k) × [ky, ky + k)`, so
/// a position `p` in it is `k·p` in the frame.
pub fn shrink(image: &RgbImage, k: u32) -> RgbImage {
    let (w, h) = (image.width() / k, image.height() / k);
    let n = k * k;
    let (iw, k) = (image.width() as usize, k as usize);
    let raw = image.as_raw();
    // Choice: row slices, not `get_pixel` per sample, whose bounds checks made this 3.5 %
    // of a frame's time; the same sums.
    let mut out = Vec::with_capacity(w as usize * h as usize * 3);
    let mut acc = vec![0u32; w as usize * 3];
    for y in 0..h as usize {
        acc.fill(0);
        for dy in 0..k {
            let row = &raw[(y * k + dy) * iw * 3..][..w as usize * k * 3];
            for (a, block) in acc.chunks_exact_mut(3).zip(row.chunks_exact(3 * k)) {
                for px in block.chunks_exact(3) {
                    for c in 0..3 {
                        a[c] += u32::from(px[c]);
                    }
                }
            }
        }
        out.extend(acc.iter().map(|&a| ((a + n / 2) / n) as u8));
    }
    RgbImage::from_raw(w, h, out).unwrap_or_else(|| RgbImage::new(w, h))
}

/// The candidates of a two-level pyramid: `fine` from the frame, `coarse` from the frame
/// shrunk `k` times (in its own px). Coarse boxes are scaled to frame px and kept from
/// [`CenterNetConfig::coarse_min_side`] up, fine ones below
/// [`CenterNetConfig::fine_max_side`]; a fine vehicle box lying at least
/// [`CenterNetConfig::part_fraction`] inside a larger coarse vehicle box is dropped.
pub fn merge_levels(
    fine: Vec<Candidate>,
    coarse: Vec<Candidate>,
    k: u32,
    cfg: &CenterNetConfig,
) -> Vec<Candidate> {
    let kf = f64::from(k);
    let coarse: Vec<Candidate> = coarse
        .into_iter()
        .map(|c| Candidate {
            cx: c.cx * kf,
            cy: c.cy * kf,
            w: c.w * kf,
            h: c.h * kf,
            ..c
        })
        .filter(|c| c.w.max(c.h) >= cfg.coarse_min_side)
        .collect();
    let vehicle = |c: &Candidate| channel_class(c.class) != ObjectClass::Pedestrian;
    let mut out: Vec<Candidate> = fine
        .into_iter()
        .filter(|f| f.w.max(f.h) < cfg.fine_max_side)
        .filter(|f| {
            !vehicle(f)
                || !coarse.iter().any(|c| {
                    vehicle(c) && c.w * c.h > f.w * f.h && f.inside_fraction(c) >= cfg.part_fraction
                })
        })
        .collect();
    out.extend(coarse);
    out
}

/// `input` (`3 × h × w`, row-major) mirrored left–right (`x`) and/or upside down (`y`).
pub fn flip_input(input: &[f32], h: usize, w: usize, x: bool, y: bool) -> Vec<f32> {
    let mut out = Vec::with_capacity(input.len());
    for plane in input.chunks_exact(h * w).take(3) {
        for r in 0..h {
            let row = &plane[if y { h - 1 - r } else { r } * w..][..w];
            if x {
                out.extend(row.iter().rev());
            } else {
                out.extend_from_slice(row);
            }
        }
    }
    out
}

/// Folds the outputs of flipped inputs (`views`: heat, boxes, mirrored left–right, upside
/// down) into `heat` and `boxes` (each `1 × C × rows × cols`): per cell the mean over the
/// original and every view, each view read at the mirrored cell. Box channels: log width
/// and log height average as they are; the x offset `dx` of a centre at `4 (c + dx)` is
/// `1 − dx'` read at cell `cols − 1 − c` of a left–right view (the padded sides are
/// multiples of the stride, so mirroring maps `x` to `width − x`), `dy` likewise for an
/// upside-down view.
pub fn average_flipped(
    heat: &mut tract_ndarray::ArrayD<f32>,
    boxes: &mut tract_ndarray::ArrayD<f32>,
    views: &[(
        tract_ndarray::ArrayD<f32>,
        tract_ndarray::ArrayD<f32>,
        bool,
        bool,
    )],
) {
    fold_flipped(heat, views.iter().map(|(h, _, x, y)| (h, *x, *y)), false);
    fold_flipped(boxes, views.iter().map(|(_, b, x, y)| (b, *x, *y)), true);
}

/// One output of [`average_flipped`]: `out` becomes the mean of itself and each view read
/// at the mirrored cell; with `offsets`, channel 2 (`dx`) of a left–right view and channel
/// 3 (`dy`) of an upside-down one are read as `1 − v`.
fn fold_flipped<'a>(
    out: &mut tract_ndarray::ArrayD<f32>,
    views: impl Iterator<Item = (&'a tract_ndarray::ArrayD<f32>, bool, bool)> + Clone,
    offsets: bool,
) {
    use std::borrow::Cow;
    let shape = out.shape().to_vec();
    let (ch, rows, cols) = (shape[1], shape[2], shape[3]);
    let n = (views.clone().count() + 1) as f32;
    // Choice: flat row-major copies, not `IxDyn` indexing per cell, which cost a tenth of a
    // flipped frame's time; the sums run in the same order, so the result is the same.
    let views: Vec<(Cow<'a, [f32]>, bool, bool)> = views.map(|(m, x, y)| (flat(m), x, y)).collect();
    let mut folded: Vec<f32> = flat(out).into_owned();
    for k in 0..ch {
        for r in 0..rows {
            let row = (k * rows + r) * cols;
            for c in 0..cols {
                let mut sum = folded[row + c];
                for (m, x, y) in &views {
                    let rr = if *y { rows - 1 - r } else { r };
                    let cc = if *x { cols - 1 - c } else { c };
                    let v = m[(k * rows + rr) * cols + cc];
                    let turned = offsets && ((k == 2 && *x) || (k == 3 && *y));
                    sum += if turned { 1.0 - v } else { v };
                }
                folded[row + c] = sum / n;
            }
        }
    }
    match out.as_slice_mut() {
        Some(o) => o.copy_from_slice(&folded),
        None => out.iter_mut().zip(folded).for_each(|(o, v)| *o = v),
    }
}

/// The values of `a` in row-major order: borrowed when `a` is contiguous (a network's
/// outputs are), copied otherwise. Iterating an `ArrayD` value by value costs several times
/// a slice copy.
pub(super) fn flat(a: &tract_ndarray::ArrayD<f32>) -> std::borrow::Cow<'_, [f32]> {
    match a.as_slice() {
        Some(s) => std::borrow::Cow::Borrowed(s),
        None => std::borrow::Cow::Owned(a.iter().copied().collect()),
    }
}

/// `boxes` without those lying mostly inside a larger box of their group
/// ([`CenterNetConfig::nested`], [`roadtrack::detect::nested::nested`]); the order is kept.
/// A box of a class with its own lowest score ([`CenterNetConfig::class_min_score`]) that
/// scores under [`CenterNetConfig::min_score`], kept only by that floor, holds no other box.
// Choice: a floor lets in the low-scored boxes of one class (lorries at 0.2); the larger of
// them lying over a queue of cars took the cars' boxes by the nested rule, which keeps the
// larger box whatever the scores (the demo's seed 1, `--class-min-score lorry=0.2`: cars
// found 0.91 -> 0.86 before this rule, 0.91 with it; docs/DETECTION.md "Lowest score per
// class").
pub fn drop_nested(boxes: Vec<Candidate>, cfg: &CenterNetConfig) -> Vec<Candidate> {
    let judged: Vec<(BBox, bool)> = boxes
        .iter()
        .map(|c| {
            (
                BBox::from_centre(Point::new(c.cx, c.cy), c.w, c.h),
                channel_class(c.class) == ObjectClass::Pedestrian,
            )
        })
        .collect();
    let floors = cfg.class_min_score.by_channel();
    let containers: Vec<bool> = boxes
        .iter()
        .map(|c| floors.get(c.class).copied().flatten().is_none() || c.score >= cfg.min_score)
        .collect();
    boxes
        .into_iter()
        .zip(nested_in(&judged, &containers, &cfg.nested))
        .filter_map(|(c, n)| (!n).then_some(c))
        .collect()
}

/// `boxes` without second peaks on small vehicles ([`CenterNetConfig::second_peak_max_side`]):
/// best score first (ties in input order), a vehicle box (any vehicle class) whose longer
/// side is in `[second_peak_min_side, second_peak_max_side)` and whose centre lies inside a
/// vehicle box kept so far, grown `second_peak_grow` times about its centre, at an offset
/// along that box's longer side at least `second_peak_along` times the offset across it, is
/// dropped; pedestrians are never tested and test nothing. The order of the rest is kept.
pub fn drop_second_peaks(boxes: Vec<Candidate>, cfg: &CenterNetConfig) -> Vec<Candidate> {
    if cfg.second_peak_max_side <= 0.0 {
        return boxes;
    }
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    order.sort_by(|&a, &b| boxes[b].score.total_cmp(&boxes[a].score).then(a.cmp(&b)));
    let half = cfg.second_peak_grow / 2.0;
    let second_of = |c: &Candidate, k: &Candidate| {
        let (dx, dy) = ((c.cx - k.cx).abs(), (c.cy - k.cy).abs());
        let (along, across) = if k.w >= k.h { (dx, dy) } else { (dy, dx) };
        dx <= k.w * half && dy <= k.h * half && along >= cfg.second_peak_along * across
    };
    let mut kept: Vec<&Candidate> = Vec::new();
    let mut drop = vec![false; boxes.len()];
    for i in order {
        let c = &boxes[i];
        if channel_class(c.class) == ObjectClass::Pedestrian {
            continue;
        }
        let side = c.w.max(c.h);
        if (cfg.second_peak_min_side..cfg.second_peak_max_side).contains(&side)
            && kept.iter().any(|k| second_of(c, k))
        {
            drop[i] = true;
        } else {
            kept.push(c);
        }
    }
    boxes
        .into_iter()
        .zip(drop)
        .filter_map(|(c, d)| (!d).then_some(c))
        .collect()
}

/// Length of the car the zoom looks for, m.
// Choice: 4.5 m, a mid-size car: lorries and buses are larger and found without the zoom.
pub const ZOOM_CAR_LENGTH_M: f64 = 4.5;

/// The rows `[top, bottom)` of a `width × height` image through `calibration` in which a
/// car of [`ZOOM_CAR_LENGTH_M`] on the ground measures under `max_px` px: per row, at the
/// centre column, the larger of the image lengths of a step along the ground's two axes,
/// times the car's length. `None` when no row qualifies (rows above the horizon never do).
// Choice: ground distances only, heights ignored (a car's box is taller than its footprint
// in an oblique view, so the band errs towards zooming); the centre column stands for the
// row (on a flat ground plane the scale changes far more across rows than along them).
pub fn zoom_rows(
    calibration: &Calibration,
    width: u32,
    height: u32,
    max_px: f64,
) -> Option<(u32, u32)> {
    let cx = f64::from(width) / 2.0;
    let small = |y: u32| -> bool {
        let p = Point::new(cx, f64::from(y) + 0.5);
        let Some((gx, gy)) = calibration.ground_from_image(p) else {
            return false;
        };
        let step = |dx: f64, dy: f64| {
            calibration
                .image_from_ground(gx + dx, gy + dy)
                .map(|q| ((q.x - p.x).powi(2) + (q.y - p.y).powi(2)).sqrt())
        };
        match (step(1.0, 0.0), step(0.0, 1.0)) {
            (Some(a), Some(b)) if a.is_finite() && b.is_finite() => {
                ZOOM_CAR_LENGTH_M * a.max(b) < max_px
            }
            _ => false,
        }
    };
    let first = (0..height).find(|&y| small(y))?;
    let last = (0..height).rev().find(|&y| small(y))?;
    Some((first, last + 1))
}

/// The zoomed level as a pyramid level ([`super::ZoomMode::Level`]): the boxes of the
/// other levels (`levels`, before NMS) whose longer side is under `max_side` px and whose
/// centre lies in `rows` (frame px, `[top, bottom)`) are dropped, and `zoomed` (already
/// limited to those sizes and rows) joins them, so NMS sees one level per size.
// Choice: the size alone picks the level, as SNIP's ranges do (Singh & Davis 2018), so an
// object near the limit takes its box from one level or the other per frame. Averaging the
// two levels' boxes where both find an object scored less in the Python prototype
// (relaxation on the oblique intersection at PX 32: 0.560 against 0.582; docs/
// EXPERIMENTS.md "Zoom as a level").
pub fn replace_small(
    levels: &mut Vec<Candidate>,
    zoomed: Vec<Candidate>,
    rows: (f64, f64),
    max_side: f64,
) {
    levels.retain(|c| !(c.w.max(c.h) < max_side && c.cy >= rows.0 && c.cy < rows.1));
    levels.extend(zoomed);
}

/// Adds `zoomed` (best first) to `kept` (the other levels' boxes after NMS), each unless
/// it overlaps a box already there by IoU > [`ZOOM_OVERLAP_IOU`], whatever the class, up
/// to [`CenterNetConfig::max_detections`].
pub fn add_zoomed(kept: &mut Vec<Candidate>, zoomed: Vec<Candidate>, cfg: &CenterNetConfig) {
    for c in zoomed {
        if kept.len() >= cfg.max_detections {
            break;
        }
        if kept.iter().all(|k| k.iou(&c) <= ZOOM_OVERLAP_IOU) {
            kept.push(c);
        }
    }
}

/// The maximum of `channels` of `maps` per cell as a [`ScoreMap`].
pub fn score_map_of(maps: &HeatMaps, channels: &[usize]) -> ScoreMap {
    let n = maps.rows * maps.cols;
    let values = (0..n)
        .map(|i| {
            channels
                .iter()
                .filter(|&&c| c < CLASSES)
                .map(|&c| f64::from(maps.heat[c * n + i]))
                .fold(0.0, f64::max)
        })
        .collect();
    let half = STRIDE as f64 / 2.0;
    ScoreMap {
        origin_px: Point::new(half, half),
        stride_px: STRIDE as f64,
        cols: maps.cols,
        rows: maps.rows,
        values,
    }
}

/// Heat-map peaks (a cell at least as high as its 8 neighbours, ≥ its channel's
/// `min_score`) as boxes in image px: centre `4 (cell + offset)`, size `4 e^s`.
pub fn decode_peaks(maps: &HeatMaps, min_score: &[f64; CLASSES]) -> Vec<Candidate> {
    let (rows, cols) = (maps.rows, maps.cols);
    let n = rows * cols;
    let s = STRIDE as f64;
    let mut out = Vec::new();
    for k in 0..CLASSES {
        let plane = &maps.heat[k * n..(k + 1) * n];
        let min_score = min_score[k];
        for r in 0..rows {
            for c in 0..cols {
                let v = plane[r * cols + c];
                if f64::from(v) < min_score || !v.is_finite() {
                    continue;
                }
                let mut peak = true;
                'n: for dr in -1i64..=1 {
                    for dc in -1i64..=1 {
                        let (rr, cc) = (r as i64 + dr, c as i64 + dc);
                        if (dr, dc) == (0, 0)
                            || rr < 0
                            || cc < 0
                            || rr >= rows as i64
                            || cc >= cols as i64
                        {
                            continue;
                        }
                        let u = plane[rr as usize * cols + cc as usize];
                        // Ties: the first cell in raster order is the peak.
                        if u > v || (u == v && (dr < 0 || (dr == 0 && dc < 0))) {
                            peak = false;
                            break 'n;
                        }
                    }
                }
                if !peak {
                    continue;
                }
                let i = r * cols + c;
                let b = |j: usize| f64::from(maps.boxes[j * n + i]);
                let (lw, lh) = (b(0).clamp(-4.0, 6.0), b(1).clamp(-4.0, 6.0));
                out.push(Candidate {
                    cx: (c as f64 + b(2).clamp(-0.5, 1.5)) * s,
                    cy: (r as f64 + b(3).clamp(-0.5, 1.5)) * s,
                    w: s * lw.exp(),
                    h: s * lh.exp(),
                    class: k,
                    score: f64::from(v),
                    gain_scale: 1.0,
                });
            }
        }
    }
    out
}
