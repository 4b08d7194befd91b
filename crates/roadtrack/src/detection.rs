//! Detections: objects found in one frame, before any tracking.

use crate::class::ObjectClass;
use crate::geometry::{BBox, Point};

/// One object found in one frame (a row of the detections CSV, INTERFACES.md).
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    /// 1-based frame number.
    pub frame: u32,
    /// Identifier, unique within the frame.
    pub id: u64,
    /// Centre, px.
    pub pos_px: Point,
    /// Box width and height, px, when known.
    pub size_px: Option<(f64, f64)>,
    /// Mean colour of the object's pixels, 8-bit RGB (0–255), when known. Seed 000 uses it.
    pub colour_rgb: Option<[f64; 3]>,
    /// Class, when known.
    pub class: Option<ObjectClass>,
    /// Confidence in `[0, 1]`, when known.
    pub score: Option<f64>,
    /// Region area, px², when known (foreground extraction writes it).
    pub area_px: Option<f64>,
}

impl Detection {
    /// A detection with only a frame, an id and a centre.
    pub fn at(frame: u32, id: u64, pos_px: Point) -> Self {
        Self {
            frame,
            id,
            pos_px,
            size_px: None,
            colour_rgb: None,
            class: None,
            score: None,
            area_px: None,
        }
    }

    /// The box, when the size is known.
    pub fn bbox(&self) -> Option<BBox> {
        self.size_px
            .map(|(w, h)| BBox::from_centre(self.pos_px, w, h))
    }
}

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

/// Morphological clean-up of a foreground mask: opening then closing (imageproc).
pub fn clean_mask(mask: &image::GrayImage, config: &RegionConfig) -> image::GrayImage {
    use imageproc::distance_transform::Norm;
    let opened = if config.open_radius_px > 0 {
        imageproc::morphology::open(mask, Norm::LInf, config.open_radius_px)
    } else {
        mask.clone()
    };
    if config.close_radius_px > 0 {
        imageproc::morphology::close(&opened, Norm::LInf, config.close_radius_px)
    } else {
        opened
    }
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
    use imageproc::region_labelling::{Connectivity, connected_components};
    let labels = connected_components(mask, Connectivity::Eight, image::Luma([0u8]));
    // Labels are assigned in raster order of first appearance, 1..=n.
    let n = labels.pixels().map(|p| p[0]).max().unwrap_or(0) as usize;
    #[derive(Clone, Copy)]
    struct Acc {
        n: u64,
        sx: f64,
        sy: f64,
        rgb: [f64; 3],
        x0: u32,
        y0: u32,
        x1: u32,
        y1: u32,
    }
    let mut acc = vec![
        Acc {
            n: 0,
            sx: 0.0,
            sy: 0.0,
            rgb: [0.0; 3],
            x0: u32::MAX,
            y0: u32::MAX,
            x1: 0,
            y1: 0,
        };
        n + 1
    ];
    let (w, h) = labels.dimensions();
    let img_ok = image.dimensions() == (w, h);
    for y in 0..h {
        for x in 0..w {
            let l = labels.get_pixel(x, y)[0] as usize;
            if l == 0 {
                continue;
            }
            let a = &mut acc[l];
            a.n += 1;
            a.sx += f64::from(x) + 0.5;
            a.sy += f64::from(y) + 0.5;
            if img_ok {
                let p = image.get_pixel(x, y);
                for c in 0..3 {
                    a.rgb[c] += f64::from(p[c]);
                }
            }
            a.x0 = a.x0.min(x);
            a.y0 = a.y0.min(y);
            a.x1 = a.x1.max(x);
            a.y1 = a.y1.max(y);
        }
    }
    acc.iter()
        .skip(1)
        .filter(|a| a.n >= u64::from(config.min_area_px) && a.n <= u64::from(config.max_area_px))
        .map(|a| {
            let nf = a.n as f64;
            Region {
                area_px: a.n as u32,
                centroid_px: Point::new(a.sx / nf, a.sy / nf),
                bbox: BBox::new(
                    f64::from(a.x0),
                    f64::from(a.y0),
                    f64::from(a.x1 - a.x0 + 1),
                    f64::from(a.y1 - a.y0 + 1),
                ),
                mean_rgb: a.rgb.map(|s| s / nf),
            }
        })
        .collect()
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
