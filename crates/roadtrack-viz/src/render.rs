//! Annotated frames: boxes, ids, class colours and fading trails over the images, for any
//! tracker output or ground truth, alone or side by side (issue 8, part 3).
//!
//! A [`Renderer`] keeps, per id, the centres of the last [`RenderConfig::trail_frames`]
//! frames and draws, for each frame:
//! 1. every id's trail: the polyline through its recent box centres, each segment blended
//!    over the frame with opacity `1 − age / trail_frames` (age in frames of the segment's
//!    newer end), so the trail fades out towards its tail;
//! 2. every box, 2 px, in the id's colour (or the class's, see [`ColourBy`]), and a dot at
//!    its centre (a point without a box size is drawn as a ring);
//! 3. a label `"<id> <class>"` above the box on a filled tag of the box colour, with a
//!    small swatch of the class colour when boxes are coloured by id.
//!
//! Drawing is integer arithmetic on a deterministic order (ids ascending), so the same
//! frames and points give byte-identical images.
//!
//! The command line runs renderers inside the tracking pipeline (its overlay sink), one
//! for the tracks and one for the ground truth beside them ([`side_by_side`]).

use crate::overlay::{
    LABEL_PADDING, class_colour, draw_box, draw_dot, draw_faded_polyline, draw_label, font,
    id_colour, label_tile, paste_tile,
};
use ab_glyph::FontRef;
use image::{Rgb, RgbImage};
use imageproc::drawing::draw_hollow_circle_mut;
use roadtrack_core::ObjectClass;
use roadtrack_core::error::{Error, Result};
use roadtrack_core::frame::Frame;
use roadtrack_core::geometry::Point;
use roadtrack_core::track_point::TrackPoint;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap, VecDeque};

/// What decides the colour of a box and its trail.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum ColourBy {
    /// One colour per id ([`id_colour`]): identity switches show as colour changes. The
    /// label carries a swatch of the class colour.
    #[default]
    #[cfg_attr(feature = "clap", value(help = "One colour per track id"))]
    Id,
    /// One colour per class ([`class_colour`]); ids are told apart by their labels.
    #[cfg_attr(feature = "clap", value(help = "One colour per class"))]
    Class,
}

/// How frames are annotated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderConfig {
    /// Trail length in frames: centres older than this many frames are dropped (default 30,
    /// 3 s at the 10 frames/s of image folders).
    pub trail_frames: u32,
    /// Trail width, px (default 3).
    pub trail_width_px: f32,
    /// Colour boxes and trails by id or by class (default by id).
    pub colour_by: ColourBy,
    /// Draw id/class labels (default true).
    pub labels: bool,
    /// Label text height, px; `None` picks `clamp(height / 40, 9, 18)` from the frame.
    pub label_height_px: Option<f32>,
    /// Title of the tracker half in side-by-side output (default "tracks").
    pub tracks_title: String,
    /// Title of the ground-truth half in side-by-side output (default "ground truth").
    pub truth_title: String,
}

impl Default for RenderConfig {
    fn default() -> Self {
        Self {
            // Choice: the issue leaves the trail length open; 30 frames follows the brief.
            trail_frames: 30,
            trail_width_px: 3.0,
            colour_by: ColourBy::Id,
            labels: true,
            label_height_px: None,
            tracks_title: "tracks".into(),
            truth_title: "ground truth".into(),
        }
    }
}

impl RenderConfig {
    /// Fails when a value cannot be drawn.
    pub fn validate(&self) -> Result<()> {
        if !(self.trail_width_px.is_finite() && self.trail_width_px > 0.0) {
            return Err(Error::config(
                "RenderConfig",
                "trail_width_px",
                format!("must be positive, found {}", self.trail_width_px),
            ));
        }
        if let Some(h) = self.label_height_px
            && !(h.is_finite() && h >= 4.0)
        {
            return Err(Error::config(
                "RenderConfig",
                "label_height_px",
                format!("must be at least 4, found {h}"),
            ));
        }
        Ok(())
    }

    fn label_height(&self, image_height: u32) -> f32 {
        self.label_height_px
            .unwrap_or_else(|| (image_height as f32 / 40.0).clamp(9.0, 18.0))
    }
}

/// Draws annotated frames and keeps the trail of every id between calls.
#[derive(Debug)]
pub struct Renderer {
    config: RenderConfig,
    font: FontRef<'static>,
    /// Per id: (frame, centre) of the most recent points, oldest first.
    trails: BTreeMap<u64, VecDeque<(u32, Point)>>,
    /// The labels drawn so far, by text, height and colour ([`label_tile`]).
    // Choice: kept whole up to LABEL_TILES labels, then emptied: a sequence's labels are
    // its ids' (a few hundred), and the glyphs were 7 % of the demo overlay's CPU.
    label_tiles: HashMap<(String, u32, [u8; 3]), RgbImage>,
}

/// The most labels a [`Renderer`] keeps drawn.
const LABEL_TILES: usize = 4096;

impl Renderer {
    /// A renderer with empty trails.
    ///
    /// # Errors
    /// An invalid `config`.
    pub fn new(config: RenderConfig) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config,
            font: font()?,
            trails: BTreeMap::new(),
            label_tiles: HashMap::new(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &RenderConfig {
        &self.config
    }

    /// Forgets every trail (for example before rendering another sequence).
    pub fn reset(&mut self) {
        self.trails.clear();
    }

    /// The frame's image with `points` drawn over it.
    ///
    /// Pass the points of this frame; points of other frames (`point.frame !=
    /// frame.index`) are ignored. Frames must come in increasing order for the trails to
    /// make sense; a frame number lower than a trail's newest point restarts that trail.
    pub fn render(&mut self, frame: &Frame, points: &[TrackPoint]) -> RgbImage {
        let mut image = frame.image.clone();
        let mut now: Vec<&TrackPoint> = points.iter().filter(|p| p.frame == frame.index).collect();
        now.sort_by_key(|p| p.id);
        now.dedup_by_key(|p| p.id);
        self.update_trails(frame.index, &now);
        let colour_of = |id: u64, class: &ObjectClass| match self.config.colour_by {
            ColourBy::Id => id_colour(id),
            ColourBy::Class => class_colour(class),
        };
        // 1. Trails, ids ascending; the class for a trail comes from the current point
        //    when there is one.
        let n = self.config.trail_frames.max(1) as f32;
        for (id, trail) in &self.trails {
            let class = now
                .iter()
                .find(|p| p.id == *id)
                .map_or(ObjectClass::Unknown, |p| p.class.clone());
            let pts: Vec<Point> = trail.iter().map(|&(_, c)| c).collect();
            let alphas: Vec<f32> = trail
                .iter()
                .skip(1)
                .map(|&(f, _)| 1.0 - frame.index.saturating_sub(f) as f32 / n)
                .collect();
            draw_faded_polyline(
                &mut image,
                &pts,
                &alphas,
                colour_of(*id, &class),
                self.config.trail_width_px,
            );
        }
        // 2. Boxes and centres.
        for p in &now {
            let colour = colour_of(p.id, &p.class);
            let c = p.bbox.centre();
            if p.bbox.width >= 1.0 && p.bbox.height >= 1.0 {
                draw_box(&mut image, &p.bbox, colour);
                draw_dot(&mut image, c, 1.5, colour);
            } else {
                let (x, y) = (c.x.round() as i32, c.y.round() as i32);
                draw_hollow_circle_mut(&mut image, (x, y), 4, colour);
                draw_hollow_circle_mut(&mut image, (x, y), 5, colour);
            }
        }
        // 3. Labels on top of everything.
        if self.config.labels {
            let height = self.config.label_height(image.height());
            let colours: Vec<Rgb<u8>> = now.iter().map(|p| colour_of(p.id, &p.class)).collect();
            for (p, colour) in now.iter().zip(colours) {
                self.draw_point_label(&mut image, p, colour, height);
            }
        }
        image
    }

    fn update_trails(&mut self, index: u32, now: &[&TrackPoint]) {
        let keep = self.config.trail_frames;
        for p in now {
            let trail = self.trails.entry(p.id).or_default();
            if trail.back().is_some_and(|&(f, _)| f >= index) {
                trail.clear();
            }
            trail.push_back((index, p.bbox.centre()));
        }
        for trail in self.trails.values_mut() {
            while trail
                .front()
                .is_some_and(|&(f, _)| index.saturating_sub(f) > keep)
            {
                trail.pop_front();
            }
        }
        self.trails.retain(|_, t| !t.is_empty());
    }

    fn draw_point_label(&mut self, image: &mut RgbImage, p: &TrackPoint, colour: Rgb<u8>, h: f32) {
        let text = if p.class == ObjectClass::Unknown {
            p.id.to_string()
        } else {
            format!("{} {}", p.id, p.class)
        };
        if self.label_tiles.len() >= LABEL_TILES {
            self.label_tiles.clear();
        }
        let font = &self.font;
        let tile = self
            .label_tiles
            .entry((text, h.to_bits(), colour.0))
            .or_insert_with_key(|(text, _, _)| label_tile(font, h, text, colour));
        let (px, py) = LABEL_PADDING;
        let (tw, th) = (tile.width() - 2 * px, tile.height() - 2 * py);
        let swatch =
            matches!(self.config.colour_by, ColourBy::Id) && p.class != ObjectClass::Unknown;
        let sw = if swatch { th + 2 } else { 0 };
        let (lw, lh) = (tw + 4 + sw, th + 2);
        // Above the box when it fits, else just inside its top edge; kept inside the image.
        let (iw, ih) = image.dimensions();
        let mut x = p.bbox.left.round() as i64;
        let mut y = p.bbox.top.round() as i64 - i64::from(lh);
        if y < 0 {
            y = p.bbox.top.round() as i64 + 2;
        }
        x = x.clamp(0, (i64::from(iw) - i64::from(lw)).max(0));
        y = y.clamp(0, (i64::from(ih) - i64::from(lh)).max(0));
        let (x, y) = (x as i32, y as i32);
        if swatch {
            imageproc::drawing::draw_filled_rect_mut(
                image,
                imageproc::rect::Rect::at(x, y).of_size(sw, lh),
                class_colour(&p.class),
            );
        }
        paste_tile(image, tile, (x + sw as i32, y));
    }
}

/// `left` and `right` next to each other, each with its title in a dark banner at its
/// top-left corner. The result is `left.width + right.width` wide and as tall as the taller
/// image (the shorter one is padded with black below).
pub fn side_by_side(
    left: &RgbImage,
    right: &RgbImage,
    left_title: &str,
    right_title: &str,
) -> Result<RgbImage> {
    let f = font()?;
    let (lw, lh) = left.dimensions();
    let (rw, rh) = right.dimensions();
    let mut out = RgbImage::new(lw + rw, lh.max(rh));
    paste_rows(&mut out, left, 0);
    paste_rows(&mut out, right, lw);
    let h = (out.height() as f32 / 30.0).clamp(9.0, 22.0);
    let banner = Rgb([20, 20, 20]);
    if !left_title.is_empty() {
        draw_label(&mut out, &f, h, (0, 0), left_title, banner);
    }
    if !right_title.is_empty() {
        draw_label(&mut out, &f, h, (lw as i32, 0), right_title, banner);
    }
    // A 1-px divider so the halves do not run together.
    if lw > 0 {
        for y in 0..out.height() {
            out.put_pixel(lw - 1, y, Rgb([255, 255, 255]));
        }
    }
    Ok(out)
}

/// Points grouped by frame, each group sorted by id.
pub fn group_by_frame(points: &[TrackPoint]) -> BTreeMap<u32, Vec<TrackPoint>> {
    let mut out: BTreeMap<u32, Vec<TrackPoint>> = BTreeMap::new();
    for p in points {
        out.entry(p.frame).or_default().push(p.clone());
    }
    for v in out.values_mut() {
        v.sort_by_key(|p| p.id);
    }
    out
}

/// Copies `src` into `out` with its top-left corner at column `x0`, row by row:
/// `image::imageops::replace` without its per-pixel bounds checks, which cost the demo's
/// overlay a tenth of its CPU. `src` must fit (`x0 + src.width() <= out.width()`, no taller).
fn paste_rows(out: &mut RgbImage, src: &RgbImage, x0: u32) {
    let row_out = out.width() as usize * 3;
    let row_src = src.width() as usize * 3;
    let at = x0 as usize * 3;
    let dst: &mut [u8] = out;
    for (d, s) in dst.chunks_exact_mut(row_out).zip(src.chunks_exact(row_src)) {
        d[at..at + row_src].copy_from_slice(s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use roadtrack_core::geometry::BBox;

    fn frame(index: u32) -> Frame {
        Frame {
            index,
            time_s: f64::from(index - 1) / 10.0,
            image: RgbImage::from_pixel(120, 80, Rgb([0, 0, 0])),
        }
    }

    fn point(frame: u32, id: u64, left: f64, top: f64) -> TrackPoint {
        TrackPoint {
            frame,
            time_s: f64::from(frame - 1) / 10.0,
            id,
            class: ObjectClass::Unknown,
            bbox: BBox::new(left, top, 20.0, 10.0),
            score: 1.0,
            ground: None,
        }
    }

    fn no_labels() -> RenderConfig {
        RenderConfig {
            labels: false,
            ..RenderConfig::default()
        }
    }

    #[test]
    fn boxes_land_where_the_points_say() -> Result<()> {
        let mut r = Renderer::new(no_labels())?;
        let img = r.render(&frame(1), &[point(1, 3, 30.0, 40.0)]);
        let c = id_colour(3);
        // Outline: left edge column 30, top row 40, right edge column 49.
        assert_eq!(img.get_pixel(30, 45), &c);
        assert_eq!(img.get_pixel(35, 40), &c);
        assert_eq!(img.get_pixel(49, 45), &c);
        // Inside (away from the centre dot) and outside stay black.
        assert_eq!(img.get_pixel(34, 44), &Rgb([0, 0, 0]));
        assert_eq!(img.get_pixel(60, 45), &Rgb([0, 0, 0]));
        // Centre dot at (40, 45).
        assert_eq!(img.get_pixel(40, 45), &c);
        Ok(())
    }

    #[test]
    fn points_of_other_frames_are_ignored() -> Result<()> {
        let mut r = Renderer::new(no_labels())?;
        let img = r.render(&frame(1), &[point(2, 3, 30.0, 40.0)]);
        assert_eq!(img, frame(1).image);
        Ok(())
    }

    #[test]
    fn trails_follow_the_centres_and_fade_with_age() -> Result<()> {
        let config = RenderConfig {
            trail_frames: 4,
            ..no_labels()
        };
        let mut r = Renderer::new(config)?;
        // Centre moves right along y = 15 by 20 px per frame: x = 20, 40, 60, 80.
        let mut img = RgbImage::new(1, 1);
        for f in 1..=4u32 {
            let left = 10.0 + 20.0 * f64::from(f - 1);
            img = r.render(&frame(f), &[point(f, 1, left, 10.0)]);
        }
        let c = id_colour(1);
        let blended = |a: f32| Rgb(c.0.map(|v| (f32::from(v) * a).round() as u8));
        // The trail runs along y = 15 (pixel rows 14 and 15). A segment's opacity is
        // 1 − age / 4 with the age of its newer end: 60→80 age 0 → 1, 40→60 age 1 → 0.75,
        // 20→40 age 2 → 0.5.
        assert_eq!(img.get_pixel(65, 14), &c);
        assert_eq!(img.get_pixel(50, 14), &blended(0.75));
        assert_eq!(img.get_pixel(30, 14), &blended(0.5));
        // Off the trail.
        assert_eq!(img.get_pixel(30, 30), &Rgb([0, 0, 0]));
        // Five frames later with no points, the trail has aged out.
        let img = r.render(&frame(9), &[]);
        assert_eq!(img, frame(9).image);
        Ok(())
    }

    #[test]
    fn rendering_is_deterministic() -> Result<()> {
        let config = RenderConfig::default();
        let run = || -> Result<Vec<RgbImage>> {
            let mut r = Renderer::new(config.clone())?;
            Ok((1..=5u32)
                .map(|f| {
                    let mut a = point(f, 7, 5.0 + 8.0 * f64::from(f), 20.0);
                    a.class = ObjectClass::Car;
                    let b = point(f, 2, 90.0 - 6.0 * f64::from(f), 50.0);
                    r.render(&frame(f), &[b, a])
                })
                .collect())
        };
        let (a, b) = (run()?, run()?);
        assert_eq!(a, b);
        // Labels were drawn: box 7 (a car) has a class-colour swatch on its tag.
        assert!(a[4].pixels().any(|p| *p == class_colour(&ObjectClass::Car)));
        Ok(())
    }

    #[test]
    fn colouring_by_class_uses_the_class_colour() -> Result<()> {
        let config = RenderConfig {
            colour_by: ColourBy::Class,
            ..no_labels()
        };
        let mut r = Renderer::new(config)?;
        let mut p = point(1, 3, 30.0, 40.0);
        p.class = ObjectClass::Pedestrian;
        let img = r.render(&frame(1), &[p]);
        assert_eq!(
            img.get_pixel(30, 45),
            &class_colour(&ObjectClass::Pedestrian)
        );
        Ok(())
    }

    #[test]
    fn side_by_side_is_twice_as_wide_with_each_half_in_place() -> Result<()> {
        let left = RgbImage::from_pixel(50, 40, Rgb([10, 20, 30]));
        let right = RgbImage::from_pixel(50, 40, Rgb([200, 100, 0]));
        let out = side_by_side(&left, &right, "tracks", "truth")?;
        assert_eq!(out.dimensions(), (100, 40));
        assert_eq!(out.get_pixel(20, 35), &Rgb([10, 20, 30]));
        assert_eq!(out.get_pixel(80, 35), &Rgb([200, 100, 0]));
        // Banners: dark tag with white text at each half's top-left.
        assert!((50..75).any(|x| out.get_pixel(x, 5).0[0] == 20));
        Ok(())
    }

    #[test]
    fn paste_rows_agrees_with_imageops_replace() {
        let src = RgbImage::from_fn(7, 5, |x, y| Rgb([x as u8 * 30, y as u8 * 40, 99]));
        for (w, h, x0) in [(7, 5, 0), (20, 5, 13), (20, 9, 6)] {
            let mut ours = RgbImage::from_pixel(w, h, Rgb([1, 2, 3]));
            let mut theirs = ours.clone();
            paste_rows(&mut ours, &src, x0);
            image::imageops::replace(&mut theirs, &src, i64::from(x0), 0);
            assert_eq!(ours, theirs, "{w}x{h} at {x0}");
        }
    }

    #[test]
    fn invalid_config_is_rejected() {
        let bad = RenderConfig {
            trail_width_px: 0.0,
            ..RenderConfig::default()
        };
        assert!(Renderer::new(bad).is_err());
    }
}
