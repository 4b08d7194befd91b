//! Drawing primitives for overlays: id and class colours, boxes, text labels, alpha-blended
//! trails. [`crate::render`] composes them into annotated frames.
//!
//! Text uses DejaVu Sans, compiled into the library (`assets/fonts/DejaVuSans.ttf`, licence
//! in `assets/fonts/LICENSE-DejaVu.txt`), so drawing never depends on system fonts.

use ab_glyph::{FontRef, PxScale};
use image::{Rgb, RgbImage};
use imageproc::drawing::{draw_hollow_rect_mut, draw_text_mut, text_size};
use imageproc::rect::Rect;
use roadtrack_core::class::ObjectClass;
use roadtrack_core::error::{Error, Result};
use roadtrack_core::geometry::{BBox, Point};

/// The bytes of DejaVu Sans (Bitstream Vera licence, see `assets/fonts/LICENSE-DejaVu.txt`).
pub const FONT_BYTES: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

/// The compiled-in font, parsed (cheap: only the table directory is read).
///
/// # Errors
/// Never with the committed font; an error would mean the font file was replaced by
/// something that is not a TrueType font.
pub fn font() -> Result<FontRef<'static>> {
    FontRef::try_from_slice(FONT_BYTES)
        .map_err(|e| Error::Invalid(format!("the compiled-in font does not parse: {e}")))
}

/// A distinct, stable colour for an id (golden-ratio hue walk; ids never map to grey).
pub fn id_colour(id: u64) -> Rgb<u8> {
    let h = (id as f64 * 0.618_033_988_749_895).fract() * 6.0;
    let i = h.floor();
    let f = h - i;
    let (v, s) = (1.0, 0.85);
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    let (r, g, b) = match i as u8 {
        0 => (v, t, p),
        1 => (q, v, p),
        2 => (p, v, t),
        3 => (p, q, v),
        4 => (t, p, v),
        _ => (v, p, q),
    };
    Rgb([(r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8])
}

/// Draws `bbox` as a 2-px outline in `colour`, clipped to the image.
pub fn draw_box(image: &mut RgbImage, bbox: &BBox, colour: Rgb<u8>) {
    let (w, h) = image.dimensions();
    let x0 = bbox.left.floor().max(0.0);
    let y0 = bbox.top.floor().max(0.0);
    let x1 = bbox.right().ceil().min(f64::from(w));
    let y1 = bbox.bottom().ceil().min(f64::from(h));
    if x1 - x0 < 1.0 || y1 - y0 < 1.0 {
        return;
    }
    for inset in 0..2u32 {
        let (rw, rh) = ((x1 - x0) as u32, (y1 - y0) as u32);
        if rw <= 2 * inset || rh <= 2 * inset {
            break;
        }
        let r = Rect::at(x0 as i32 + inset as i32, y0 as i32 + inset as i32)
            .of_size(rw - 2 * inset, rh - 2 * inset);
        draw_hollow_rect_mut(image, r, colour);
    }
}

/// A fixed colour per class, so a scene reads the same in every picture: cars blue, trucks
/// orange, buses yellow, motorcycles magenta, bicycles green, pedestrians red, unknown
/// light grey; any other word gets a stable colour from its name.
pub fn class_colour(class: &ObjectClass) -> Rgb<u8> {
    match class {
        ObjectClass::Car => Rgb([40, 120, 255]),
        ObjectClass::Truck => Rgb([255, 140, 0]),
        ObjectClass::Bus => Rgb([255, 215, 0]),
        ObjectClass::Motorcycle => Rgb([230, 40, 230]),
        ObjectClass::Bicycle => Rgb([40, 200, 60]),
        ObjectClass::Pedestrian => Rgb([240, 40, 40]),
        ObjectClass::Unknown => Rgb([200, 200, 200]),
        ObjectClass::Other(name) => {
            // FNV-1a of the name: stable across runs and platforms.
            let h = name.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
                (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
            });
            id_colour(h % 1000 + 1)
        }
    }
}

/// Black or white, whichever reads better on `background` (Rec. 601 luma threshold).
pub fn text_colour_on(background: Rgb<u8>) -> Rgb<u8> {
    let [r, g, b] = background.0;
    let luma = 0.299 * f64::from(r) + 0.587 * f64::from(g) + 0.114 * f64::from(b);
    if luma > 140.0 {
        Rgb([0, 0, 0])
    } else {
        Rgb([255, 255, 255])
    }
}

/// Blends `colour` over the pixel at `(x, y)` with opacity `alpha` in `[0, 1]`; pixels
/// outside the image are ignored.
pub fn blend_pixel(image: &mut RgbImage, x: i64, y: i64, colour: Rgb<u8>, alpha: f32) {
    let (w, h) = image.dimensions();
    if x < 0 || y < 0 || x >= i64::from(w) || y >= i64::from(h) {
        return;
    }
    let a = alpha.clamp(0.0, 1.0);
    let p = image.get_pixel_mut(x as u32, y as u32);
    for (c, n) in p.0.iter_mut().zip(colour.0) {
        *c = (f32::from(*c) * (1.0 - a) + f32::from(n) * a).round() as u8;
    }
}

/// Size in px of `text` drawn `height_px` tall.
pub fn label_size(font: &FontRef<'_>, height_px: f32, text: &str) -> (u32, u32) {
    text_size(PxScale::from(height_px), font, text)
}

/// Draws `text` on a filled `background` rectangle whose top-left corner is `at`, clipped
/// to the image, with [`LABEL_PADDING`] around the text ([`label_tile`]); returns the
/// rectangle's size.
pub fn draw_label(
    image: &mut RgbImage,
    font: &FontRef<'_>,
    height_px: f32,
    at: (i32, i32),
    text: &str,
    background: Rgb<u8>,
) -> (u32, u32) {
    let tile = label_tile(font, height_px, text, background);
    paste_tile(image, &tile, at);
    tile.dimensions()
}

/// Space around a label's text in its rectangle, px: left and right, top and bottom.
pub const LABEL_PADDING: (u32, u32) = (2, 1);

/// The label [`draw_label`] draws, on its own: the filled rectangle with the text in it, to
/// be copied into frames with [`paste_tile`]. Laying the glyphs out and rasterising them
/// is most of a label's cost, and a track's label repeats frame after frame.
pub fn label_tile(font: &FontRef<'_>, height_px: f32, text: &str, background: Rgb<u8>) -> RgbImage {
    let (tw, th) = label_size(font, height_px, text);
    let (px, py) = LABEL_PADDING;
    let mut tile = RgbImage::from_pixel(tw + 2 * px, th + 2 * py, background);
    draw_text_mut(
        &mut tile,
        text_colour_on(background),
        px as i32,
        py as i32,
        PxScale::from(height_px),
        font,
        text,
    );
    tile
}

/// Copies `tile` into `image` with its top-left corner at `(x, y)`, clipped to the image.
pub fn paste_tile(image: &mut RgbImage, tile: &RgbImage, (x, y): (i32, i32)) {
    let (iw, ih) = (i64::from(image.width()), i64::from(image.height()));
    let (tw, th) = (i64::from(tile.width()), i64::from(tile.height()));
    let (x, y) = (i64::from(x), i64::from(y));
    let (x0, x1) = (x.max(0), (x + tw).min(iw));
    if x0 >= x1 {
        return;
    }
    let span = 3 * (x1 - x0) as usize;
    for row in y.max(0)..(y + th).min(ih) {
        let from = 3 * (((row - y) * tw + (x0 - x)) as usize);
        let to = 3 * ((row * iw + x0) as usize);
        let (src, dst): (&[u8], &mut [u8]) = (tile.as_raw(), image.as_mut());
        dst[to..to + span].copy_from_slice(&src[from..from + span]);
    }
}

/// Draws a polyline through `points` whose opacity varies per segment: segment `i` (from
/// `points[i]` to `points[i + 1]`) gets `alphas[i]`. Lines are `width_px` wide. Each pixel
/// is blended once with the largest opacity of any segment covering it, so overlapping
/// segments do not darken joints.
///
/// # Panics
/// Never; extra alphas are ignored and missing ones count as 0.
pub fn draw_faded_polyline(
    image: &mut RgbImage,
    points: &[Point],
    alphas: &[f32],
    colour: Rgb<u8>,
    width_px: f32,
) {
    if points.len() < 2 {
        return;
    }
    let r = f64::from(width_px.max(0.5)) / 2.0;
    let (iw, ih) = image.dimensions();
    let lo_x = points.iter().map(|p| p.x).fold(f64::INFINITY, f64::min) - r - 1.0;
    let lo_y = points.iter().map(|p| p.y).fold(f64::INFINITY, f64::min) - r - 1.0;
    let hi_x = points.iter().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max) + r + 1.0;
    let hi_y = points.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max) + r + 1.0;
    if !(lo_x.is_finite() && lo_y.is_finite() && hi_x.is_finite() && hi_y.is_finite()) {
        return;
    }
    // Coverage mask over the polyline's bounding box, clipped to the image.
    let x0 = lo_x.floor().max(0.0) as i64;
    let y0 = lo_y.floor().max(0.0) as i64;
    let x1 = (hi_x.ceil() as i64).min(i64::from(iw));
    let y1 = (hi_y.ceil() as i64).min(i64::from(ih));
    if x1 <= x0 || y1 <= y0 {
        return;
    }
    let mw = (x1 - x0) as usize;
    let mut mask = vec![0f32; mw * (y1 - y0) as usize];
    for (i, seg) in points.windows(2).enumerate() {
        let a = alphas.get(i).copied().unwrap_or(0.0).clamp(0.0, 1.0);
        if a <= 0.0 {
            continue;
        }
        let (p, q) = (seg[0], seg[1]);
        let sx0 = ((p.x.min(q.x) - r).floor() as i64).max(x0);
        let sx1 = ((p.x.max(q.x) + r).ceil() as i64).min(x1 - 1);
        let sy0 = ((p.y.min(q.y) - r).floor() as i64).max(y0);
        let sy1 = ((p.y.max(q.y) + r).ceil() as i64).min(y1 - 1);
        for py in sy0..=sy1 {
            for px in sx0..=sx1 {
                // Distance from the pixel centre to the segment.
                let c = Point::new(px as f64 + 0.5, py as f64 + 0.5);
                if distance_to_segment(c, p, q) <= r {
                    let k = (py - y0) as usize * mw + (px - x0) as usize;
                    mask[k] = mask[k].max(a);
                }
            }
        }
    }
    for (k, &a) in mask.iter().enumerate() {
        if a > 0.0 {
            let (px, py) = (x0 + (k % mw) as i64, y0 + (k / mw) as i64);
            blend_pixel(image, px, py, colour, a);
        }
    }
}

/// Distance from `c` to the segment `p`–`q`.
fn distance_to_segment(c: Point, p: Point, q: Point) -> f64 {
    let (dx, dy) = (q.x - p.x, q.y - p.y);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((c.x - p.x) * dx + (c.y - p.y) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    c.distance(Point::new(p.x + t * dx, p.y + t * dy))
}

/// Draws a filled disc of radius `radius_px` centred on `centre`.
pub fn draw_dot(image: &mut RgbImage, centre: Point, radius_px: f64, colour: Rgb<u8>) {
    let r = radius_px.max(0.5);
    let (x0, x1) = ((centre.x - r).floor() as i64, (centre.x + r).ceil() as i64);
    let (y0, y1) = ((centre.y - r).floor() as i64, (centre.y + r).ceil() as i64);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let c = Point::new(x as f64 + 0.5, y as f64 + 0.5);
            if c.distance(centre) <= r {
                blend_pixel(image, x, y, colour, 1.0);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_outline_is_drawn_and_clipped() {
        let mut img = RgbImage::new(10, 10);
        let c = Rgb([255, 0, 0]);
        draw_box(&mut img, &BBox::new(2.0, 2.0, 6.0, 6.0), c);
        assert_eq!(img.get_pixel(3, 5), &c);
        assert_eq!(img.get_pixel(2, 2), &c);
        assert_eq!(img.get_pixel(4, 4), &Rgb([0, 0, 0]));
        draw_box(&mut img, &BBox::new(-5.0, 8.0, 30.0, 30.0), c);
        assert_eq!(img.get_pixel(0, 8), &c);
    }

    #[test]
    fn neighbouring_ids_get_different_colours() {
        assert_ne!(id_colour(1), id_colour(2));
        assert_eq!(id_colour(7), id_colour(7));
    }

    #[test]
    fn the_compiled_in_font_parses_and_draws_text() -> Result<()> {
        let f = font()?;
        let mut img = RgbImage::new(60, 20);
        let (w, h) = draw_label(&mut img, &f, 12.0, (1, 1), "42", Rgb([255, 255, 255]));
        assert!(w > 10 && h >= 12, "{w}×{h}");
        // Black text on white: some pixels inside the label are dark.
        let dark = (1..1 + w)
            .flat_map(|x| (1..1 + h).map(move |y| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0[0] < 100)
            .count();
        assert!(dark > 5, "{dark} dark pixels");
        Ok(())
    }

    /// A label drawn in place on the frame: the filled rectangle, then the text over it.
    fn label_in_place(
        image: &mut RgbImage,
        font: &FontRef<'_>,
        height_px: f32,
        (x, y): (i32, i32),
        text: &str,
        background: Rgb<u8>,
    ) -> (u32, u32) {
        let (tw, th) = label_size(font, height_px, text);
        let (w, h) = (tw + 4, th + 2);
        imageproc::drawing::draw_filled_rect_mut(image, Rect::at(x, y).of_size(w, h), background);
        draw_text_mut(
            image,
            text_colour_on(background),
            x + 2,
            y + 1,
            PxScale::from(height_px),
            font,
            text,
        );
        (w, h)
    }

    /// A label drawn once as a tile and pasted is the label drawn in place, pixel for
    /// pixel, over any frame, wherever it lands (clipped at every edge).
    #[test]
    fn a_pasted_label_tile_is_the_label_drawn_in_place() -> Result<()> {
        use rand::RngExt;
        let f = font()?;
        let mut rng = roadtrack_core::rng::rng_for(5, roadtrack_core::rng::Stream::Synthetic, 0);
        for (k, text) in [
            "7",
            "42 car",
            "1234 pedestrian",
            "9 lorry/bus",
            "gjpqy",
            "ÄÖ",
        ]
        .iter()
        .enumerate()
        {
            for height in [9.0, 12.5, 18.0, 22.0] {
                let background = Rgb([rng.random(), rng.random(), 40]);
                let tile = label_tile(&f, height, text, background);
                for at in [(3, 4), (-7, -3), (50, 30), (-200, 5), (5, -100), (60, 38)] {
                    let frame = RgbImage::from_fn(64, 40, |x, y| {
                        Rgb([(x * 4) as u8, (y * 6 + k as u32) as u8, rng.random()])
                    });
                    let mut drawn = frame.clone();
                    let size = label_in_place(&mut drawn, &f, height, at, text, background);
                    assert_eq!(size, tile.dimensions());
                    let mut pasted = frame;
                    paste_tile(&mut pasted, &tile, at);
                    assert!(pasted == drawn, "{text:?} at {at:?}, {height} px");
                }
            }
        }
        Ok(())
    }

    #[test]
    fn text_colour_contrasts_with_the_background() {
        assert_eq!(text_colour_on(Rgb([255, 255, 0])), Rgb([0, 0, 0]));
        assert_eq!(text_colour_on(Rgb([0, 0, 128])), Rgb([255, 255, 255]));
    }

    #[test]
    fn blending_mixes_colours_by_alpha_and_ignores_outside_pixels() {
        let mut img = RgbImage::from_pixel(2, 1, Rgb([0, 0, 200]));
        blend_pixel(&mut img, 0, 0, Rgb([200, 0, 0]), 0.25);
        assert_eq!(img.get_pixel(0, 0), &Rgb([50, 0, 150]));
        blend_pixel(&mut img, -1, 0, Rgb([200, 0, 0]), 1.0);
        blend_pixel(&mut img, 2, 0, Rgb([200, 0, 0]), 1.0);
        assert_eq!(img.get_pixel(1, 0), &Rgb([0, 0, 200]));
    }

    #[test]
    fn faded_polyline_covers_its_segments_with_their_own_opacity() {
        let mut img = RgbImage::new(40, 10);
        let pts = [
            Point::new(2.0, 5.0),
            Point::new(20.0, 5.0),
            Point::new(38.0, 5.0),
        ];
        draw_faded_polyline(&mut img, &pts, &[0.5, 1.0], Rgb([200, 200, 200]), 2.0);
        // Pixel (10, 4) has centre (10.5, 4.5): on the first segment, half opacity.
        assert_eq!(img.get_pixel(10, 4), &Rgb([100, 100, 100]));
        assert_eq!(img.get_pixel(30, 4), &Rgb([200, 200, 200]));
        // Off the line.
        assert_eq!(img.get_pixel(10, 8), &Rgb([0, 0, 0]));
        // The joint is blended once, with the larger opacity.
        assert_eq!(img.get_pixel(20, 4), &Rgb([200, 200, 200]));
    }

    #[test]
    fn class_colours_are_fixed_and_other_words_stable() {
        assert_eq!(class_colour(&ObjectClass::Car), Rgb([40, 120, 255]));
        let tram = ObjectClass::Other("tram".into());
        assert_eq!(class_colour(&tram), class_colour(&tram.clone()));
        assert_ne!(
            class_colour(&ObjectClass::Car),
            class_colour(&ObjectClass::Pedestrian)
        );
    }
}
