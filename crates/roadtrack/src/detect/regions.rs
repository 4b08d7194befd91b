//! Foreground regions: mask clean-up (morphological opening and closing) and connected
//! regions with centroid, box, area and mean colour.

use crate::detection::Detection;
use crate::geometry::{BBox, Point};

/// Parameters of foreground extraction: mask clean-up and region filtering.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RegionConfig {
    /// Radius of the morphological opening (L∞ norm, px) that removes speckle. Default 1
    /// (a 3 × 3 square). 0 disables it.
    pub open_radius_px: u8,
    /// Radius of the morphological closing (L∞, px) applied after the opening, which joins
    /// fragments of one object. Default 3.
    pub close_radius_px: u8,
    /// Smallest region kept, px². Default 60.
    pub min_area_px: u32,
    /// Largest region kept, px². Default 50 000.
    pub max_area_px: u32,
}

impl Default for RegionConfig {
    fn default() -> Self {
        Self {
            open_radius_px: 1,
            close_radius_px: 3,
            min_area_px: 60,
            max_area_px: 50_000,
        }
    }
}

impl RegionConfig {
    /// Checks the ranges.
    pub fn validate(&self) -> crate::Result<()> {
        if self.min_area_px > self.max_area_px {
            return Err(crate::Error::config(
                "RegionConfig",
                "min_area_px",
                format!(
                    "{} exceeds max_area_px {}",
                    self.min_area_px, self.max_area_px
                ),
            ));
        }
        Ok(())
    }
}

/// A connected region of foreground pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// Number of pixels, px².
    pub area_px: u32,
    /// Centroid of the pixels (pixel centres at `x + 0.5`), px.
    pub centroid_px: Point,
    /// Tight box around the pixels, px (pixel edges).
    pub bbox: BBox,
    /// Mean colour of the region's pixels in the frame, 0–255.
    pub mean_rgb: [f64; 3],
}

/// Morphological clean-up of a foreground mask: opening then closing with square (L∞)
/// structuring elements.
///
/// Same result as `imageproc::morphology::{open, close}` with `Norm::LInf` (a property test
/// checks it), computed with separable running counts: O(1) per pixel whatever the radius,
/// about 1.9× faster than imageproc's distance transforms on `vtest.avi` masks (same run,
/// release build: 9.1 against 17.3 ms per 768 × 576 frame on a loaded 2-core machine).
pub fn clean_mask(mask: &image::GrayImage, config: &RegionConfig) -> image::GrayImage {
    let mut m = mask.clone();
    let r_open = u32::from(config.open_radius_px);
    if r_open > 0 {
        m = square_morphology(&m, r_open, Morph::Erode);
        m = square_morphology(&m, r_open, Morph::Dilate);
    }
    let r_close = u32::from(config.close_radius_px);
    if r_close > 0 {
        m = square_morphology(&m, r_close, Morph::Dilate);
        m = square_morphology(&m, r_close, Morph::Erode);
    }
    m
}

#[derive(Clone, Copy, PartialEq)]
enum Morph {
    Erode,
    Dilate,
}

/// Binary erosion or dilation of a mask (non-zero = set) by a `(2r+1)²` square.
///
/// Pixels outside the image are ignored: erosion keeps a pixel when every in-image pixel of
/// its window is set, dilation sets it when any is (imageproc's convention).
fn square_morphology(mask: &image::GrayImage, r: u32, op: Morph) -> image::GrayImage {
    let (w, h) = mask.dimensions();
    let (wu, hu, ru) = (w as usize, h as usize, r as usize);
    let decide = |count: u16, len: u16| -> u8 {
        let set = match op {
            Morph::Erode => count == len,
            Morph::Dilate => count > 0,
        };
        if set { 255 } else { 0 }
    };
    // Horizontal pass: running count of set pixels in [x − r, x + r] ∩ row.
    let src = mask.as_raw();
    let mut tmp = vec![0u8; wu * hu];
    for (row, dst) in src.chunks_exact(wu).zip(tmp.chunks_exact_mut(wu)) {
        // An empty row stays empty under erosion and dilation (`tmp` is zeroed); most rows
        // of a traffic frame are empty, and this test is one vectorised scan.
        if row.iter().all(|&v| v == 0) {
            continue;
        }
        let mut count = row[..ru.min(wu)].iter().filter(|&&v| v != 0).count() as u16;
        for x in 0..wu {
            if x + ru < wu && row[x + ru] != 0 {
                count += 1;
            }
            if x > ru && row[x - ru - 1] != 0 {
                count -= 1;
            }
            let len = ((x + ru + 1).min(wu) - x.saturating_sub(ru)) as u16;
            dst[x] = decide(count, len);
        }
    }
    // Vertical pass, row by row (cache-friendly): per-column running counts.
    let mut out = vec![0u8; wu * hu];
    let mut counts = vec![0u16; wu];
    for y in 0..ru.min(hu) {
        for (c, &v) in counts.iter_mut().zip(&tmp[y * wu..(y + 1) * wu]) {
            *c += u16::from(v != 0);
        }
    }
    for y in 0..hu {
        if y + ru < hu {
            let enter = &tmp[(y + ru) * wu..(y + ru + 1) * wu];
            for (c, &v) in counts.iter_mut().zip(enter) {
                *c += u16::from(v != 0);
            }
        }
        if y > ru {
            let leave = &tmp[(y - ru - 1) * wu..(y - ru) * wu];
            for (c, &v) in counts.iter_mut().zip(leave) {
                *c -= u16::from(v != 0);
            }
        }
        let len = ((y + ru + 1).min(hu) - y.saturating_sub(ru)) as u16;
        for (o, &c) in out[y * wu..(y + 1) * wu].iter_mut().zip(&counts) {
            *o = decide(c, len);
        }
    }
    image::GrayImage::from_raw(w, h, out).unwrap_or_else(|| image::GrayImage::new(w, h))
}

/// The 8-connected regions of non-zero pixels of `mask` whose area lies in
/// `[min_area_px, max_area_px]`, with centroid, box and mean colour taken from `image`.
///
/// Regions are ordered by their first pixel in raster order (top to bottom, left to right),
/// so the order is deterministic.
pub fn extract_regions(
    mask: &image::GrayImage,
    image: &image::RgbImage,
    config: &RegionConfig,
) -> Vec<Region> {
    extract_regions_split(mask, image, config, None, None)
}

/// Running sums of one region's pixels.
#[derive(Clone, Copy)]
struct Acc {
    n: u64,
    /// Raster index of the first pixel.
    first: u64,
    sx: f64,
    sy: f64,
    sxx: f64,
    syy: f64,
    sxy: f64,
    rgb: [f64; 3],
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

impl Acc {
    const EMPTY: Acc = Acc {
        n: 0,
        first: u64::MAX,
        sx: 0.0,
        sy: 0.0,
        sxx: 0.0,
        syy: 0.0,
        sxy: 0.0,
        rgb: [0.0; 3],
        x0: u32::MAX,
        y0: u32::MAX,
        x1: 0,
        y1: 0,
    };

    #[inline]
    fn add(&mut self, x: u32, y: u32, width: u32, rgb: Option<&image::Rgb<u8>>) {
        if self.n == 0 {
            self.first = u64::from(y) * u64::from(width) + u64::from(x);
        }
        self.n += 1;
        let (fx, fy) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
        self.sx += fx;
        self.sy += fy;
        self.sxx += fx * fx;
        self.syy += fy * fy;
        self.sxy += fx * fy;
        if let Some(p) = rgb {
            for c in 0..3 {
                self.rgb[c] += f64::from(p[c]);
            }
        }
        self.x0 = self.x0.min(x);
        self.y0 = self.y0.min(y);
        self.x1 = self.x1.max(x);
        self.y1 = self.y1.max(y);
    }

    fn centroid(&self) -> Point {
        let nf = self.n as f64;
        Point::new(self.sx / nf, self.sy / nf)
    }

    /// The unit principal axis (of the larger second moment).
    fn axis(&self) -> (f64, f64) {
        let nf = self.n as f64;
        let c = self.centroid();
        let cxx = self.sxx / nf - c.x * c.x;
        let cyy = self.syy / nf - c.y * c.y;
        let cxy = self.sxy / nf - c.x * c.y;
        let theta = 0.5 * (2.0 * cxy).atan2(cxx - cyy);
        (theta.cos(), theta.sin())
    }

    fn region(&self) -> Region {
        let nf = self.n as f64;
        Region {
            area_px: self.n as u32,
            centroid_px: self.centroid(),
            bbox: BBox::new(
                f64::from(self.x0),
                f64::from(self.y0),
                f64::from(self.x1 - self.x0 + 1),
                f64::from(self.y1 - self.y0 + 1),
            ),
            mean_rgb: self.rgb.map(|s| s / nf),
        }
    }
}

/// [`extract_regions`], then each region kept is cut at the valleys of its column profile
/// when `columns` is given (people side by side, module [`super::columns`]), else by
/// `splitter` (when given) into the vehicles it holds (module [`super::split`]); pieces are
/// regions of their own, ordered with the others by first pixel.
pub fn extract_regions_split(
    mask: &image::GrayImage,
    image: &image::RgbImage,
    config: &RegionConfig,
    splitter: Option<&super::split::Splitter>,
    columns: Option<&super::split::SplitConfig>,
) -> Vec<Region> {
    use imageproc::region_labelling::{Connectivity, connected_components};
    let labels = connected_components(mask, Connectivity::Eight, image::Luma([0u8]));
    // Labels are assigned in raster order of first appearance, 1..=n: the accumulators grow
    // as labels appear (one pass over the labels, not two).
    let mut acc = vec![Acc::EMPTY];
    let (w, h) = labels.dimensions();
    let img_ok = image.dimensions() == (w, h);
    let px = image.as_raw();
    for (y, row) in labels.as_raw().chunks_exact(w.max(1) as usize).enumerate() {
        for (x, &l) in row.iter().enumerate() {
            if l == 0 {
                continue;
            }
            let l = l as usize;
            if l >= acc.len() {
                acc.resize(l + 1, Acc::EMPTY);
            }
            let i = 3 * (y * w as usize + x);
            let rgb = img_ok.then(|| image::Rgb([px[i], px[i + 1], px[i + 2]]));
            acc[l].add(x as u32, y as u32, w, rgb.as_ref());
        }
    }
    let n = acc.len() - 1;
    let keep =
        |a: &Acc| a.n >= u64::from(config.min_area_px) && a.n <= u64::from(config.max_area_px);
    if splitter.is_none() && columns.is_none() {
        return acc
            .iter()
            .skip(1)
            .filter(|a| keep(a))
            .map(Acc::region)
            .collect();
    }
    let mut pieces: Vec<Acc> = Vec::with_capacity(n);
    for (l, a) in acc.iter().enumerate().skip(1) {
        if !keep(a) {
            continue;
        }
        if let Some(cfg) = columns {
            let mut counts = vec![0u32; (a.x1 - a.x0 + 1) as usize];
            for y in a.y0..=a.y1 {
                for x in a.x0..=a.x1 {
                    if labels.get_pixel(x, y)[0] as usize == l {
                        counts[(x - a.x0) as usize] += 1;
                    }
                }
            }
            let cuts = super::columns::column_cuts(&counts, f64::from(a.y1 - a.y0 + 1), cfg);
            if !cuts.is_empty() {
                let mut parts = vec![Acc::EMPTY; cuts.len() + 1];
                for y in a.y0..=a.y1 {
                    for x in a.x0..=a.x1 {
                        if labels.get_pixel(x, y)[0] as usize == l {
                            let k = cuts.partition_point(|&cut| cut <= (x - a.x0) as usize);
                            parts[k].add(x, y, w, img_ok.then(|| image.get_pixel(x, y)));
                        }
                    }
                }
                pieces.extend(parts.into_iter().filter(|p| p.n > 0));
                continue;
            }
        }
        let Some(splitter) = splitter else {
            pieces.push(*a);
            continue;
        };
        let c = a.centroid();
        let u = a.axis();
        let t_of =
            |x: u32, y: u32| (f64::from(x) + 0.5 - c.x) * u.0 + (f64::from(y) + 0.5 - c.y) * u.1;
        let (mut t_min, mut t_max) = (f64::INFINITY, f64::NEG_INFINITY);
        for y in a.y0..=a.y1 {
            for x in a.x0..=a.x1 {
                if labels.get_pixel(x, y)[0] as usize == l {
                    let t = t_of(x, y);
                    t_min = t_min.min(t);
                    t_max = t_max.max(t);
                }
            }
        }
        // Pixel centres → pixel edges.
        let cuts = splitter.cuts(c, u, t_min - 0.5, t_max + 0.5);
        if cuts.is_empty() {
            pieces.push(*a);
            continue;
        }
        let mut parts = vec![Acc::EMPTY; cuts.len() + 1];
        for y in a.y0..=a.y1 {
            for x in a.x0..=a.x1 {
                if labels.get_pixel(x, y)[0] as usize == l {
                    let t = t_of(x, y);
                    let k = cuts.partition_point(|&cut| cut <= t);
                    parts[k].add(x, y, w, img_ok.then(|| image.get_pixel(x, y)));
                }
            }
        }
        pieces.extend(parts.into_iter().filter(|p| p.n > 0));
    }
    pieces.sort_by_key(|p| p.first);
    pieces.iter().map(Acc::region).collect()
}

impl Region {
    /// The region as a detection in `frame` with `id`: centre at the centroid, size from
    /// the box, the mean colour, the area.
    pub fn to_detection(&self, frame: u32, id: u64) -> Detection {
        Detection {
            frame,
            id,
            pos_px: self.centroid_px,
            size_px: Some((self.bbox.width, self.bbox.height)),
            colour_rgb: Some(self.mean_rgb),
            class: None,
            score: None,
            area_px: Some(f64::from(self.area_px)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{GrayImage, Luma, Rgb, RgbImage};

    #[test]
    fn regions_have_exact_area_centroid_box_and_colour() {
        let mut mask = GrayImage::new(20, 10);
        let mut img = RgbImage::from_pixel(20, 10, Rgb([0, 0, 0]));
        // A 4×3 block at (2,1) coloured (10,20,30), and a 2×2 block at (15,6).
        for y in 1..4 {
            for x in 2..6 {
                mask.put_pixel(x, y, Luma([255]));
                img.put_pixel(x, y, Rgb([10, 20, 30]));
            }
        }
        for y in 6..8 {
            for x in 15..17 {
                mask.put_pixel(x, y, Luma([255]));
            }
        }
        let cfg = RegionConfig {
            min_area_px: 1,
            ..Default::default()
        };
        let r = extract_regions(&mask, &img, &cfg);
        assert_eq!(r.len(), 2);
        assert_eq!(r[0].area_px, 12);
        assert_eq!(r[0].centroid_px, Point::new(4.0, 2.5));
        assert_eq!(r[0].bbox, BBox::new(2.0, 1.0, 4.0, 3.0));
        assert_eq!(r[0].mean_rgb, [10.0, 20.0, 30.0]);
        assert_eq!(r[1].area_px, 4);
        let big_only = RegionConfig {
            min_area_px: 5,
            ..Default::default()
        };
        assert_eq!(extract_regions(&mask, &img, &big_only).len(), 1);
    }

    #[test]
    fn diagonal_pixels_are_one_region() {
        let mut mask = GrayImage::new(5, 5);
        for i in 0..5 {
            mask.put_pixel(i, i, Luma([255]));
        }
        let cfg = RegionConfig {
            min_area_px: 1,
            ..Default::default()
        };
        assert_eq!(extract_regions(&mask, &RgbImage::new(5, 5), &cfg).len(), 1);
    }

    proptest::proptest! {
        /// The separable morphology equals imageproc's (the reference) on random masks.
        #[test]
        fn clean_mask_matches_imageproc(w in 1u32..40, h in 1u32..40, seed in 0u64..1000,
                                        open in 0u8..3, close in 0u8..4, density in 1u64..9) {
            use imageproc::distance_transform::Norm;
            use rand::RngExt;
            let mut rng = crate::rng::rng_for(seed, crate::rng::Stream::Synthetic, 0);
            let mask = GrayImage::from_fn(w, h, |_, _| Luma([if rng.random_range(0..10u64) < density { 255 } else { 0 }]));
            let cfg = RegionConfig { open_radius_px: open, close_radius_px: close, ..Default::default() };
            let mut reference = mask.clone();
            if open > 0 {
                proptest::prop_assume!(mask.pixels().any(|p| p[0] == 0));
                reference = imageproc::morphology::open(&reference, Norm::LInf, open);
            }
            if close > 0 {
                // imageproc erodes an image with no background pixel at all to nothing (its
                // distance transform has no seed); ours keeps it, as the pixels outside the
                // image are ignored. Compare only where imageproc's convention applies.
                let dilated = imageproc::morphology::dilate(&reference, Norm::LInf, close);
                proptest::prop_assume!(dilated.pixels().any(|p| p[0] == 0));
                reference = imageproc::morphology::close(&reference, Norm::LInf, close);
            }
            proptest::prop_assert_eq!(clean_mask(&mask, &cfg), reference);
        }
    }

    #[test]
    fn cleaning_removes_speckle_and_keeps_blobs() {
        let mut mask = GrayImage::new(30, 30);
        mask.put_pixel(2, 2, Luma([255]));
        for y in 10..20 {
            for x in 10..20 {
                mask.put_pixel(x, y, Luma([255]));
            }
        }
        let cleaned = clean_mask(&mask, &RegionConfig::default());
        assert_eq!(cleaned.get_pixel(2, 2)[0], 0);
        let cfg = RegionConfig {
            min_area_px: 1,
            ..Default::default()
        };
        let r = extract_regions(&cleaned, &RgbImage::new(30, 30), &cfg);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].area_px, 100);
    }
}
