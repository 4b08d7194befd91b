//! Cutting a foreground region at the valleys of its column profile: people walking side
//! by side, whom background subtraction joins into one region (`[split] columns`).
//!
//! The profile is the number of the region's pixels in each image column, smoothed over
//! three columns. A column `v` is a valley when, within the piece being cut, the highest
//! profile value on each side of it is at least `column_min_peak` × the region's highest
//! (both sides hold a body, not an arm or a bag), the valley is at most
//! `column_valley_ratio` × the lower of the two, and both sides are at least
//! `column_min_width` × the region's height wide. The deepest valley (lowest valley / peak
//! ratio; the leftmost on a tie) is cut first, then each side again, up to `max_pieces`.
//!
//! Choice: a column profile rather than the calibration's expected size (the row cutter of
//! [`super::split`]). People side by side are separated in the image by a gap between
//! their bodies that closing fills only partly, so the profile dips there, and no
//! calibration is needed (vtest.avi has none). It cannot separate people one behind the
//! other (no dip), and it would cut a vehicle whose mask has a dark hole across it, so it is
//! off by default and meant for cameras that watch people
//! (`configs/detect-pedestrians.toml`).

use super::split::SplitConfig;

/// Columns at which to cut a region whose column profile is `counts` (pixels of the region
/// per column, left to right) and whose box is `height` px high: each returned index `v` is
/// the first column of a piece, ascending, at most `max_pieces − 1` of them.
pub fn column_cuts(counts: &[u32], height: f64, cfg: &SplitConfig) -> Vec<usize> {
    let n = counts.len();
    let min_w = ((cfg.column_min_width * height).ceil() as usize).max(1);
    if n < 2 * min_w || cfg.max_pieces < 2 {
        return Vec::new();
    }
    let smooth: Vec<f64> = (0..n)
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(1), (i + 1).min(n - 1));
            counts[lo..=hi].iter().map(|&c| f64::from(c)).sum::<f64>() / (hi - lo + 1) as f64
        })
        .collect();
    let top = smooth.iter().copied().fold(0.0, f64::max);
    let min_peak = cfg.column_min_peak * top;
    let mut cuts = Vec::new();
    let mut pending = vec![(0usize, n)];
    while let Some((a, b)) = pending.pop() {
        if cuts.len() + 1 >= cfg.max_pieces as usize {
            break;
        }
        if b - a < 2 * min_w {
            continue;
        }
        // Running maxima from the left (over a..v) and from the right (over v+1..b).
        let mut left = vec![0.0; b - a];
        let mut m = 0.0f64;
        for v in a..b {
            left[v - a] = m;
            m = m.max(smooth[v]);
        }
        let mut right = vec![0.0; b - a];
        let mut m = 0.0f64;
        for v in (a..b).rev() {
            right[v - a] = m;
            m = m.max(smooth[v]);
        }
        let mut best: Option<(f64, usize)> = None;
        for v in a + min_w..=b - min_w {
            let (l, r) = (left[v - a], right[v - a]);
            if l < min_peak || r < min_peak {
                continue;
            }
            let ratio = smooth[v] / l.min(r);
            if ratio <= cfg.column_valley_ratio && best.is_none_or(|(q, _)| ratio < q) {
                best = Some((ratio, v));
            }
        }
        if let Some((_, v)) = best {
            cuts.push(v);
            // Right first on the stack so that the left piece is cut next (deterministic).
            pending.push((v, b));
            pending.push((a, v));
        }
    }
    cuts.sort_unstable();
    cuts
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> SplitConfig {
        SplitConfig {
            columns: true,
            ..SplitConfig::default()
        }
    }

    /// A person: a `w`-wide body of height `h` columns.
    fn person(w: usize, h: u32) -> Vec<u32> {
        vec![h; w]
    }

    #[test]
    fn two_people_joined_by_an_arm_are_cut_between_them() {
        let mut p = person(12, 50);
        p.extend([6, 5, 6]);
        p.extend(person(11, 46));
        assert_eq!(column_cuts(&p, 50.0, &cfg()), vec![13]);
        // Three people.
        p.extend([4, 4, 4]);
        p.extend(person(12, 48));
        let cuts = column_cuts(&p, 50.0, &cfg());
        assert_eq!(cuts.len(), 2);
        assert!(
            (12..=14).contains(&cuts[0]) && (27..=29).contains(&cuts[1]),
            "{cuts:?}"
        );
    }

    #[test]
    fn one_person_a_swinging_arm_or_a_flat_vehicle_stays_whole() {
        // Legs apart under a torso: every column holds the torso.
        let body: Vec<u32> = [20, 30, 45, 50, 50, 50, 50, 50, 45, 30, 20].to_vec();
        assert!(column_cuts(&body, 50.0, &cfg()).is_empty());
        // An arm away from the body: its peak is far below the body's.
        let mut arm = person(12, 50);
        arm.extend([0, 0, 0, 12, 12, 12, 12, 12, 12, 12, 12, 12]);
        assert!(column_cuts(&arm, 50.0, &cfg()).is_empty());
        // A car: a flat profile.
        assert!(column_cuts(&person(40, 15), 15.0, &cfg()).is_empty());
        // Pieces narrower than 0.2 × height are not cut off.
        let mut narrow = person(6, 50);
        narrow.extend([0, 0]);
        narrow.extend(person(6, 50));
        assert!(column_cuts(&narrow, 50.0, &cfg()).is_empty());
    }

    #[test]
    fn max_pieces_caps_the_cuts() {
        let mut p = Vec::new();
        for _ in 0..5 {
            p.extend(person(12, 50));
            p.extend([2, 2, 2]);
        }
        assert_eq!(column_cuts(&p, 50.0, &cfg()).len(), 4);
        let three = SplitConfig {
            max_pieces: 3,
            ..cfg()
        };
        assert_eq!(column_cuts(&p, 50.0, &three).len(), 2);
    }

    #[test]
    fn regions_of_two_people_side_by_side_become_two_detections_only_with_columns() {
        use crate::detect::regions::{RegionConfig, extract_regions_split};
        use image::{GrayImage, Luma, RgbImage};
        // Two 12 × 40 bodies 4 px apart, joined by a 4 × 3 arm at shoulder height.
        let mut mask = GrayImage::new(60, 60);
        for y in 10..50 {
            for x in (10..22).chain(26..38) {
                mask.put_pixel(x, y, Luma([255]));
            }
        }
        for y in 20..23 {
            for x in 22..26 {
                mask.put_pixel(x, y, Luma([255]));
            }
        }
        let img = RgbImage::new(60, 60);
        let rc = RegionConfig::default();
        let whole = extract_regions_split(&mask, &img, &rc, None, None);
        assert_eq!(whole.len(), 1);
        let cut = extract_regions_split(&mask, &img, &rc, None, Some(&cfg()));
        assert_eq!(cut.len(), 2);
        let mut boxes: Vec<_> = cut.iter().map(|r| (r.bbox.left, r.bbox.width)).collect();
        boxes.sort_by(|a, b| a.0.total_cmp(&b.0));
        // The cut falls in the gap: each piece holds one body (plus part of the arm).
        assert!(
            boxes[0].0 == 10.0 && (12.0..=16.0).contains(&boxes[0].1),
            "{boxes:?}"
        );
        assert!((22.0..=26.0).contains(&boxes[1].0) && boxes[1].0 + boxes[1].1 == 38.0);
        assert_eq!(cut.iter().map(|r| r.area_px).sum::<u32>(), whole[0].area_px);
    }
}
