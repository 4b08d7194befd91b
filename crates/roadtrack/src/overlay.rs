//! Drawing boxes over frames for visual checks.

use crate::geometry::BBox;
use image::{Rgb, RgbImage};
use imageproc::drawing::draw_hollow_rect_mut;
use imageproc::rect::Rect;

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
}
