//! Solids built of blocks (a walker's body, a vehicle) seen through a pinhole camera: the
//! image box of their corners, and the headings that turn them, for the box models of
//! [`super::walker_box`] and [`super::vehicle_box`].

use crate::camera::Pinhole;
use crate::geometry::{BBox, Point};

/// One block of a solid, in its own frame (`x` forward, `y` left, `z` up): the bottom
/// rectangle `[x0, x1] × [−y, y]` at `z0`, the top one at `z1`.
pub(crate) struct Block {
    pub bottom: [f64; 3],
    pub top: [f64; 3],
    pub z: [f64; 2],
}

impl Block {
    pub(crate) fn new(bottom: [f64; 3], top: [f64; 3], z: [f64; 2]) -> Self {
        Self { bottom, top, z }
    }
}

/// The image box of the solid `blocks` whose origin stands at ground point `(x, y)`, facing
/// `heading` (rad, counter-clockwise from ground `+x`): the box of its corners' images, or
/// `None` when a corner is behind the camera.
pub(crate) fn image_box(
    camera: &Pinhole,
    blocks: &[Block],
    (x, y): (f64, f64),
    heading: f64,
) -> Option<BBox> {
    let (s, c) = heading.sin_cos();
    let (mut lo, mut hi) = (
        Point::new(f64::INFINITY, f64::INFINITY),
        Point::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for b in blocks {
        for ([x0, x1, hw], z) in [(b.bottom, b.z[0]), (b.top, b.z[1])] {
            for u in [x0, x1] {
                for v in [-hw, hw] {
                    let p = camera.project(x + u * c - v * s, y + u * s + v * c, z)?;
                    lo = Point::new(lo.x.min(p.x), lo.y.min(p.y));
                    hi = Point::new(hi.x.max(p.x), hi.y.max(p.y));
                }
            }
        }
    }
    Some(BBox {
        left: lo.x,
        top: lo.y,
        width: hi.x - lo.x,
        height: hi.y - lo.y,
    })
}

/// Each point's heading, or where it has none (standing, too slow to tell) the last one
/// before it, else the first one after; `None` when no point has one.
pub(crate) fn hold_headings(headings: &[Option<f64>]) -> Option<Vec<f64>> {
    let mut last = *headings.iter().flatten().next()?;
    Some(
        headings
            .iter()
            .map(|h| {
                if let Some(h) = h {
                    last = *h;
                }
                last
            })
            .collect(),
    )
}

/// The ground homography of a camera `height_m` up at `(0, −back_m)`, looking along `+y`
/// `tilt_rad` down, f = 512 px, its principal point at the centre of 640 × 480 px.
#[cfg(test)]
pub(crate) fn looking_along_y(height_m: f64, back_m: f64, tilt_rad: f64) -> crate::Calibration {
    let (s, c) = tilt_rad.sin_cos();
    let (f, cu, cv) = (512.0, 320.0, 240.0);
    let rows = [[1.0, 0.0, 0.0], [0.0, -s, -c], [0.0, c, -s]];
    let centre = [0.0, -back_m, height_m];
    let t: Vec<f64> = rows
        .iter()
        .map(|r| -(r[0] * centre[0] + r[1] * centre[1] + r[2] * centre[2]))
        .collect();
    let k = [[f, 0.0, cu], [0.0, f, cv], [0.0, 0.0, 1.0]];
    let mut h = [[0.0; 3]; 3];
    for i in 0..3 {
        for (j, col) in [0, 1, 3].into_iter().enumerate() {
            h[i][j] = (0..3)
                .map(|l| k[i][l] * if col < 3 { rows[l][col] } else { t[l] })
                .sum();
        }
    }
    crate::Calibration::from_homography(h).expect("a valid homography")
}
