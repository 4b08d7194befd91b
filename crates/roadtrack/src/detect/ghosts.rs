//! Ghost suppression for the background detector (`[background] ghost_edge_ratio`).
//!
//! A *ghost* is foreground where no object is: the background model holds an object that
//! has since left. The persistent start-up makes them where one vehicle covered a pixel
//! for most of the sampled frames (a car that waits at the light for three quarters of the
//! sequence is the background there, and the empty road before it arrives is
//! "foreground"); the hold keeps them for `hold_still_s`. A ghost costs twice: a false box
//! while it lasts, and a missed vehicle when the car comes back, since it then matches the
//! background.
//!
//! Test (the edge-based ghost test of background-subtraction systems, e.g. Cucchiara et
//! al. 2003 "Detecting moving objects, ghosts and shadows"): along the outline of a
//! region, a real object shows its edges in the frame, while a ghost's outline is an edge
//! of the *background* (the departed object's silhouette) over an even frame. For every
//! outline pixel take the largest gradient magnitude within `RADIUS` px, in the frame and
//! in the background; the region is a ghost when the frame's sum is under
//! `ghost_edge_ratio` × the background's. Only regions still for `ghost_still_s` are
//! tested (ghosts do not move; a moving vehicle is never tested). A ghost is removed from
//! the mask and the background is set to the frame under it, so a vehicle that comes back
//! is foreground again (and held).
//!
//! Choice: the outline of the cleaned mask, not of the raw one: it is the region the
//! detector would report. Choice: the Sobel magnitude `|∂x| + |∂y|` of the channel sum,
//! not a colour edge detector: the test compares two sums of the same measure, so only
//! their ratio matters; Sobel's smoothing across the difference keeps the frame's sensor
//! noise (the background mean has none) from passing for edges (central differences with
//! the largest value within 2 px put a ghost on the simulator's aerial intersection at
//! 0.53 of its background's edges, Sobel within 1 px at 0.36).

use super::background_model::BackgroundModel;
use super::regions::component_runs;
use image::{GrayImage, RgbImage};

/// How far (px) from an outline pixel an edge still counts: the cleaned mask's outline
/// lies about a pixel from the object's silhouette (opening and closing), and the Sobel
/// kernel spans a pixel on each side too.
const RADIUS: i64 = 1;

/// Share of a region's pixels that must have been held for `ghost_still_s`.
const STILL_SHARE: f64 = 0.9;

/// Finds the ghosts among the regions of `mask` (the cleaned foreground of `image`, before
/// the model learns `image`) at time `time_s`, clears them from `mask` and absorbs them
/// into `model`. Regions under `min_area_px` are left alone. A region's outline is its
/// pixels next to a background pixel of `outline_of` (`None`: of `mask`): given the cleaned
/// mask when `mask` holds the age cut's pieces, a piece's outline leaves out the cut lines,
/// which may run through an object. Returns the ghosts' pixel runs.
pub fn suppress(
    model: &mut BackgroundModel,
    mask: &mut GrayImage,
    outline_of: Option<&GrayImage>,
    image: &RgbImage,
    time_s: f64,
    min_area_px: u32,
) -> Vec<Vec<(u32, u32, u32)>> {
    let cfg = model.config();
    let (ratio, still_s) = (cfg.ghost_edge_ratio, cfg.ghost_still_s);
    if ratio <= 0.0 {
        return Vec::new();
    }
    let w = mask.width();
    let t = time_s as f32;
    let still = |since: f32| !since.is_nan() && f64::from(t - since) >= still_s;
    // Most frames of moving traffic hold no pixel that long: skip the labelling then.
    let any_still = mask
        .as_raw()
        .iter()
        .zip(model.held_since())
        .any(|(&m, &since)| m != 0 && still(since));
    if !any_still {
        return Vec::new();
    }
    let mut ghosts = Vec::new();
    for runs in component_runs(mask) {
        let n: u64 = runs.iter().map(|&(_, a, b)| u64::from(b - a)).sum();
        if n < u64::from(min_area_px) {
            continue;
        }
        // A piece the cut left whole is a region the first test has seen: skip it.
        if outline_of.is_some_and(|around| !touches_a_cut(around, mask, &runs)) {
            continue;
        }
        let held = model.held_since();
        let n_still: u64 = runs
            .iter()
            .map(|&(y, a, b)| {
                let row = (y * w) as usize;
                held[row + a as usize..row + b as usize]
                    .iter()
                    .filter(|&&s| still(s))
                    .count() as u64
            })
            .sum();
        if (n_still as f64) < STILL_SHARE * n as f64 {
            continue;
        }
        let (e_frame, e_background) = outline_edges(outline_of.unwrap_or(mask), &runs, |x, y| {
            let i = 3 * (y as usize * w as usize + x as usize);
            let p = &image.as_raw()[i..i + 3];
            let m = &model.mean()[i..i + 3];
            (
                f32::from(p[0]) + f32::from(p[1]) + f32::from(p[2]),
                m[0] + m[1] + m[2],
            )
        });
        if e_frame < ratio * e_background
            && outline_of
                .is_none_or(|around| looks_like_its_surroundings(around, &runs, image, model))
        {
            ghosts.push(runs);
        }
    }
    for runs in &ghosts {
        clear_runs(mask, runs);
        model.absorb(image, runs);
    }
    ghosts
}

/// Sets the pixels of `runs` (row, first column, end column) to 0 in `mask`.
pub fn clear_runs(mask: &mut GrayImage, runs: &[(u32, u32, u32)]) {
    let w = mask.width();
    for &(y, a, b) in runs {
        let row = (y * w) as usize;
        mask.as_mut()[row + a as usize..row + b as usize].fill(0);
    }
}

/// The 4-neighbours inside a `w × h` frame of a region's pixels (`runs`), in pixel order
/// and with repeats (a pixel beside two of the region's is given twice).
fn neighbours(runs: &[(u32, u32, u32)], w: u32, h: u32) -> impl Iterator<Item = (u32, u32)> + '_ {
    runs.iter().flat_map(move |&(y, a, b)| {
        (a..b).flat_map(move |x| {
            [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
                .into_iter()
                .filter_map(move |(dx, dy)| {
                    let (nx, ny) = (i64::from(x) + dx, i64::from(y) + dy);
                    (nx >= 0 && ny >= 0 && nx < i64::from(w) && ny < i64::from(h))
                        .then_some((nx as u32, ny as u32))
                })
        })
    })
}

/// Whether a piece of the age cut (`runs`, pixels of `pieces`) borders a pixel that the cut
/// removed (in `around`, the cleaned mask, but not in `pieces`).
fn touches_a_cut(around: &GrayImage, pieces: &GrayImage, runs: &[(u32, u32, u32)]) -> bool {
    let (w, h) = around.dimensions();
    neighbours(runs, w, h)
        .any(|(x, y)| around.get_pixel(x, y)[0] != 0 && pieces.get_pixel(x, y)[0] == 0)
}

/// Largest per-channel difference (grey levels) between the frame's mean colour over a
/// piece and the background's mean colour just around it for the piece to pass as a
/// ghost ([`looks_like_its_surroundings`]).
// Choice: 20 grey levels: the background's noise floor is 8 (`min_sigma`), and the road
// under a ghost and beside it differ by markings; a vehicle differs from the road by more.
const SURROUNDINGS_TOLERANCE: f32 = 20.0;

/// Whether the frame over a piece of the age cut (`runs`) shows what the background shows
/// around it (its 4-neighbours that are background in `around`, the cleaned mask): a
/// ghost shows the road it stands on, a vehicle its own colours. No neighbour: `false`.
fn looks_like_its_surroundings(
    around: &GrayImage,
    runs: &[(u32, u32, u32)],
    image: &RgbImage,
    model: &BackgroundModel,
) -> bool {
    let (w, h) = around.dimensions();
    let (px, mean) = (image.as_raw(), model.mean());
    let at = |x: u32, y: u32| 3 * (y as usize * w as usize + x as usize);
    let (mut inside, mut n_in) = ([0.0f64; 3], 0.0f64);
    for &(y, a, b) in runs {
        for x in a..b {
            for c in 0..3 {
                inside[c] += f64::from(px[at(x, y) + c]);
            }
            n_in += 1.0;
        }
    }
    let (mut ring, mut n_ring) = ([0.0f64; 3], 0.0f64);
    for (x, y) in neighbours(runs, w, h).filter(|&(x, y)| around.get_pixel(x, y)[0] == 0) {
        for c in 0..3 {
            ring[c] += f64::from(mean[at(x, y) + c]);
        }
        n_ring += 1.0;
    }
    n_ring > 0.0
        && (0..3)
            .all(|c| ((inside[c] / n_in - ring[c] / n_ring).abs() as f32) < SURROUNDINGS_TOLERANCE)
}

/// Sums over the outline pixels of a region (`runs`, pixels of `mask`) of the largest
/// gradient magnitude within [`RADIUS`], of the frame and of the background; `value(x, y)`
/// gives both images' values at a pixel. Outline: a region pixel with a 4-neighbour
/// inside the frame that is not in the mask (the frame's border is not an outline).
fn outline_edges(
    mask: &GrayImage,
    runs: &[(u32, u32, u32)],
    value: impl Fn(u32, u32) -> (f32, f32),
) -> (f64, f64) {
    let (w, h) = mask.dimensions();
    let inside = |x: i64, y: i64| x >= 0 && y >= 0 && x < i64::from(w) && y < i64::from(h);
    let off = |x: i64, y: i64| inside(x, y) && mask.get_pixel(x as u32, y as u32)[0] == 0;
    // Sobel magnitude of both images at (x, y), the image clamped at its border.
    let grad = |x: i64, y: i64| -> (f32, f32) {
        let at = |x: i64, y: i64| {
            value(
                x.clamp(0, i64::from(w) - 1) as u32,
                y.clamp(0, i64::from(h) - 1) as u32,
            )
        };
        // Sobel: differences across x summed over three rows (1 2 1), and across y.
        let (mut gx, mut gy) = ((0.0f32, 0.0f32), (0.0f32, 0.0f32));
        for (k, wgt) in [(-1i64, 1.0f32), (0, 2.0), (1, 1.0)] {
            let (l, r) = (at(x - 1, y + k), at(x + 1, y + k));
            let (u, d) = (at(x + k, y - 1), at(x + k, y + 1));
            gx.0 += wgt * (r.0 - l.0);
            gx.1 += wgt * (r.1 - l.1);
            gy.0 += wgt * (d.0 - u.0);
            gy.1 += wgt * (d.1 - u.1);
        }
        (gx.0.abs() + gy.0.abs(), gx.1.abs() + gy.1.abs())
    };
    let (mut sum_f, mut sum_b) = (0.0f64, 0.0f64);
    for &(y, a, b) in runs {
        let y = i64::from(y);
        for x in i64::from(a)..i64::from(b) {
            if !(off(x - 1, y) || off(x + 1, y) || off(x, y - 1) || off(x, y + 1)) {
                continue;
            }
            let (mut best_f, mut best_b) = (0.0f32, 0.0f32);
            for dy in -RADIUS..=RADIUS {
                for dx in -RADIUS..=RADIUS {
                    if inside(x + dx, y + dy) {
                        let (gf, gb) = grad(x + dx, y + dy);
                        best_f = best_f.max(gf);
                        best_b = best_b.max(gb);
                    }
                }
            }
            sum_f += f64::from(best_f);
            sum_b += f64::from(best_b);
        }
    }
    (sum_f, sum_b)
}

#[cfg(test)]
mod tests {
    use super::super::background::{BackgroundDetector, BackgroundDetectorConfig};
    use crate::error::Result;
    use crate::frame::Frame;
    use crate::geometry::BBox;
    use image::{Rgb, RgbImage};

    const ROAD: [u8; 3] = [100, 100, 100];

    /// A 20 × 12 light vehicle with a dark 1 px outline at `(x0, y0)`.
    fn car(img: &mut RgbImage, x0: u32, y0: u32) {
        for y in y0..y0 + 12 {
            for x in x0..x0 + 20 {
                let edge = x == x0 || y == y0 || x == x0 + 19 || y == y0 + 11;
                img.put_pixel(x, y, Rgb(if edge { [30, 30, 30] } else { [220, 60, 50] }));
            }
        }
    }

    fn boxes(ghost_edge_ratio: f64) -> Result<Vec<Vec<BBox>>> {
        // Start-up samples: a car at (10, 10) in four of five, so the persistent start-up
        // takes it as the background there.
        let mut with_car = RgbImage::from_pixel(100, 40, Rgb(ROAD));
        car(&mut with_car, 10, 10);
        let boot = vec![
            with_car.clone(),
            with_car.clone(),
            RgbImage::from_pixel(100, 40, Rgb(ROAD)),
            with_car.clone(),
            with_car,
        ];
        let mut cfg = BackgroundDetectorConfig::default();
        cfg.background.ghost_edge_ratio = ghost_edge_ratio;
        // The car is away for frames 1–40 and parks where it was from 41 on; a second car
        // stands at (60, 14) from the first frame to the last.
        road_boxes(BackgroundDetector::new(cfg, &boot)?, 80, |i, img| {
            if i > 40 {
                car(img, 10, 10);
            }
            car(img, 60, 14);
        })
    }

    /// The detector's boxes on frames 1..=n at 10 frames/s: the road with what `draw(i,
    /// frame)` puts on it.
    fn road_boxes(
        mut det: BackgroundDetector,
        n: u32,
        draw: impl Fn(u32, &mut RgbImage),
    ) -> Result<Vec<Vec<BBox>>> {
        (1..=n)
            .map(|i| {
                let mut image = RgbImage::from_pixel(100, 40, Rgb(ROAD));
                draw(i, &mut image);
                let f = Frame {
                    index: i,
                    time_s: f64::from(i - 1) / 10.0,
                    image,
                };
                Ok(det.detect(&f)?.iter().filter_map(|d| d.bbox()).collect())
            })
            .collect()
    }

    fn has(boxes: &[BBox], x: f64, y: f64) -> bool {
        boxes
            .iter()
            .any(|b| b.iou(&BBox::new(x, y, 20.0, 12.0)) >= 0.8)
    }

    /// Where the background holds a car that has left, the road shows as a region (a
    /// ghost) and the car, when it comes back, matches the background and is missed. With
    /// ghost suppression the ghost is gone after `ghost_still_s` (0.5 s) and the returning
    /// car is found; a car standing still from the first frame is kept throughout.
    #[test]
    fn a_ghost_is_dropped_and_the_vehicle_that_returns_is_found() -> Result<()> {
        let off = boxes(0.0)?;
        let on = boxes(0.5)?;
        for (i, (b_off, b_on)) in off.iter().zip(&on).enumerate() {
            let frame = i + 1;
            assert!(has(b_off, 60.0, 14.0), "still car, off, frame {frame}");
            assert!(has(b_on, 60.0, 14.0), "still car, on, frame {frame}");
            if frame <= 40 {
                assert!(has(b_off, 10.0, 10.0), "ghost kept when off, frame {frame}");
                assert_eq!(
                    has(b_on, 10.0, 10.0),
                    frame <= 5,
                    "ghost, on, frame {frame}"
                );
            } else {
                assert!(
                    !has(b_off, 10.0, 10.0),
                    "returned car found when off, frame {frame}"
                );
                assert!(
                    has(b_on, 10.0, 10.0),
                    "returned car missed, on, frame {frame}"
                );
            }
        }
        Ok(())
    }

    /// A ghost joined by a vehicle that stops beside it is one region of the cleaned mask
    /// whose outline shows the vehicle's edges, so the ghost test passes it. The age cut
    /// parts the two (the vehicle's pixels are younger), and the test on the cut's pieces
    /// drops the ghost; the vehicle stays. Without the cut the ghost stays, joined to it.
    #[test]
    fn a_ghost_beside_a_younger_vehicle_is_dropped_once_the_age_cut_parts_them() -> Result<()> {
        let run = |age_gap_s: f64| -> Result<Vec<Vec<BBox>>> {
            let mut with_car = RgbImage::from_pixel(100, 40, Rgb(ROAD));
            car(&mut with_car, 10, 10);
            let boot = vec![with_car.clone(), with_car.clone(), with_car];
            let mut cfg = BackgroundDetectorConfig::default();
            cfg.regions.age_gap_s = age_gap_s;
            // The background's car has left (a ghost from frame 1); another car stops
            // touching the ghost's right side at frame 4, before the ghost has been still
            // for `ghost_still_s`.
            road_boxes(BackgroundDetector::new(cfg, &boot)?, 40, |i, img| {
                if i >= 4 {
                    car(img, 30, 10);
                }
            })
        };
        let near = |boxes: &[BBox], x: f64| {
            boxes
                .iter()
                .any(|b| b.iou(&BBox::new(x, 10.0, 20.0, 12.0)) >= 0.6)
        };
        let cut = run(0.2)?;
        let uncut = run(0.0)?;
        for frame in 20..=40 {
            let (c, u) = (&cut[frame - 1], &uncut[frame - 1]);
            assert!(near(c, 30.0), "car kept, frame {frame}: {c:?}");
            assert!(!near(c, 10.0), "ghost dropped, frame {frame}: {c:?}");
            assert!(
                u.iter().any(|b| b.left <= 11.0 && b.left + b.width >= 49.0),
                "without the cut the ghost stays, joined to the car, frame {frame}: {u:?}"
            );
        }
        Ok(())
    }

    /// A piece passes as a ghost only where the frame over it shows the colour the
    /// background has around it: road over road, not a red car; without a background
    /// neighbour, never.
    #[test]
    fn a_piece_is_a_ghost_only_where_it_looks_like_the_road_around_it() -> Result<()> {
        let road = RgbImage::from_pixel(40, 20, Rgb(ROAD));
        let model = BackgroundDetector::new(
            BackgroundDetectorConfig::default(),
            std::slice::from_ref(&road),
        )?;
        let model = model.background();
        // The piece: x 10..20 on rows 5..10; the cleaned mask holds it and x 20..30.
        let runs: Vec<(u32, u32, u32)> = (5..10).map(|y| (y, 10, 20)).collect();
        let mut around = image::GrayImage::new(40, 20);
        for y in 5..10 {
            for x in 10..30 {
                around.put_pixel(x, y, image::Luma([255]));
            }
        }
        let mut frame = road.clone();
        for &(y, a, b) in &runs {
            for x in a..b {
                frame.put_pixel(x, y, Rgb([ROAD[0] + 10, ROAD[1] + 5, ROAD[2]]));
            }
        }
        assert!(super::looks_like_its_surroundings(
            &around, &runs, &frame, model
        ));
        for &(y, a, b) in &runs {
            for x in a..b {
                frame.put_pixel(x, y, Rgb([220, 60, 50]));
            }
        }
        assert!(!super::looks_like_its_surroundings(
            &around, &runs, &frame, model
        ));
        // Every neighbour in the mask: nothing to compare with.
        let full = image::GrayImage::from_pixel(40, 20, image::Luma([255]));
        assert!(!super::looks_like_its_surroundings(
            &full, &runs, &road, model
        ));
        Ok(())
    }

    #[test]
    fn ghost_settings_out_of_range_are_refused_by_name() {
        for (ratio, still, field) in [
            (-0.1, 0.5, "ghost_edge_ratio"),
            (1.5, 0.5, "ghost_edge_ratio"),
            (0.5, -1.0, "ghost_still_s"),
            (0.5, f64::NAN, "ghost_still_s"),
        ] {
            let mut cfg = BackgroundDetectorConfig::default();
            cfg.background.ghost_edge_ratio = ratio;
            cfg.background.ghost_still_s = still;
            let e = cfg.validate().expect_err("refused").to_string();
            assert!(e.contains(field), "{e}");
        }
    }
}
