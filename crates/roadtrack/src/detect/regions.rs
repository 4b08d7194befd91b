//! Foreground regions: connected regions of a cleaned mask (the clean-up is
//! [`super::morphology`], re-exported here) with centroid, box, area and mean colour.

pub use super::morphology::clean_mask;
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
    /// Smallest region kept as a share of the box a standing person would have at the
    /// region's foot point (the middle of its box's bottom edge), from the calibration's
    /// camera ([`super::split::PersonSize`]). Drops the pieces of a person (a head or legs
    /// beside a post), pieces of vehicles and small ghosts, at any distance from the
    /// camera. Needs a calibration that sees heights (an oblique one, `--calibration`);
    /// without one it does nothing. Default 0.4; `--as-published` 0 (off).
    ///
    /// Choice: on by default since it only acts with a calibration and, on the simulator's
    /// oblique scenes (seeds 0–2, docs/EXPERIMENTS.md "Far pedestrians"), it left every
    /// recall as it was and raised every precision or kept it (oblique road 0.64–0.75 →
    /// 0.65–0.76, intersection 0.50–0.78 → 0.56–0.84, crossing 0.43–0.49 → 0.55–0.62).
    /// Under 0.5, because a box under half a person's cannot match that person at IoU 0.5.
    pub min_person_share: f64,
    /// With `min_person_share` on and a person size known at a region's foot point, the
    /// smallest region kept there, px², in place of `min_area_px`: the share decides, and
    /// this floor only drops specks. The ghost test looks at regions down to it too.
    /// Elsewhere (no calibration, a nadir one, a foot point off the ground) `min_area_px`
    /// applies. Default 0 (`min_area_px` everywhere); `configs/detect-pedestrians.toml` and
    /// `configs/detect-intersection.toml` set 20.
    ///
    /// Choice: 20 in those configs, not by default. A fixed `min_area_px` of 60 dropped
    /// most of the far pedestrians of the simulator's oblique intersection (their boxes
    /// 31–72 px², median 44, for 1 716 of 2 428 missed on seed 2), but on the oblique road,
    /// which has no one to find, 20 keeps small pieces of vehicles (precision 0.75 → 0.71,
    /// seed 0; docs/EXPERIMENTS.md "Far pedestrians").
    pub person_min_area_px: u32,
    /// Where a detection's centre is: `"box"` (the middle of the region's tight box, so
    /// that centre ± size / 2 is that box) or `"centroid"` (the mean of its pixels, seed
    /// 000's vehicle position; METHODS.md §1 "Vehicle extraction"). Default `"box"`;
    /// `--as-published` uses `"centroid"`.
    ///
    /// Choice: the box centre by default. A detection carries one centre and a size, and
    /// every box that is written or scored (detections CSV, MOTChallenge output, IoU) is
    /// centre ± size / 2. With the centroid that box is shifted towards the denser part of
    /// the region (a car's body against its shadow, the near end of an oblique vehicle):
    /// on the oblique road, seed 0, precision at IoU 0.5 0.72 → 0.75 with the box centre
    /// (docs/EXPERIMENTS.md, "Detection").
    pub position: RegionPosition,
    /// Cut a region where the time its pixels have been foreground jumps by more than this,
    /// s ([`super::age_cut`]): a person or vehicle passing a queued vehicle becomes a region
    /// of its own instead of part of the queue's. Default 2; 0 disables it
    /// (`--as-published`, `configs/detect-pedestrians.toml`).
    ///
    /// Choice: 2 s, measured against 0, 1 and 4 s on the simulator's scenes (seeds 0–3,
    /// docs/EXPERIMENTS.md "Age cut"): 1 s cuts more pieces off people and ghosts, 4 s
    /// lets vehicles that stopped behind each other stay joined longer.
    pub age_gap_s: f64,
    /// For `age_gap_s`: a pixel that leaves the mask and comes back within this time keeps
    /// its age, s. Default 0.3.
    pub age_grace_s: f64,
    /// For `age_gap_s`: a piece of the cut smaller than this is joined again to what it
    /// was cut from, px². Default 0 (every piece stays).
    pub age_min_piece_px: u32,
}

/// Which point of a region is its detection's centre ([`RegionConfig::position`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RegionPosition {
    /// The middle of the tight box.
    #[default]
    Box,
    /// The mean of the pixels.
    Centroid,
}

impl Default for RegionConfig {
    fn default() -> Self {
        Self {
            open_radius_px: 1,
            close_radius_px: 3,
            min_area_px: 60,
            max_area_px: 50_000,
            min_person_share: 0.4,
            person_min_area_px: 0,
            position: RegionPosition::Box,
            age_gap_s: 2.0,
            age_grace_s: 0.3,
            age_min_piece_px: 0,
        }
    }
}

impl RegionConfig {
    /// Checks the ranges.
    pub fn validate(&self) -> crate::Result<()> {
        if !(0.0..=1.0).contains(&self.min_person_share) {
            return Err(crate::Error::config(
                "RegionConfig",
                "min_person_share",
                format!("must be in [0, 1], found {}", self.min_person_share),
            ));
        }
        for (name, v) in [
            ("age_gap_s", self.age_gap_s),
            ("age_grace_s", self.age_grace_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(crate::Error::config(
                    "RegionConfig",
                    name,
                    format!("must be a number ≥ 0, found {v}"),
                ));
            }
        }
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

/// The 8-connected components of non-zero pixels of `mask`, each as its runs `(y, x0, x1)`
/// (pixels `x0..x1` of row `y`) in raster order; components ordered by their first pixel.
pub(super) fn component_runs(mask: &image::GrayImage) -> Vec<Vec<(u32, u32, u32)>> {
    let comps = Components::label(mask);
    let mut out = vec![Vec::new(); comps.count];
    for (r, &l) in comps.runs.iter().zip(&comps.label) {
        out[l as usize].push((r.y, r.x0, r.x1));
    }
    out
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

    /// Adds the pixels of `run`, whose colours are `rgb` (3 bytes per pixel) when given.
    /// Equal to adding them one by one with [`Acc::add`]: every sum is exact.
    fn add_run(&mut self, run: &Run, width: u32, rgb: Option<&[u8]>) {
        let (x0, x1, y) = (u64::from(run.x0), u64::from(run.x1), run.y);
        let len = x1 - x0;
        if len == 0 {
            return;
        }
        if self.n == 0 {
            self.first = u64::from(y) * u64::from(width) + x0;
        }
        self.n += len;
        // Σ (x + ½) and Σ (x + ½)² over x0..x1, from Σ x and Σ x².
        let sum_sq = |n: u64| n * (n + 1) * (2 * n + 1) / 6; // Σ_{x ≤ n} x² (n ≥ 0)
        let s1 = (x0 + x1 - 1) * len / 2;
        let s2 = sum_sq(x1 - 1) - if x0 > 0 { sum_sq(x0 - 1) } else { 0 };
        let sx = s1 as f64 + 0.5 * len as f64;
        let sxx = s2 as f64 + s1 as f64 + 0.25 * len as f64;
        let fy = f64::from(y) + 0.5;
        self.sx += sx;
        self.sy += fy * len as f64;
        self.sxx += sxx;
        self.syy += fy * fy * len as f64;
        self.sxy += fy * sx;
        if let Some(px) = rgb {
            let mut sum = [0u64; 3];
            for p in px.chunks_exact(3) {
                for (s, &v) in sum.iter_mut().zip(p) {
                    *s += u64::from(v);
                }
            }
            for (acc, s) in self.rgb.iter_mut().zip(sum) {
                *acc += s as f64;
            }
        }
        self.x0 = self.x0.min(run.x0);
        self.y0 = self.y0.min(y);
        self.x1 = self.x1.max(run.x1 - 1);
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
    let (w, _) = mask.dimensions();
    let img_ok = image.dimensions() == mask.dimensions();
    let px = image.as_raw();
    let comps = Components::label(mask);
    // Choice: the sums are exact in f64 (multiples of 1/4 far below 2^53), so summing a run
    // at once gives bit for bit what summing its pixels one by one gives.
    let mut acc = vec![Acc::EMPTY; comps.count];
    for (run, &l) in comps.runs.iter().zip(&comps.label) {
        let rgb = img_ok.then(|| {
            let i = 3 * (run.y as usize * w as usize + run.x0 as usize);
            &px[i..i + 3 * (run.x1 - run.x0) as usize]
        });
        acc[l as usize].add_run(run, w, rgb);
    }
    let keep =
        |a: &Acc| a.n >= u64::from(config.min_area_px) && a.n <= u64::from(config.max_area_px);
    if splitter.is_none() && columns.is_none() {
        return acc.iter().filter(|a| keep(a)).map(Acc::region).collect();
    }
    let members = comps.members();
    // Every pixel of component `l`, in raster order.
    let pixels_of = |l: usize| {
        members[l].iter().flat_map(|&k| {
            let r = comps.runs[k as usize];
            (r.x0..r.x1).map(move |x| (x, r.y))
        })
    };
    let rgb_at = |x: u32, y: u32| img_ok.then(|| image.get_pixel(x, y));
    let mut pieces: Vec<Acc> = Vec::with_capacity(acc.len());
    for (l, a) in acc.iter().enumerate() {
        if !keep(a) {
            continue;
        }
        if let Some(cfg) = columns {
            let mut counts = vec![0u32; (a.x1 - a.x0 + 1) as usize];
            for (x, _) in pixels_of(l) {
                counts[(x - a.x0) as usize] += 1;
            }
            let cuts = super::columns::column_cuts(&counts, f64::from(a.y1 - a.y0 + 1), cfg);
            if !cuts.is_empty() {
                let mut parts = vec![Acc::EMPTY; cuts.len() + 1];
                for (x, y) in pixels_of(l) {
                    let k = cuts.partition_point(|&cut| cut <= (x - a.x0) as usize);
                    parts[k].add(x, y, w, rgb_at(x, y));
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
        for (x, y) in pixels_of(l) {
            let t = t_of(x, y);
            t_min = t_min.min(t);
            t_max = t_max.max(t);
        }
        // Pixel centres → pixel edges.
        let cuts = splitter.cuts(c, u, t_min - 0.5, t_max + 0.5);
        if cuts.is_empty() {
            pieces.push(*a);
            continue;
        }
        let mut parts = vec![Acc::EMPTY; cuts.len() + 1];
        for (x, y) in pixels_of(l) {
            let t = t_of(x, y);
            let k = cuts.partition_point(|&cut| cut <= t);
            parts[k].add(x, y, w, rgb_at(x, y));
        }
        pieces.extend(parts.into_iter().filter(|p| p.n > 0));
    }
    pieces.sort_by_key(|p| p.first);
    pieces.iter().map(Acc::region).collect()
}

/// A horizontal run of set pixels: row `y`, columns `x0..x1`.
#[derive(Clone, Copy, Debug)]
struct Run {
    y: u32,
    x0: u32,
    x1: u32,
}

/// The 8-connected components of a mask as runs (raster order) and a label per run,
/// `0..count` in raster order of each component's first pixel.
struct Components {
    runs: Vec<Run>,
    label: Vec<u32>,
    count: usize,
}

impl Components {
    /// Run-length labelling: the runs of each row, joined by union-find to the runs of the
    /// row above that they touch (8-connectivity: overlapping or diagonally adjacent).
    fn label(mask: &image::GrayImage) -> Self {
        let w = mask.width() as usize;
        let mut runs: Vec<Run> = Vec::new();
        let mut parent: Vec<u32> = Vec::new();
        if w > 0 {
            // First run of the previous row, and of this row.
            let mut prev_start = 0usize;
            for (y, row) in mask.as_raw().chunks_exact(w).enumerate() {
                let start = runs.len();
                if !row.iter().all(|&v| v == 0) {
                    let mut x = 0usize;
                    while x < w {
                        if row[x] == 0 {
                            x += 1;
                            continue;
                        }
                        let x0 = x;
                        while x < w && row[x] != 0 {
                            x += 1;
                        }
                        let k = runs.len() as u32;
                        runs.push(Run {
                            y: y as u32,
                            x0: x0 as u32,
                            x1: x as u32,
                        });
                        parent.push(k);
                    }
                }
                // Join with the previous row's runs (two pointers; both rows sorted by x).
                let mut j = prev_start;
                for c in start..runs.len() {
                    let cur = runs[c];
                    while j < start && runs[j].x1 < cur.x0 {
                        j += 1;
                    }
                    let mut k = j;
                    while k < start && runs[k].x0 <= cur.x1 {
                        union(&mut parent, k as u32, c as u32);
                        k += 1;
                    }
                }
                prev_start = start;
            }
        }
        // Labels in order of each component's first run (raster order).
        let mut label_of_root = vec![u32::MAX; runs.len()];
        let mut label = Vec::with_capacity(runs.len());
        let mut count = 0u32;
        for k in 0..runs.len() {
            let r = find(&mut parent, k as u32) as usize;
            if label_of_root[r] == u32::MAX {
                label_of_root[r] = count;
                count += 1;
            }
            label.push(label_of_root[r]);
        }
        Self {
            runs,
            label,
            count: count as usize,
        }
    }

    /// The run indices of each component, in raster order.
    fn members(&self) -> Vec<Vec<u32>> {
        let mut m = vec![Vec::new(); self.count];
        for (k, &l) in self.label.iter().enumerate() {
            m[l as usize].push(k as u32);
        }
        m
    }
}

/// Union-find root with path halving.
fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let p = parent[parent[x as usize] as usize];
        parent[x as usize] = p;
        x = p;
    }
    x
}

/// Joins the sets of `a` and `b` under the smaller root (keeps roots deterministic).
fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        let (lo, hi) = (ra.min(rb), ra.max(rb));
        parent[hi as usize] = lo;
    }
}

impl Region {
    /// The region as a detection in `frame` with `id`: centre at the box's middle or the
    /// centroid (`position`), size from the box, the mean colour, the area.
    pub fn to_detection(&self, frame: u32, id: u64, position: RegionPosition) -> Detection {
        let pos_px = match position {
            RegionPosition::Box => self.bbox.centre(),
            RegionPosition::Centroid => self.centroid_px,
        };
        Detection {
            frame,
            id,
            pos_px,
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
    fn a_detection_box_is_the_region_box_unless_the_centroid_is_asked_for() {
        // An L: a 6 × 2 bar with a 2 × 4 leg under its left end. Its pixels' mean lies
        // left of and above the box's middle.
        let mut mask = GrayImage::new(12, 10);
        for (x, y) in (1..7).flat_map(|x| (1..3).map(move |y| (x, y))) {
            mask.put_pixel(x, y, Luma([255]));
        }
        for (x, y) in (1..3).flat_map(|x| (3..7).map(move |y| (x, y))) {
            mask.put_pixel(x, y, Luma([255]));
        }
        let img = RgbImage::new(12, 10);
        let cfg = RegionConfig {
            min_area_px: 1,
            open_radius_px: 0,
            close_radius_px: 0,
            ..Default::default()
        };
        let r = extract_regions(&mask, &img, &cfg);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].bbox, BBox::new(1.0, 1.0, 6.0, 6.0));
        let d = r[0].to_detection(3, 7, RegionPosition::Box);
        let (w, h) = d.size_px.unwrap();
        assert_eq!(BBox::from_centre(d.pos_px, w, h), r[0].bbox);
        let c = r[0].to_detection(3, 7, RegionPosition::Centroid);
        assert_eq!(c.pos_px, r[0].centroid_px);
        assert!(c.pos_px.x < d.pos_px.x && c.pos_px.y < d.pos_px.y);
        assert_eq!((c.frame, c.id, c.size_px), (3, 7, d.size_px));
    }

    #[test]
    fn region_position_reads_box_and_centroid_and_refuses_others() {
        let read = |s: &str| toml::from_str::<RegionConfig>(s);
        assert_eq!(read("").unwrap().position, RegionPosition::Box);
        assert_eq!(
            read("position = \"centroid\"").unwrap().position,
            RegionPosition::Centroid
        );
        let e = read("position = \"middle\"").unwrap_err().to_string();
        assert!(
            e.contains("position = \"middle\"") && e.contains("expected `box` or `centroid`"),
            "{e}"
        );
    }

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

    /// The implementation before run-length labelling (imageproc's pixel labelling, one
    /// pixel at a time): the reference the run-based one must equal.
    #[allow(clippy::too_many_lines)]
    fn reference_extract(
        mask: &image::GrayImage,
        image: &image::RgbImage,
        config: &RegionConfig,
        splitter: Option<&crate::detect::split::Splitter>,
        columns: Option<&crate::detect::split::SplitConfig>,
    ) -> Vec<Region> {
        use imageproc::region_labelling::{Connectivity, connected_components};
        // imageproc 0.27 sizes its union-find w·h and numbers labels from 1: a 1 × 1
        // foreground mask overflows it (a panic, found by the property test below).
        let labels = if mask.dimensions() == (1, 1) {
            image::ImageBuffer::from_fn(1, 1, |x, y| {
                image::Luma([u32::from(mask.get_pixel(x, y)[0] != 0)])
            })
        } else {
            connected_components(mask, Connectivity::Eight, image::Luma([0u8]))
        };
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
                let cuts =
                    crate::detect::columns::column_cuts(&counts, f64::from(a.y1 - a.y0 + 1), cfg);
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
            let t_of = |x: u32, y: u32| {
                (f64::from(x) + 0.5 - c.x) * u.0 + (f64::from(y) + 0.5 - c.y) * u.1
            };
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

    /// A random mask of `n` filled rectangles and speckle, and a random image.
    fn random_scene(w: u32, h: u32, seed: u64, n: u32) -> (GrayImage, RgbImage) {
        use rand::RngExt;
        let mut rng = crate::rng::rng_for(seed, crate::rng::Stream::Synthetic, 1);
        let mut mask = GrayImage::new(w, h);
        for _ in 0..n {
            let (x0, y0) = (rng.random_range(0..w), rng.random_range(0..h));
            let (bw, bh) = (
                rng.random_range(1..=w / 2 + 1),
                rng.random_range(1..=h / 2 + 1),
            );
            for y in y0..(y0 + bh).min(h) {
                for x in x0..(x0 + bw).min(w) {
                    mask.put_pixel(x, y, Luma([255]));
                }
            }
        }
        for _ in 0..(w * h / 20) {
            let (x, y) = (rng.random_range(0..w), rng.random_range(0..h));
            mask.put_pixel(x, y, Luma([rng.random_range(0..2u8) * 255]));
        }
        let img = RgbImage::from_fn(w, h, |_, _| {
            Rgb([
                rng.random_range(0..=255u8),
                rng.random_range(0..=255u8),
                rng.random_range(0..=255u8),
            ])
        });
        (mask, img)
    }

    proptest::proptest! {
        /// Run-length labelling gives exactly the regions of the pixel-by-pixel reference,
        /// in the same order, whole and cut into columns.
        #[test]
        fn run_labelling_matches_pixel_reference(w in 1u32..150, h in 1u32..40, seed in 0u64..10_000,
                                                 n in 0u32..8, min_area in 1u32..20) {
            let (mask, img) = random_scene(w, h, seed, n);
            let cfg = RegionConfig { min_area_px: min_area, ..Default::default() };
            let columns = crate::detect::split::SplitConfig { columns: true, ..Default::default() };
            proptest::prop_assert_eq!(
                extract_regions_split(&mask, &img, &cfg, None, None),
                reference_extract(&mask, &img, &cfg, None, None));
            proptest::prop_assert_eq!(
                extract_regions_split(&mask, &img, &cfg, None, Some(&columns)),
                reference_extract(&mask, &img, &cfg, None, Some(&columns)));
        }
    }

    #[test]
    fn run_labelling_matches_pixel_reference_when_a_splitter_cuts() {
        use crate::detect::split::{SplitConfig, Splitter};
        let (cal, _) = crate::detect::split::tests::pinhole();
        let splitter = Splitter::new(SplitConfig::default(), cal, 640, 480);
        let cfg = RegionConfig::default();
        let mut cut = 0;
        for seed in 0..12 {
            let (mask, img) = random_scene(640, 480, seed, 6);
            let mask = clean_mask(&mask, &cfg);
            let got = extract_regions_split(&mask, &img, &cfg, Some(&splitter), None);
            let want = reference_extract(&mask, &img, &cfg, Some(&splitter), None);
            assert_eq!(got, want, "seed {seed}");
            cut += got.len() - extract_regions(&mask, &img, &cfg).len();
        }
        assert!(
            cut > 0,
            "the splitter cut no region: the test exercises nothing"
        );
    }
}
