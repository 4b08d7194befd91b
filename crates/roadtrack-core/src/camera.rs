//! A pinhole camera recovered from a ground-plane calibration, to project points above the
//! ground (a walker's head, a car's roof) that the homography alone cannot place.
//!
//! A calibration maps the plane `z = 0`; a camera maps every point:
//!
//! ```text
//! [u·w, v·w, w]ᵀ = K · [r₁ r₂ r₃ t] · [x, y, z, 1]ᵀ,   K = [[f, 0, c_u], [0, f, c_v], [0, 0, 1]]
//! ```
//!
//! and its ground-plane part is the homography: `H ∝ K · [r₁ r₂ t]`. With square pixels, no
//! skew and the principal point `(c_u, c_v)` at the image centre, the focal length `f`
//! follows from one homography (Zhang, *A flexible new technique for camera calibration*,
//! 2000, §2.3): the first two columns of `K⁻¹ H` are orthogonal and of equal length. Each of
//! the two conditions gives `f²`; the rotation's third column is `r₃ = r₁ × r₂`.
//!
//! Choice: the principal point is taken at the image centre, where every camera `roadtrack
//! simulate` renders has it and most real cameras have it within a few per cent; a nadir
//! (orthographic) calibration has no perspective to recover `f` from and is refused.

use crate::calibration::Calibration;
use crate::error::{Error, Result};
use crate::geometry::Point;

/// A pinhole camera (see the module documentation): ground frame in metres, `z` up.
#[derive(Debug, Clone, PartialEq)]
pub struct Pinhole {
    /// `K · [r₁ r₂ r₃ t]`, row-major.
    p: [[f64; 4]; 3],
    focal_px: f64,
}

impl Pinhole {
    /// The camera whose view of the ground is `calibration`, for images of `width ×
    /// height` px, its principal point at their centre.
    ///
    /// # Errors
    /// [`Error::Invalid`] when the calibration has no perspective (a nadir or affine view:
    /// the ground's horizon is at infinity) or gives no real focal length (not a view a
    /// pinhole with its principal point at the image centre can have).
    pub fn from_calibration(calibration: &Calibration, width: u32, height: u32) -> Result<Self> {
        let h = calibration.image_from_ground_matrix();
        let (cu, cv) = (f64::from(width) / 2.0, f64::from(height) / 2.0);
        // Column j of H with the principal point taken out: K⁻¹ h = (a_u / f, a_v / f, h_w).
        let col = |j: usize| [h[0][j] - cu * h[2][j], h[1][j] - cv * h[2][j], h[2][j]];
        let (c1, c2) = (col(0), col(1));
        let dot2 = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1];
        // Denominators this small against the bottom row are an affine view's zeros.
        let hw = h[2].iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let tiny = 1e-12 * hw * hw;
        let mut estimates = Vec::with_capacity(2);
        // r₁ · r₂ = 0.
        let d = c1[2] * c2[2];
        if d.abs() > tiny {
            estimates.push(-dot2(&c1, &c2) / d);
        }
        // |r₁| = |r₂|.
        let d = c2[2] * c2[2] - c1[2] * c1[2];
        if d.abs() > tiny {
            estimates.push((dot2(&c1, &c1) - dot2(&c2, &c2)) / d);
        }
        let positive: Vec<f64> = estimates
            .into_iter()
            .filter(|f2| f2.is_finite() && *f2 > 0.0)
            .collect();
        if positive.is_empty() {
            return Err(Error::Invalid(
                "the calibration has no perspective a pinhole camera with its principal point at \
                 the image centre could give (a nadir or affine view has none): a camera cannot be \
                 recovered from it"
                    .into(),
            ));
        }
        let f = (positive.iter().sum::<f64>() / positive.len() as f64).sqrt();
        let m = |c: [f64; 3]| [c[0] / f, c[1] / f, c[2]];
        let (m1, m2, m3) = (m(c1), m(c2), m(col(2)));
        let norm = |v: &[f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        // H's sign makes w > 0 in front of the camera (calibration.rs), so λ > 0.
        let lambda = 2.0 / (norm(&m1) + norm(&m2));
        let r1 = m1.map(|v| v * lambda);
        let r2 = m2.map(|v| v * lambda);
        let t = m3.map(|v| v * lambda);
        let r3 = [
            r1[1] * r2[2] - r1[2] * r2[1],
            r1[2] * r2[0] - r1[0] * r2[2],
            r1[0] * r2[1] - r1[1] * r2[0],
        ];
        let k = [[f, 0.0, cu], [0.0, f, cv], [0.0, 0.0, 1.0]];
        let rt = [
            [r1[0], r2[0], r3[0], t[0]],
            [r1[1], r2[1], r3[1], t[1]],
            [r1[2], r2[2], r3[2], t[2]],
        ];
        let mut p = [[0.0; 4]; 3];
        for (i, row) in p.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (0..3).map(|l| k[i][l] * rt[l][j]).sum();
            }
        }
        Ok(Self { p, focal_px: f })
    }

    /// The focal length, px.
    pub fn focal_px(&self) -> f64 {
        self.focal_px
    }

    /// The image point of `(x, y, z)` (m, `z` up), or `None` behind the camera.
    pub fn project(&self, x: f64, y: f64, z: f64) -> Option<Point> {
        let r = |i: usize| self.p[i][0] * x + self.p[i][1] * y + self.p[i][2] * z + self.p[i][3];
        let w = r(2);
        if w <= 0.0 {
            return None;
        }
        Some(Point::new(r(0) / w, r(1) / w))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `K [R | t]` of a camera `height` m above the ground at `(0, −back)`, looking along
    /// `+y` and down by `tilt` rad, focal `f`, principal point at the image centre.
    fn camera(f: f64, tilt: f64, height: f64, back: f64) -> [[f64; 4]; 3] {
        let (s, c) = tilt.sin_cos();
        // Camera axes in the ground frame: right = +x, down and forward from the tilt.
        let right = [1.0, 0.0, 0.0];
        let forward = [0.0, c, -s];
        let down = [0.0, -s, -c];
        let centre = [0.0, -back, height];
        let r = [right, down, forward];
        let t: Vec<f64> = r
            .iter()
            .map(|a| -(a[0] * centre[0] + a[1] * centre[1] + a[2] * centre[2]))
            .collect();
        let k = [[f, 0.0, 320.0], [0.0, f, 240.0], [0.0, 0.0, 1.0]];
        let mut p = [[0.0; 4]; 3];
        for i in 0..3 {
            for j in 0..4 {
                p[i][j] = (0..3)
                    .map(|l| k[i][l] * if j < 3 { r[l][j] } else { t[l] })
                    .sum();
            }
        }
        p
    }

    fn project(p: &[[f64; 4]; 3], x: f64, y: f64, z: f64) -> (f64, f64) {
        let r = |i: usize| p[i][0] * x + p[i][1] * y + p[i][2] * z + p[i][3];
        (r(0) / r(2), r(1) / r(2))
    }

    #[test]
    fn a_camera_is_recovered_from_its_ground_homography() -> Result<()> {
        for (f, tilt, height, back, k) in [
            (512.0_f64, 0.5, 12.0, 30.0, 1.0_f64),
            (800.0, 0.9, 40.0, 10.0, -3.5),
            (350.0, 0.25, 6.0, 5.0, 1e-3),
        ] {
            let p = camera(f, tilt, height, back);
            // The homography of the plane z = 0 (columns 1, 2 and 4), at an arbitrary
            // positive scale: the camera must not depend on it.
            let s = k.abs();
            let h = [
                [p[0][0] * s, p[0][1] * s, p[0][3] * s],
                [p[1][0] * s, p[1][1] * s, p[1][3] * s],
                [p[2][0] * s, p[2][1] * s, p[2][3] * s],
            ];
            let cam = Pinhole::from_calibration(&Calibration::from_homography(h)?, 640, 480)?;
            assert!(
                (cam.focal_px() - f).abs() < 1e-6 * f,
                "{} {f}",
                cam.focal_px()
            );
            for (x, y, z) in [(0.0, 20.0, 0.0), (3.0, 25.0, 1.7), (-4.0, 12.0, 3.5)] {
                let want = project(&p, x, y, z);
                let got = cam.project(x, y, z).expect("in front");
                assert!(
                    (got.x - want.0).abs() < 1e-6 && (got.y - want.1).abs() < 1e-6,
                    "{got:?} {want:?}"
                );
            }
            // Behind the camera: 10 m back along its axis.
            let (st, ct) = tilt.sin_cos();
            assert!(
                cam.project(0.0, -back - 10.0 * ct, height + 10.0 * st)
                    .is_none()
            );
        }
        Ok(())
    }

    #[test]
    fn a_view_without_perspective_is_refused() -> Result<()> {
        let nadir =
            Calibration::from_homography([[3.0, 0.0, 100.0], [0.0, -3.0, 200.0], [0.0, 0.0, 1.0]])?;
        let err = Pinhole::from_calibration(&nadir, 640, 480).unwrap_err();
        assert!(err.to_string().contains("no perspective"), "{err}");
        Ok(())
    }
}
