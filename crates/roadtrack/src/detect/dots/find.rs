//! One frame's dots ([`find_dots`]): which pixels differ from the background and which of
//! those are shadow ([`classify`], shared with [`crate::detect::refine`]), their blobs, and
//! the dark objects whose blobs are shadow-like, centred by the offset of the shadows that
//! lone dots cast ([`ShadowOffset`]). The module documentation of [`super`] says why.

use super::DotConfig;
use crate::error::{Error, Result};
use crate::geometry::Point;
use image::RgbImage;

/// Which pixels differ from the background and which of those are shadow ([`classify`]):
/// the fields of the same names of [`DotConfig`] and [`crate::detect::refine::RefineConfig`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct PixelTest {
    pub min_difference: f64,
    pub shadow_min_ratio: f64,
    pub shadow_max_ratio: f64,
    pub shadow_max_chroma: f64,
}

impl PixelTest {
    /// Checks the shadow bounds; `config` names the configuration in the error.
    pub(crate) fn validate(&self, config: &'static str) -> Result<()> {
        let ratios_ordered = (0.0..=1.0).contains(&self.shadow_min_ratio)
            && self.shadow_max_ratio >= self.shadow_min_ratio
            && self.shadow_max_ratio <= 1.0;
        if !ratios_ordered {
            return Err(Error::config(
                config,
                "shadow_min_ratio/shadow_max_ratio",
                format!(
                    "must satisfy 0 ≤ min ≤ max ≤ 1, found {} and {}",
                    self.shadow_min_ratio, self.shadow_max_ratio
                ),
            ));
        }
        if !(self.shadow_max_chroma.is_finite() && self.shadow_max_chroma >= 0.0) {
            return Err(Error::config(
                config,
                "shadow_max_chroma",
                format!("must be 0 or more, found {}", self.shadow_max_chroma),
            ));
        }
        Ok(())
    }
}

/// One dot: the difference-weighted centroid of its pixels (pixel centres at `x + 0.5`) and
/// the sum of their differences.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Dot {
    /// Centroid, px.
    pub centre: Point,
    /// Sum of `|ΔR| + |ΔG| + |ΔB|` over the dot's pixels.
    pub weight: f64,
    /// Pixels.
    pub area_px: u32,
}

/// What the pixel `rgb` over background `mu` is: its difference when it differs by
/// [`PixelTest::min_difference`] or more, and whether it is shadow.
pub(crate) fn classify(rgb: &[u8], mu: &[f32], cfg: &PixelTest) -> Option<(f32, bool)> {
    let f = [f32::from(rgb[0]), f32::from(rgb[1]), f32::from(rgb[2])];
    let diff: f32 = (0..3).map(|k| (f[k] - mu[k]).abs()).sum();
    if f64::from(diff) < cfg.min_difference {
        return None;
    }
    // Shadow (as docs/DETECTION.md's background model, on channel sums): darker by a ratio
    // in [min, max) with the chromaticity kept.
    let (sf, sb) = (f.iter().sum::<f32>() + 1.0, mu.iter().sum::<f32>() + 1.0);
    let ratio = f64::from(sf / sb);
    let shadow = ratio >= cfg.shadow_min_ratio
        && ratio < cfg.shadow_max_ratio
        && f64::from((0..3).map(|k| (f[k] / sf - mu[k] / sb).abs()).sum::<f32>())
            < cfg.shadow_max_chroma;
    Some((diff, shadow))
}

/// The 4-connected blobs of the pixels where `set` holds, in raster order of their first
/// pixel; `f(blob)` is called with each blob's pixel indices.
fn blobs(w: usize, h: usize, set: impl Fn(usize) -> bool, mut f: impl FnMut(&[usize])) {
    let mut seen = vec![false; w * h];
    let mut stack = Vec::new();
    let mut blob = Vec::new();
    for start in 0..w * h {
        if seen[start] || !set(start) {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        blob.clear();
        while let Some(i) = stack.pop() {
            blob.push(i);
            let (x, y) = (i % w, i / w);
            let neighbours = [
                (x > 0).then(|| i - 1),
                (x + 1 < w).then(|| i + 1),
                (y > 0).then(|| i - w),
                (y + 1 < h).then(|| i + w),
            ];
            for j in neighbours.into_iter().flatten() {
                if !seen[j] && set(j) {
                    seen[j] = true;
                    stack.push(j);
                }
            }
        }
        f(&blob);
    }
}

/// Where shadows fall from the objects that cast them: from the offsets, px, of the shadow
/// blobs beside lone dots (the centres of their pixels) over every frame seen, per axis the
/// mean of those within 1 px of the median. A dark object's blob holds it and its shadow,
/// so the object is this far up-sun of the blob's centre.
// Choice: not the mean: at a junction pieces of vehicles and their shadows pass for lone
// dots beside shadows (aerial intersection seed 4: the mean went from (0.13, 0.27) px
// after 5 frames to (0.51, 0.86) after 300, the crossing's (0.59, 1.26)). Not the median
// alone: the offsets take few values, and the median jumped between them (y 1.33 on one
// sequence, 1.75 on another, dark dots' median error 0.25 and 0.48 px). Offsets of blobs
// of up to 3 and 4 px are multiples of 1/12 px: a histogram of twelfths over
// ±SHADOW_RANGE_PX holds them exactly.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ShadowOffset {
    /// Per axis, the count of offsets in each twelfth of a pixel from -SHADOW_RANGE_PX.
    bins: [Vec<u64>; 2],
    n: u64,
}

/// Offsets of shadows are counted within this many px on each axis (farther ones at the
/// ends).
const SHADOW_RANGE_PX: i64 = 4;
/// Bins of the offsets' histograms per px.
const SHADOW_BINS_PER_PX: i64 = 12;

impl Default for ShadowOffset {
    fn default() -> Self {
        let n = (2 * SHADOW_RANGE_PX * SHADOW_BINS_PER_PX + 1) as usize;
        Self {
            bins: [vec![0; n], vec![0; n]],
            n: 0,
        }
    }
}

impl ShadowOffset {
    fn add(&mut self, d: Point) {
        let r = SHADOW_RANGE_PX * SHADOW_BINS_PER_PX;
        for (bins, v) in self.bins.iter_mut().zip([d.x, d.y]) {
            let k = ((v * SHADOW_BINS_PER_PX as f64).round() as i64).clamp(-r, r);
            bins[(k + r) as usize] += 1;
        }
        self.n += 1;
    }

    /// The offset: on each axis the mean of the samples within 1 px of their median (the
    /// lower median), or none before the first lone dot with its shadow.
    pub(crate) fn offset(&self) -> Option<Point> {
        if self.n == 0 {
            return None;
        }
        let r = SHADOW_RANGE_PX * SHADOW_BINS_PER_PX;
        let axis = |bins: &[u64]| {
            let half = self.n.div_ceil(2);
            let mut seen = 0;
            let m = bins
                .iter()
                .position(|&c| {
                    seen += c;
                    seen >= half
                })
                .unwrap_or(0);
            let near = m.saturating_sub(SHADOW_BINS_PER_PX as usize)
                ..=(m + SHADOW_BINS_PER_PX as usize).min(bins.len() - 1);
            let (sum, n) = near.fold((0.0, 0u64), |(sum, n), k| {
                (sum + bins[k] as f64 * (k as i64 - r) as f64, n + bins[k])
            });
            sum / n as f64 / SHADOW_BINS_PER_PX as f64
        };
        Some(Point::new(axis(&self.bins[0]), axis(&self.bins[1])))
    }
}

/// Unweighted centre of `blob` (pixel indices in an image `w` wide; pixel centres at
/// `x + 0.5`).
fn pixel_centre(blob: &[usize], w: usize) -> Point {
    let n = blob.len() as f64;
    let (sx, sy) = blob.iter().fold((0.0, 0.0), |(sx, sy), &i| {
        (sx + (i % w) as f64 + 0.5, sy + (i / w) as f64 + 0.5)
    });
    Point::new(sx / n, sy / n)
}

/// The contrast of `blob` (centre `c`, its [`pixel_centre`]) in an image of 3 values per
/// pixel (`value(i)` the `i`-th value, row-major): the largest `|ΔR| + |ΔG| + |ΔB|` of a
/// blob pixel from the per-channel median of the ring of pixels 2 or 3 px (Chebyshev) from
/// the blob's centre pixel, inside the image; 0 with no ring.
fn contrast(value: impl Fn(usize) -> f32, w: usize, h: usize, blob: &[usize], c: Point) -> f32 {
    let (cx, cy) = (c.x.floor() as i64, c.y.floor() as i64);
    // Per channel, the ring's values (at most RING_LEN), on the stack: this runs for every
    // blob small enough to be a dot.
    let mut ring = [[0f32; RING_LEN]; 3];
    let mut n = 0;
    for dy in -RING_PX..=RING_PX {
        for dx in -RING_PX..=RING_PX {
            let (x, y) = (cx + dx, cy + dy);
            if dx.abs().max(dy.abs()) < RING_PX - 1 || x < 0 || y < 0 {
                continue;
            }
            let (x, y) = (x as usize, y as usize);
            if x >= w || y >= h {
                continue;
            }
            for (k, r) in ring.iter_mut().enumerate() {
                r[n] = value(3 * (y * w + x) + k);
            }
            n += 1;
        }
    }
    if n == 0 {
        return 0.0;
    }
    let med = ring.map(|mut r| *r[..n].select_nth_unstable_by(n / 2, f32::total_cmp).1);
    blob.iter()
        .map(|&i| {
            (0..3)
                .map(|k| (value(3 * i + k) - med[k]).abs())
                .sum::<f32>()
        })
        .fold(0.0, f32::max)
}

/// Outer radius (Chebyshev, px) of [`contrast`]'s ring; the ring is this and one less.
const RING_PX: i64 = 3;
/// Pixels in [`contrast`]'s ring: (2·3 + 1)² − (2·1 + 1)².
const RING_LEN: usize = 40;

/// Whether `blob` is a ghost by [`DotConfig::ghost_contrast_ratio`]: the frame's contrast
/// there under that share of the background's ([`contrast`]). A walker shows contrast in
/// the frame whatever the background holds; a ghost is where the background still holds
/// someone who has left, over an even frame.
// Choice: the background's own contrast as the yardstick, not the blob's difference from
// the background. Against the difference (frame contrast ≥ 0.5 × difference) a walker in a
// group, whose ring is half walkers, failed the test: the aerial crossing, seeds 4–6, HOTA
// +0.004, against +0.012 this way (docs/EXPERIMENTS.md "Ghost dots").
fn is_ghost(
    (px, mean): (&[u8], &[f32]),
    (w, h): (usize, usize),
    blob: &[usize],
    centre: Point,
    ratio: f64,
) -> bool {
    ratio > 0.0
        && f64::from(contrast(|i| f32::from(px[i]), w, h, blob, centre))
            < ratio * f64::from(contrast(|i| mean[i], w, h, blob, centre))
}

/// A lone dot beside its shadow gives the offset of shadows when the dot has at most this
/// many pixels and the shadow at most [`LONE_SHADOW_PX`].
const LONE_DOT_PX: usize = 3;
/// See [`LONE_DOT_PX`].
const LONE_SHADOW_PX: usize = 4;

/// The dots of `image` against the background `mean` (3 values per pixel, row-major, as
/// [`crate::detect::background_model::BackgroundModel::mean`]), looked for where `allowed` is true
/// (all pixels when `None`): first the blobs of the differing pixels that are not shadow,
/// up to [`DotConfig::max_area_px`], in raster order of their first pixel; then, with
/// [`DotConfig::dark_dots`], the dark objects (blobs of shadow-like pixels that touch no
/// other differing pixel, [`DotConfig::dark_min_area_px`] to `dark_max_area_px`), each
/// centred `shadows`' offset up-sun of its blob's centre. The lone dots beside their
/// shadows of this frame join `shadows` first. `mean` and `allowed` must be of `image`'s
/// size ([`super::WithDots`] checks each frame's first).
// Choice: shadow pixels do not join a dot's blob, so a walker stays a dot beside its
// shadow. Leaving out the dots whose blob with the shadow is larger than 16 px (a car's
// pieces) was tried: on the aerial crossing it lost a fifth of the walkers, who go in
// groups, for no precision (docs/DETECTION.md "Dots").
// Choice: a dark object's centre is its blob's unweighted centre moved by the shadows'
// offset, learnt from the input rather than from a sun direction the footage does not
// give. On the aerial crossing (seed 1, a prototype over the per-pixel median) the walkers
// stand (-0.80, -1.34) px from their dark blobs' centres (medians), and shadows lie
// (0.67, 1.33) px from lone dots.
pub(crate) fn find_dots(
    image: &RgbImage,
    mean: &[f32],
    allowed: Option<&[bool]>,
    cfg: &DotConfig,
    shadows: &mut ShadowOffset,
) -> Vec<Dot> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let px = image.as_raw();
    // Per pixel: the difference of a dot pixel and of a shadow pixel, 0 elsewhere.
    let test = cfg.pixel_test();
    let mut diff = vec![0f32; w * h];
    let mut shade = vec![0f32; w * h];
    for i in 0..w * h {
        if allowed.is_some_and(|a| !a[i]) {
            continue;
        }
        match classify(&px[3 * i..3 * i + 3], &mean[3 * i..3 * i + 3], &test) {
            Some((v, false)) => diff[i] = v,
            Some((v, true)) => shade[i] = v,
            None => {}
        }
    }
    let mut dots = Vec::new();
    // Per pixel, the blob of differing pixels it belongs to (1-based; 0: none), and per
    // blob its pixel count and unweighted centre.
    let mut blob_of = vec![0u32; w * h];
    let mut blob_info: Vec<(usize, Point)> = Vec::new();
    blobs(
        w,
        h,
        |i| diff[i] > 0.0,
        |blob| {
            let centre = pixel_centre(blob, w);
            blob_info.push((blob.len(), centre));
            let id = blob_info.len() as u32;
            for &i in blob {
                blob_of[i] = id;
            }
            if blob.len() > cfg.max_area_px as usize
                || is_ghost((px, mean), (w, h), blob, centre, cfg.ghost_contrast_ratio)
            {
                return;
            }
            let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
            for &i in blob {
                let v = f64::from(diff[i]);
                sx += v * ((i % w) as f64 + 0.5);
                sy += v * ((i / w) as f64 + 0.5);
                sw += v;
            }
            dots.push(Dot {
                centre: Point::new(sx / sw, sy / sw),
                weight: sw,
                area_px: blob.len() as u32,
            });
        },
    );
    if !cfg.dark_dots {
        return dots;
    }
    // Shadow blobs: with the one blob of differing pixels they touch (8-neighbours), a
    // sample of the shadows' offset; touching none, a dark object.
    let mut dark = Vec::new();
    blobs(
        w,
        h,
        |i| shade[i] > 0.0,
        |blob| {
            let mut touched = None;
            let mut several = false;
            for &i in blob {
                let (x, y) = ((i % w) as i64, (i / w) as i64);
                for (dx, dy) in (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (dx, dy))) {
                    let (nx, ny) = (x + dx, y + dy);
                    if (dx, dy) == (0, 0) || nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let b = blob_of[ny as usize * w + nx as usize];
                    if b > 0 {
                        several |= touched.is_some_and(|t| t != b);
                        touched = Some(b);
                    }
                }
            }
            match touched {
                Some(b) if !several => {
                    let (area, centre) = blob_info[b as usize - 1];
                    if area <= LONE_DOT_PX && blob.len() <= LONE_SHADOW_PX {
                        let c = pixel_centre(blob, w);
                        shadows.add(Point::new(c.x - centre.x, c.y - centre.y));
                    }
                }
                Some(_) => {}
                None => {
                    let n = blob.len();
                    if n >= cfg.dark_min_area_px as usize && n <= cfg.dark_max_area_px as usize {
                        let centre = pixel_centre(blob, w);
                        let ghost =
                            is_ghost((px, mean), (w, h), blob, centre, cfg.ghost_contrast_ratio);
                        if !ghost {
                            let weight = blob.iter().map(|&i| f64::from(shade[i])).sum();
                            dark.push((centre, weight, n as u32));
                        }
                    }
                }
            }
        },
    );
    let offset = shadows.offset().unwrap_or(Point::new(0.0, 0.0));
    dots.extend(dark.into_iter().map(|(c, weight, area_px)| Dot {
        // A blob at the frame's edge keeps its object in the frame.
        centre: Point::new(
            (c.x - offset.x).clamp(0.0, w as f64),
            (c.y - offset.y).clamp(0.0, h as f64),
        ),
        weight,
        area_px,
    }));
    dots
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use image::Rgb;

    pub(in crate::detect::dots) const ROAD: [u8; 3] = [120, 115, 110];

    fn mean_of(img: &RgbImage) -> Vec<f32> {
        img.as_raw().iter().map(|&v| f32::from(v)).collect()
    }

    /// Each rule on one synthetic frame: a one-pixel dot, a two-pixel dot weighted by its
    /// differences, a shadow, a blob too large, a pixel too faint.
    #[test]
    fn dots_are_small_blobs_of_difference_that_are_not_shadow() {
        let bg = RgbImage::from_pixel(40, 20, Rgb(ROAD));
        let mut img = bg.clone();
        img.put_pixel(10, 10, Rgb([200, 40, 40]));
        // Differences 120 and 60 (grey, brighter: no shadow).
        img.put_pixel(20, 5, Rgb([160, 155, 150]));
        img.put_pixel(21, 5, Rgb([140, 135, 130]));
        // A shadow 3 px long: the road × 0.6.
        for x in 30..33 {
            img.put_pixel(x, 15, Rgb(ROAD.map(|v| (f32::from(v) * 0.6) as u8)));
        }
        // A 3 × 3 blob (9 px > 6).
        for y in 14..17 {
            for x in 2..5 {
                img.put_pixel(x, y, Rgb([20, 20, 200]));
            }
        }
        // Difference 30 < 40.
        img.put_pixel(36, 3, Rgb([130, 125, 120]));
        // The shadow touches no other differing pixel: a dark object to the dark-dot rule
        // (the next test), left out here.
        let cfg = DotConfig {
            dark_dots: false,
            ..DotConfig::default()
        };
        let mut shadows = ShadowOffset::default();
        let dots = find_dots(&img, &mean_of(&bg), None, &cfg, &mut shadows);
        assert_eq!(dots.len(), 2, "{dots:?}");
        assert_eq!(shadows.n, 0);
        // Raster order: (20, 5) first.
        assert_eq!(dots[0].area_px, 2);
        let x = (120.0 * 20.5 + 60.0 * 21.5) / 180.0;
        assert!((dots[0].centre.x - x).abs() < 1e-9, "{:?}", dots[0]);
        assert_eq!(dots[0].centre.y, 5.5);
        assert_eq!(dots[0].weight, 180.0);
        assert_eq!(dots[1].centre, Point::new(10.5, 10.5));
        assert_eq!(dots[1].area_px, 1);
        // Without the shadow test the shadow is a dot too; where not allowed, nothing.
        let no_shadow = DotConfig {
            shadow_max_ratio: 0.45,
            ..cfg.clone()
        };
        assert_eq!(
            find_dots(&img, &mean_of(&bg), None, &no_shadow, &mut shadows).len(),
            3
        );
        let none = vec![false; 40 * 20];
        let all = DotConfig::default();
        assert!(find_dots(&img, &mean_of(&bg), Some(&none), &all, &mut shadows).is_empty());
    }

    /// The shadows' offset is the mean of the samples within 1 px of their median: stray
    /// samples (pieces of vehicles beside their shadows) do not move it; samples beyond
    /// the range count at its ends.
    #[test]
    fn the_shadow_offset_is_the_median_of_its_samples() {
        let mut s = ShadowOffset::default();
        assert_eq!(s.offset(), None);
        for p in [
            (0.5, 1.25),
            (0.5, 1.25),
            (7.0 / 12.0, 1.25),
            (-3.0, -3.0),
            (10.0, 10.0),
        ] {
            s.add(Point::new(p.0, p.1));
        }
        let o = s.offset().expect("samples");
        assert!(
            (o.x - (0.5 + 0.5 + 7.0 / 12.0) / 3.0).abs() < 1e-12,
            "{o:?}"
        );
        assert!((o.y - 1.25).abs() < 1e-12, "{o:?}");
        // Four more far beyond the range: the median moves to the range's end, where only
        // the clamped samples are within 1 px.
        for _ in 0..4 {
            s.add(Point::new(0.5, 9.0));
        }
        let o = s.offset().expect("samples");
        assert!((o.y - 4.0).abs() < 1e-12, "{o:?}");
    }

    /// A dark object: its blob of shadow-like pixels touches no other differing pixel, and
    /// it is centred up-sun of that blob by the offset of the lone dots' shadows.
    #[test]
    fn a_dark_blob_alone_is_a_dot_moved_up_sun() {
        let bg = RgbImage::from_pixel(60, 30, Rgb(ROAD));
        let shade = Rgb(ROAD.map(|v| (f32::from(v) * 0.6) as u8));
        let mut img = bg.clone();
        // Two lone walkers, each with a shadow of three pixels below and right of it: the
        // shadow blob's centre is (2/3, 4/3) px from the walker's.
        for (x, y) in [(5, 5), (15, 5)] {
            img.put_pixel(x, y, Rgb([200, 40, 40]));
            img.put_pixel(x, y + 1, shade);
            img.put_pixel(x + 1, y + 1, shade);
            img.put_pixel(x + 1, y + 2, shade);
        }
        // A dark walker (shadow-like itself) with the same shadow: one blob of 4 px.
        img.put_pixel(30, 10, shade);
        img.put_pixel(30, 11, shade);
        img.put_pixel(31, 11, shade);
        img.put_pixel(31, 12, shade);
        // Shadow-like pieces too small (2 px) and too large (12 px), and shadow on a
        // vehicle's side (touching a large blob).
        img.put_pixel(45, 5, shade);
        img.put_pixel(46, 5, shade);
        for x in 40..52 {
            img.put_pixel(x, 20, shade);
        }
        for y in 24..28 {
            for x in 40..48 {
                img.put_pixel(x, y, Rgb([20, 20, 200]));
            }
            img.put_pixel(48, y, shade);
        }
        let mut shadows = ShadowOffset::default();
        let dots = find_dots(
            &img,
            &mean_of(&bg),
            None,
            &DotConfig::default(),
            &mut shadows,
        );
        let offset = shadows.offset().expect("two lone dots");
        assert!((offset.x - 2.0 / 3.0).abs() < 1e-9 && (offset.y - 4.0 / 3.0).abs() < 1e-9);
        assert_eq!(shadows.n, 2);
        // The two walkers, then the dark one.
        assert_eq!(dots.len(), 3, "{dots:?}");
        assert_eq!(dots[0].centre, Point::new(5.5, 5.5));
        assert_eq!(dots[1].centre, Point::new(15.5, 5.5));
        let blob_centre = Point::new(31.0, 11.5);
        let c = dots[2].centre;
        assert!((c.x - (blob_centre.x - 2.0 / 3.0)).abs() < 1e-9, "{c:?}");
        assert!((c.y - (blob_centre.y - 4.0 / 3.0)).abs() < 1e-9, "{c:?}");
        assert_eq!(dots[2].area_px, 4);
        // Off: the dots of before.
        let off = DotConfig {
            dark_dots: false,
            ..DotConfig::default()
        };
        assert_eq!(
            find_dots(
                &img,
                &mean_of(&bg),
                None,
                &off,
                &mut ShadowOffset::default()
            )
            .len(),
            2
        );
    }

    /// A walker the background learnt and who has left: the frame is even road where the
    /// model holds the walker (a bright pixel, and a dark 3-pixel blob the dark-dot rule
    /// would take), so both are ghosts; a walker on the road, alone or beside two others,
    /// and a walker standing where the model holds another one, are dots.
    #[test]
    fn ghosts_of_walkers_who_left_are_not_dots() {
        let road = RgbImage::from_pixel(60, 30, Rgb(ROAD));
        let mut bg = road.clone();
        let mut img = road.clone();
        // Ghosts: in the background only.
        bg.put_pixel(5, 5, Rgb([200, 40, 40]));
        let bright = Rgb(ROAD.map(|v| (f32::from(v) * 1.6) as u8));
        for (x, y) in [(15, 5), (15, 6), (16, 6)] {
            bg.put_pixel(x, y, bright);
        }
        // Walkers: in the frame (one alone, a group of three in a row, one standing on a
        // ghost of another colour).
        img.put_pixel(30, 5, Rgb([200, 40, 40]));
        for x in [40, 42, 44] {
            img.put_pixel(x, 20, Rgb([40, 40, 200]));
        }
        bg.put_pixel(50, 10, Rgb([200, 190, 180]));
        img.put_pixel(50, 10, Rgb([30, 160, 30]));
        let find = |ratio: f64| {
            let cfg = DotConfig {
                ghost_contrast_ratio: ratio,
                ..DotConfig::default()
            };
            find_dots(
                &img,
                &mean_of(&bg),
                None,
                &cfg,
                &mut ShadowOffset::default(),
            )
            .into_iter()
            .map(|d| (d.centre.x.floor() as i64, d.centre.y.floor() as i64))
            .collect::<Vec<_>>()
        };
        let walkers = vec![(30, 5), (50, 10), (40, 20), (42, 20), (44, 20)];
        assert_eq!(find(DotConfig::default().ghost_contrast_ratio), walkers);
        // Off: the ghosts are dots too.
        let all = find(0.0);
        assert!(all.contains(&(5, 5)), "{all:?}");
        assert!(
            all.iter().any(|&(x, y)| (14..=17).contains(&x) && y <= 6),
            "{all:?}"
        );
        assert_eq!(all.len(), walkers.len() + 2, "{all:?}");
    }

    /// The contrast of a blob against the median of its ring, by hand.
    #[test]
    fn contrast_is_the_largest_difference_from_the_rings_median() {
        let mut img = RgbImage::from_pixel(9, 9, Rgb([100, 100, 100]));
        img.put_pixel(4, 4, Rgb([130, 90, 100]));
        // Ring pixels off the median: fewer than half of the ring's 40.
        for x in 1..8 {
            img.put_pixel(x, 1, Rgb([0, 0, 0]));
        }
        let w = 9;
        let value = |i: usize| f32::from(img.as_raw()[i]);
        let at = |blob: &[usize], w| pixel_centre(blob, w);
        assert_eq!(
            contrast(value, w, 9, &[4 * w + 4], at(&[4 * w + 4], w)),
            40.0
        );
        // A blob in a corner has a part ring; an image with no ring gives 0.
        assert_eq!(contrast(value, w, 9, &[0], at(&[0], w)), 0.0);
        let one = RgbImage::from_pixel(1, 1, Rgb([5, 5, 5]));
        let value = |i: usize| f32::from(one.as_raw()[i]);
        assert_eq!(contrast(value, 1, 1, &[0], at(&[0], 1)), 0.0);
    }
}
