//! Appearance of a detector box (ours, issue 14; docs/MRF.md "Detections"): the mean colour
//! of its upper and lower halves, compared between an object and a box when boxes are
//! matched to objects. Pedestrians walking side by side share their box motion and, when
//! narrower than a block, their blocks; what still tells them apart is what they wear.

use crate::geometry::BBox;
use image::RgbImage;

/// Mean RGB of the upper and the lower half of a box, grey levels (0–255 per channel).
pub type Appearance = [f64; 6];

/// The mean colour of the upper and lower halves of the middle `inner` fraction of the
/// box's width, clipped to the image; `None` when a half holds no pixel.
// Choice: the middle half of the width (`inner` 0.5) and two halves of the height: a
// pedestrian's top and trousers (a vehicle's roof and body); the box's sides hold more
// background and neighbours than the object.
pub fn describe(image: &RgbImage, b: &BBox, inner: f64) -> Option<Appearance> {
    let (w, h) = (f64::from(image.width()), f64::from(image.height()));
    let c = b.centre();
    let half_w = (b.width * inner / 2.0).max(0.5);
    let x0 = (c.x - half_w).floor().clamp(0.0, w) as u32;
    let x1 = (c.x + half_w).ceil().clamp(0.0, w) as u32;
    let y0 = b.top.floor().clamp(0.0, h) as u32;
    let y1 = b.bottom().ceil().clamp(0.0, h) as u32;
    let ym = ((b.top + b.bottom()) / 2.0)
        .round()
        .clamp(f64::from(y0), f64::from(y1)) as u32;
    let mut out = [0.0; 6];
    for (k, (ya, yb)) in [(y0, ym), (ym, y1)].into_iter().enumerate() {
        let mut sum = [0u64; 3];
        let mut n = 0u64;
        for y in ya..yb {
            for x in x0..x1 {
                let p = image.get_pixel(x, y).0;
                for ch in 0..3 {
                    sum[ch] += u64::from(p[ch]);
                }
                n += 1;
            }
        }
        if n == 0 {
            return None;
        }
        for ch in 0..3 {
            out[3 * k + ch] = sum[ch] as f64 / n as f64;
        }
    }
    Some(out)
}

/// `max(0, 1 − d / scale)`, `d` the mean absolute difference of the six channels.
pub fn similarity(a: &Appearance, b: &Appearance, scale: f64) -> f64 {
    if scale <= 0.0 {
        return 0.0;
    }
    let d = a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f64>() / 6.0;
    (1.0 - d / scale).max(0.0)
}

/// `(1 − a) · old + a · new`, channel by channel.
pub fn blend(old: &Appearance, new: &Appearance, a: f64) -> Appearance {
    let mut out = *old;
    for (o, n) in out.iter_mut().zip(new) {
        *o = (1.0 - a) * *o + a * n;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    #[test]
    fn halves_are_described_by_their_mean_colour() {
        let mut img = RgbImage::from_pixel(40, 40, Rgb([0, 0, 0]));
        for y in 10..20 {
            for x in 10..20 {
                img.put_pixel(x, y, Rgb([200, 100, 0]));
            }
        }
        for y in 20..30 {
            for x in 10..20 {
                img.put_pixel(x, y, Rgb([0, 0, 50]));
            }
        }
        let a = describe(&img, &BBox::new(10.0, 10.0, 10.0, 20.0), 0.5).unwrap();
        assert_eq!(a, [200.0, 100.0, 0.0, 0.0, 0.0, 50.0]);
        assert_eq!(similarity(&a, &a, 40.0), 1.0);
        let b = [200.0, 100.0, 0.0, 0.0, 0.0, 50.0 + 6.0 * 20.0];
        assert!((similarity(&a, &b, 40.0) - 0.5).abs() < 1e-12);
        assert!(describe(&img, &BBox::new(50.0, 50.0, 10.0, 10.0), 0.5).is_none());
    }
}
