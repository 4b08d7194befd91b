//! Image ↔ ground calibration: the mapping between pixels and metres on the road plane.
//!
//! The ground is the plane `z = 0`, in metres, with `x` and `y` forming a right-handed
//! frame seen from above (headings are counter-clockwise from `+x`). A calibration is a
//! plane-to-plane homography `image_from_ground` (3 × 3, homogeneous):
//!
//! ```text
//! [u·w, v·w, w]ᵀ = H · [x_m, y_m, 1]ᵀ      (u, v) in px, w > 0 in front of the camera
//! ```
//!
//! Two ways to give one, in TOML (`calibration.toml`, written by `roadtrack simulate`):
//!
//! ```toml
//! # 1. Nadir (straight-down) view at a fixed scale, e.g. seed 000's 0.33 m/px:
//! metres_per_pixel = 0.33
//! origin_m = [0.0, 40.0]   # ground point of the image's top-left corner (pixel (0, 0))
//! rotation_deg = 0.0       # ground direction of the image's +x axis, ccw from ground +x
//! ```
//!
//! ```toml
//! # 2. Any camera looking at the road plane: the homography, row-major.
//! image_from_ground = [[h11, h12, h13], [h21, h22, h23], [h31, h32, h33]]
//! ```
//!
//! ```toml
//! # 3. Four or more surveyed points: image px ↔ ground m; H is estimated by least squares.
//! [[points]]
//! image = [102.5, 388.0]
//! ground = [0.0, 0.0]
//! # … at least four, no three of them on one line
//! ```
//!
//! In the nadir form the image's `+y` axis (down) points to the ground direction
//! `rotation_deg − 90°`, so with `rotation_deg = 0` image right is ground `+x` and image
//! down is ground `−y` (north up). The 3 × 3 algebra (product, inverse) is written out here;
//! the point-pair form uses the normalised direct linear transform (Hartley & Zisserman,
//! alg. 4.2) solved by SVD (nalgebra) and reports the reprojection error ([`FitReport`]).

use crate::config::exact;
use crate::error::{Error, Result};
use crate::geometry::Point;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A 3 × 3 matrix, row-major.
pub type Mat3 = [[f64; 3]; 3];

/// The mapping between image pixels and ground metres (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    image_from_ground: Mat3,
    ground_from_image: Mat3,
    nadir: Option<NadirScale>,
    fit: Option<FitReport>,
}

/// One surveyed correspondence: a pixel and the ground point it shows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointPair {
    /// Image position `[u, v]`, px.
    #[serde(deserialize_with = "exact::array")]
    pub image: [f64; 2],
    /// Ground position `[x, y]`, m.
    #[serde(deserialize_with = "exact::array")]
    pub ground: [f64; 2],
}

/// How well an estimated homography reproduces its point pairs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitReport {
    /// Number of point pairs.
    pub points: usize,
    /// Root-mean-square reprojection error in the image, px.
    pub rms_px: f64,
    /// Largest reprojection error, px.
    pub max_px: f64,
    /// Reprojection error of each pair, px, in input order.
    pub errors_px: Vec<f64>,
}

/// The parameters of a nadir calibration at a fixed scale.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NadirScale {
    /// Ground sample distance, m/px (seed 000: 0.33).
    pub metres_per_pixel: f64,
    /// Ground point `[x_m, y_m]` of the image's top-left corner, pixel `(0, 0)`.
    pub origin_m: [f64; 2],
    /// Ground direction of the image's `+x` axis, degrees counter-clockwise from ground `+x`.
    pub rotation_deg: f64,
}

/// The TOML layout of a calibration file: exactly one of the two forms.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CalibrationFile {
    #[serde(skip_serializing_if = "Option::is_none")]
    metres_per_pixel: Option<f64>,
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "exact::option_array"
    )]
    origin_m: Option<[f64; 2]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    rotation_deg: Option<f64>,
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "exact::option_matrix"
    )]
    image_from_ground: Option<Mat3>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    points: Vec<PointPair>,
}

/// `a · b`.
pub fn mat3_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}

/// The inverse of `m` by the adjugate, or `None` when `m` is singular (relative determinant
/// below 1e-12).
pub fn mat3_inverse(m: &Mat3) -> Option<Mat3> {
    let c =
        |r0: usize, r1: usize, c0: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    // Cofactors, transposed (adjugate).
    let adj = [
        [c(1, 2, 1, 2), -c(0, 2, 1, 2), c(0, 1, 1, 2)],
        [-c(1, 2, 0, 2), c(0, 2, 0, 2), -c(0, 1, 0, 2)],
        [c(1, 2, 0, 1), -c(0, 2, 0, 1), c(0, 1, 0, 1)],
    ];
    let det = m[0][0] * adj[0][0] + m[0][1] * adj[1][0] + m[0][2] * adj[2][0];
    let scale = m.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
    if !det.is_finite() || scale == 0.0 || det.abs() <= 1e-12 * scale.powi(3) {
        return None;
    }
    let mut out = adj;
    for row in out.iter_mut() {
        for v in row.iter_mut() {
            *v /= det;
        }
    }
    Some(out)
}

/// `m · [x, y, 1]ᵀ`.
fn apply(m: &Mat3, x: f64, y: f64) -> [f64; 3] {
    [
        m[0][0] * x + m[0][1] * y + m[0][2],
        m[1][0] * x + m[1][1] * y + m[1][2],
        m[2][0] * x + m[2][1] * y + m[2][2],
    ]
}

impl Calibration {
    /// A nadir view at `metres_per_pixel`, with pixel `(0, 0)` at ground `origin_m` and the
    /// image's `+x` axis along ground direction `rotation_deg`.
    ///
    /// # Errors
    /// A scale that is not finite and positive, or a non-finite origin or angle (each
    /// named by its field).
    pub fn from_nadir(
        metres_per_pixel: f64,
        origin_m: [f64; 2],
        rotation_deg: f64,
    ) -> Result<Self> {
        if !(metres_per_pixel.is_finite() && metres_per_pixel > 0.0) {
            return Err(Error::config(
                "Calibration",
                "metres_per_pixel",
                format!("must be finite and positive, found {metres_per_pixel}"),
            ));
        }
        if !origin_m.iter().all(|v| v.is_finite()) {
            return Err(Error::config(
                "Calibration",
                "origin_m",
                format!("must be finite, found {origin_m:?}"),
            ));
        }
        if !rotation_deg.is_finite() {
            return Err(Error::config(
                "Calibration",
                "rotation_deg",
                format!("must be finite, found {rotation_deg}"),
            ));
        }
        let (s, c) = rotation_deg.to_radians().sin_cos();
        let k = metres_per_pixel;
        // Image +x → ground (c, s); image +y → ground direction rotation − 90° = (s, −c).
        let ground_from_image = [
            [k * c, k * s, origin_m[0]],
            [k * s, -k * c, origin_m[1]],
            [0.0, 0.0, 1.0],
        ];
        let image_from_ground = mat3_inverse(&ground_from_image)
            .ok_or_else(|| Error::config("Calibration", "metres_per_pixel", "degenerate"))?;
        Ok(Self {
            image_from_ground,
            ground_from_image,
            nadir: Some(NadirScale {
                metres_per_pixel,
                origin_m,
                rotation_deg,
            }),
            fit: None,
        })
    }

    /// A calibration from the homography `image_from_ground` (row-major). Its sign must make
    /// `w > 0` for ground points in front of the camera (multiply by −1 otherwise).
    ///
    /// # Errors
    /// A non-finite or singular matrix.
    pub fn from_homography(image_from_ground: Mat3) -> Result<Self> {
        if !image_from_ground.iter().flatten().all(|v| v.is_finite()) {
            return Err(Error::config(
                "Calibration",
                "image_from_ground",
                "has a non-finite entry",
            ));
        }
        let ground_from_image = mat3_inverse(&image_from_ground).ok_or_else(|| {
            Error::config("Calibration", "image_from_ground", "matrix is singular")
        })?;
        Ok(Self {
            image_from_ground,
            ground_from_image,
            nadir: None,
            fit: None,
        })
    }

    /// The homography from ground metres to image pixels.
    pub fn image_from_ground_matrix(&self) -> Mat3 {
        self.image_from_ground
    }

    /// The homography from image pixels to ground metres (the inverse).
    pub fn ground_from_image_matrix(&self) -> Mat3 {
        self.ground_from_image
    }

    /// The nadir parameters, when the calibration was given as a scale.
    pub fn nadir(&self) -> Option<NadirScale> {
        self.nadir
    }

    /// The ground sample distance of a nadir calibration, m/px.
    pub fn metres_per_pixel(&self) -> Option<f64> {
        self.nadir.map(|n| n.metres_per_pixel)
    }

    /// The ground point `(x_m, y_m)` seen at image point `p`, or `None` when `p` is on or
    /// above the horizon (its ray never meets the ground in front of the camera).
    pub fn ground_from_image(&self, p: Point) -> Option<(f64, f64)> {
        let [x, y, w] = apply(&self.ground_from_image, p.x, p.y);
        // H·(g/g_w) = p/g_w, so the ground point is in front (w > 0) exactly when g_w > 0.
        if w <= 1e-12 * (x.abs() + y.abs()).max(1.0) {
            return None;
        }
        Some((x / w, y / w))
    }

    /// The image point of ground point `(x_m, y_m)`, or `None` when it is behind the camera.
    pub fn image_from_ground(&self, x_m: f64, y_m: f64) -> Option<Point> {
        let [u, v, w] = apply(&self.image_from_ground, x_m, y_m);
        if w <= 0.0 {
            return None;
        }
        Some(Point::new(u / w, v / w))
    }

    /// The calibration as TOML text (the nadir form when it has one, else the homography).
    pub fn to_toml(&self) -> String {
        let file = match self.nadir {
            Some(n) => CalibrationFile {
                metres_per_pixel: Some(n.metres_per_pixel),
                origin_m: Some(n.origin_m),
                rotation_deg: Some(n.rotation_deg),
                image_from_ground: None,
                points: Vec::new(),
            },
            None => CalibrationFile {
                image_from_ground: Some(self.image_from_ground),
                ..Default::default()
            },
        };
        let body = toml::to_string(&file).unwrap_or_default();
        format!("# roadtrack calibration: ground plane z = 0 in metres, image in pixels.\n{body}")
    }

    /// Parses TOML text; `path` names the source in errors.
    ///
    /// # Errors
    /// Bad TOML, unknown keys, both or neither form given, invalid values.
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Self> {
        let file: CalibrationFile = toml::from_str(text).map_err(|e| Error::Toml {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        if !file.points.is_empty() {
            if file.metres_per_pixel.is_some() || file.image_from_ground.is_some() {
                return Err(Error::format(
                    path,
                    "give one form: points, metres_per_pixel or image_from_ground",
                ));
            }
            return Self::from_point_pairs(&file.points).map_err(|e| match e {
                Error::Invalid(m) => Error::format(path, format!("points: {m}")),
                other => other.in_file(path),
            });
        }
        if file.metres_per_pixel.is_none() && file.image_from_ground.is_none() {
            // Only `origin_m` or `rotation_deg`: the scale they belong to is missing.
            if file.origin_m.is_some() || file.rotation_deg.is_some() {
                return Err(Error::format(
                    path,
                    "origin_m and rotation_deg need metres_per_pixel",
                ));
            }
        }
        match (file.metres_per_pixel, file.image_from_ground) {
            (Some(k), None) => Self::from_nadir(
                k,
                file.origin_m.unwrap_or([0.0, 0.0]),
                file.rotation_deg.unwrap_or(0.0),
            )
            .map_err(|e| e.in_file(path)),
            (None, Some(h)) => {
                if file.origin_m.is_some() || file.rotation_deg.is_some() {
                    return Err(Error::format(
                        path,
                        "origin_m and rotation_deg belong to the metres_per_pixel form, not to image_from_ground",
                    ));
                }
                Self::from_homography(h).map_err(|e| e.in_file(path))
            }
            (Some(_), Some(_)) => Err(Error::format(
                path,
                "give either metres_per_pixel or image_from_ground, not both",
            )),
            (None, None) => Err(Error::format(
                path,
                "missing metres_per_pixel, image_from_ground or [[points]]",
            )),
        }
    }

    /// Estimates the homography from four or more point pairs by the normalised direct linear
    /// transform (least squares on the algebraic error, Hartley & Zisserman alg. 4.2), and
    /// records the reprojection error in [`Calibration::fit`].
    ///
    /// # Errors
    /// Fewer than four pairs, non-finite values, or a degenerate configuration (three or
    /// more points on one line in either plane, so that `H` is not determined).
    pub fn from_point_pairs(pairs: &[PointPair]) -> Result<Self> {
        if pairs.len() < 4 {
            return Err(Error::Invalid(format!(
                "a homography needs at least 4 point pairs, found {}",
                pairs.len()
            )));
        }
        if let Some(k) = pairs
            .iter()
            .position(|p| p.image.iter().chain(&p.ground).any(|v| !v.is_finite()))
        {
            return Err(Error::Invalid(format!(
                "point pair {} has a non-finite coordinate (image {:?}, ground {:?})",
                k + 1,
                pairs[k].image,
                pairs[k].ground
            )));
        }
        // Similarity normalisation: centroid to the origin, mean distance √2.
        fn normaliser(pts: &[[f64; 2]]) -> Mat3 {
            let n = pts.len() as f64;
            let (cx, cy) = pts
                .iter()
                .fold((0.0, 0.0), |a, p| (a.0 + p[0] / n, a.1 + p[1] / n));
            let d = pts
                .iter()
                .map(|p| (p[0] - cx).hypot(p[1] - cy))
                .sum::<f64>()
                / n;
            let s = if d > 0.0 { 2f64.sqrt() / d } else { 1.0 };
            [[s, 0.0, -s * cx], [0.0, s, -s * cy], [0.0, 0.0, 1.0]]
        }
        let apply = |m: &Mat3, p: [f64; 2]| {
            let w = m[2][0] * p[0] + m[2][1] * p[1] + m[2][2];
            [
                (m[0][0] * p[0] + m[0][1] * p[1] + m[0][2]) / w,
                (m[1][0] * p[0] + m[1][1] * p[1] + m[1][2]) / w,
            ]
        };
        let img: Vec<[f64; 2]> = pairs.iter().map(|p| p.image).collect();
        let gnd: Vec<[f64; 2]> = pairs.iter().map(|p| p.ground).collect();
        let (ti, tg) = (normaliser(&img), normaliser(&gnd));
        let n = pairs.len();
        let mut a = nalgebra::DMatrix::<f64>::zeros(2 * n, 9);
        for (k, (i, g)) in img.iter().zip(&gnd).enumerate() {
            let [u, v] = apply(&ti, *i);
            let [x, y] = apply(&tg, *g);
            let r0 = [x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, -u];
            let r1 = [0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y, -v];
            for c in 0..9 {
                a[(2 * k, c)] = r0[c];
                a[(2 * k + 1, c)] = r1[c];
            }
        }
        // The solution is the right singular vector of the smallest singular value; with
        // exactly 4 pairs A is 8 × 9, so pad to 9 rows for a full V.
        let rows = a.nrows();
        let a = if rows < 9 { a.insert_row(rows, 0.0) } else { a };
        let svd = a.svd(false, true);
        let v_t = svd
            .v_t
            .ok_or_else(|| Error::Invalid("SVD of the point pairs failed".into()))?;
        let (mut min_k, mut min_s) = (0, f64::INFINITY);
        let mut sorted: Vec<f64> = svd.singular_values.iter().copied().collect();
        for (k, &s) in svd.singular_values.iter().enumerate() {
            if s < min_s {
                (min_k, min_s) = (k, s);
            }
        }
        sorted.sort_by(f64::total_cmp);
        // Degenerate when the null space has more than one dimension.
        if sorted.len() > 1 && sorted[1] <= 1e-9 * sorted[sorted.len() - 1] {
            return Err(Error::Invalid(
                "the point pairs do not determine a homography (are three or more on one line?)"
                    .into(),
            ));
        }
        let h = v_t.row(min_k);
        let hn: Mat3 = [[h[0], h[1], h[2]], [h[3], h[4], h[5]], [h[6], h[7], h[8]]];
        let ti_inv =
            mat3_inverse(&ti).ok_or_else(|| Error::Invalid("degenerate image points".into()))?;
        let mut hm = mat3_mul(&mat3_mul(&ti_inv, &hn), &tg);
        // Scale so that w > 0 in front of the camera (at the ground points) and h33 = 1 where possible.
        let w0 = hm[2][0] * gnd[0][0] + hm[2][1] * gnd[0][1] + hm[2][2];
        let scale = if hm[2][2].abs() > 1e-12 {
            1.0 / hm[2][2]
        } else {
            1.0
        };
        let scale = if w0 * scale < 0.0 { -scale } else { scale };
        for row in &mut hm {
            for v in row.iter_mut() {
                *v *= scale;
            }
        }
        let mut cal = Self::from_homography(hm)?;
        let errors_px: Vec<f64> = pairs
            .iter()
            .map(|p| {
                cal.image_from_ground(p.ground[0], p.ground[1])
                    .map_or(f64::INFINITY, |q| {
                        (q.x - p.image[0]).hypot(q.y - p.image[1])
                    })
            })
            .collect();
        let rms_px = (errors_px.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
        let max_px = errors_px.iter().copied().fold(0.0, f64::max);
        cal.fit = Some(FitReport {
            points: n,
            rms_px,
            max_px,
            errors_px,
        });
        Ok(cal)
    }

    /// The reprojection report when the calibration was estimated from point pairs.
    pub fn fit(&self) -> Option<&FitReport> {
        self.fit.as_ref()
    }

    /// Reads a calibration file.
    ///
    /// # Errors
    /// As [`Calibration::from_toml_str`], plus I/O errors.
    pub fn load(path: &Path) -> Result<Self> {
        let text = crate::io::read_text(path)?;
        Self::from_toml_str(&text, path)
    }

    /// Writes the calibration file atomically.
    pub fn save(&self, path: &Path) -> Result<()> {
        crate::io::atomic::write_bytes_atomic(path, self.to_toml().as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn nadir_scale_maps_pixels_to_metres_with_north_up() -> Result<()> {
        let c = Calibration::from_nadir(0.33, [10.0, 50.0], 0.0)?;
        let (x, y) = c
            .ground_from_image(Point::new(100.0, 30.0))
            .ok_or(Error::Invalid("horizon".into()))?;
        assert!(
            close(x, 10.0 + 33.0, 1e-9) && close(y, 50.0 - 9.9, 1e-9),
            "{x} {y}"
        );
        let p = c
            .image_from_ground(x, y)
            .ok_or(Error::Invalid("behind".into()))?;
        assert!(close(p.x, 100.0, 1e-9) && close(p.y, 30.0, 1e-9));
        Ok(())
    }

    #[test]
    fn inverse_times_matrix_is_identity() {
        let m = [[2.0, 0.5, -3.0], [0.1, 1.5, 4.0], [0.001, 0.02, 1.0]];
        let inv = mat3_inverse(&m).expect("invertible");
        let id = mat3_mul(&m, &inv);
        for (i, row) in id.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                assert!(close(*v, f64::from(u8::from(i == j)), 1e-12), "{id:?}");
            }
        }
        assert!(mat3_inverse(&[[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]]).is_none());
    }

    #[test]
    fn toml_round_trips_both_forms() -> Result<()> {
        let p = Path::new("c.toml");
        let a = Calibration::from_nadir(0.5, [1.0, 2.0], 30.0)?;
        assert_eq!(Calibration::from_toml_str(&a.to_toml(), p)?, a);
        let h = [[500.0, 10.0, 320.0], [5.0, -200.0, 700.0], [0.01, 0.1, 1.0]];
        let b = Calibration::from_homography(h)?;
        let back = Calibration::from_toml_str(&b.to_toml(), p)?;
        assert_eq!(back.image_from_ground_matrix(), h);
        Ok(())
    }

    #[test]
    fn bad_files_are_rejected_with_a_reason() {
        let p = Path::new("c.toml");
        let both = "metres_per_pixel = 1.0\nimage_from_ground = [[1.0,0.0,0.0],[0.0,1.0,0.0],[0.0,0.0,1.0]]\n";
        assert!(Calibration::from_toml_str(both, p).is_err());
        assert!(Calibration::from_toml_str("", p).is_err());
        assert!(Calibration::from_toml_str("metres_per_pixel = 1.0\nscale = 2\n", p).is_err());
        assert!(Calibration::from_toml_str("metres_per_pixel = -1.0\n", p).is_err());
    }

    #[test]
    fn arrays_must_have_their_exact_length_and_nan_is_named_by_field() {
        let p = Path::new("calib.toml");
        let err = |text: &str| {
            Calibration::from_toml_str(text, p)
                .expect_err(text)
                .to_string()
        };
        let id = "[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]";
        for (text, needle) in [
            (
                "image_from_ground = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]\n".to_owned(),
                "exactly 3 values",
            ),
            (format!("image_from_ground = [{id}, [0.0, 0.0, 1.0]]\n"), "exactly 3 values"),
            ("image_from_ground = [[1.0, 0.0], [0.0, 1.0]]\n".to_owned(), "exactly 3"),
            (
                "metres_per_pixel = 0.5\norigin_m = [1.0, 2.0, 3.0, 4.0]\n".to_owned(),
                "exactly 2 values",
            ),
            (
                "[[points]]\nimage = [1.0, 2.0, 3.0]\nground = [0.0, 0.0]\n".to_owned(),
                "exactly 2 values",
            ),
            ("metres_per_pixel = nan\n".to_owned(), "metres_per_pixel"),
            ("metres_per_pixel = inf\n".to_owned(), "metres_per_pixel"),
            (
                "metres_per_pixel = 0.5\norigin_m = [nan, 2.0]\n".to_owned(),
                "origin_m",
            ),
            (
                "metres_per_pixel = 0.5\nrotation_deg = nan\n".to_owned(),
                "rotation_deg",
            ),
            (
                "image_from_ground = [[1.0, 0.0, nan], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n"
                    .to_owned(),
                "image_from_ground",
            ),
            (
                "image_from_ground = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]]\n"
                    .to_owned(),
                "image_from_ground: matrix is singular",
            ),
        ] {
            let e = err(&text);
            assert!(e.starts_with("calib.toml"), "{text}: {e}");
            assert!(e.contains(needle), "{text}: {e}");
            assert!(!e.contains("Calibration."), "{text}: {e}");
        }
        let nan_pair = "[[points]]\nimage = [0.0, 0.0]\nground = [0.0, 0.0]\n\
             [[points]]\nimage = [1.0, 0.0]\nground = [1.0, 0.0]\n\
             [[points]]\nimage = [1.0, 1.0]\nground = [1.0, 1.0]\n\
             [[points]]\nimage = [0.0, nan]\nground = [0.0, 1.0]\n";
        let e = err(nan_pair);
        assert!(e.contains("calib.toml: points: point pair 4"), "{e}");
    }

    #[test]
    fn points_above_the_horizon_have_no_ground_point() -> Result<()> {
        // A camera 8 m high looking along +x, tilted down: rows above the horizon map nowhere.
        let f = 500.0;
        let tilt = 10f64.to_radians();
        let (s, c) = tilt.sin_cos();
        // Camera at (0, 0, h): right = (0,−1,0), forward = (c,0,−s), up = (s,0,c), so
        // x_cam = −y, y_cam = s·x − c·h, z_cam = c·x + s·h for a ground point (x, y, 0).
        let h = 8.0;
        let (xc, yc, zc) = ([0.0, -1.0, 0.0], [s, 0.0, -c * h], [c, 0.0, s * h]);
        let m = [
            [0, 1, 2].map(|k| f * xc[k] + 320.0 * zc[k]),
            [0, 1, 2].map(|k| -f * yc[k] + 240.0 * zc[k]),
            zc,
        ];
        let cal = Calibration::from_homography(m)?;
        assert!(cal.ground_from_image(Point::new(320.0, 0.0)).is_none());
        let (x, y) = cal
            .ground_from_image(Point::new(320.0, 479.0))
            .ok_or(Error::Invalid("horizon".into()))?;
        assert!(x > 0.0 && y.abs() < 1e-9, "{x} {y}");
        assert!(cal.image_from_ground(-10.0, 0.0).is_none());
        Ok(())
    }

    /// An oblique camera's homography (8 m high, tilted) for the estimation tests.
    fn oblique() -> Mat3 {
        [
            [620.0, -180.0, 2400.0],
            [40.0, 95.0, 5200.0],
            [0.02, -0.35, 12.0],
        ]
    }

    #[test]
    fn point_pairs_recover_a_known_homography_from_noisy_points() -> Result<()> {
        use rand::RngExt;
        let truth = Calibration::from_homography(oblique())?;
        let mut rng = crate::rng::rng(3, crate::rng::Stream::Synthetic);
        let mut pairs = Vec::new();
        for gx in [-10.0, -5.0, 0.0, 5.0, 10.0] {
            for gy in [5.0, 10.0, 20.0, 30.0] {
                let p = truth.image_from_ground(gx, gy).expect("in front");
                // ±0.5 px uniform image noise.
                let (nx, ny) = (rng.random_range(-0.5..=0.5), rng.random_range(-0.5..=0.5));
                pairs.push(PointPair {
                    image: [p.x + nx, p.y + ny],
                    ground: [gx, gy],
                });
            }
        }
        let est = Calibration::from_point_pairs(&pairs)?;
        let fit = est.fit().expect("fit report");
        assert_eq!(fit.points, 20);
        assert!(fit.rms_px < 0.6 && fit.max_px < 1.5, "{fit:?}");
        // Ground positions agree within 5 cm over the surveyed area.
        for gx in [-8.0, 0.0, 8.0] {
            for gy in [6.0, 15.0, 28.0] {
                let p = truth.image_from_ground(gx, gy).expect("in front");
                let (x, y) = est.ground_from_image(p).expect("ground");
                assert!((x - gx).hypot(y - gy) < 0.05, "({gx},{gy}) → ({x},{y})");
            }
        }
        Ok(())
    }

    #[test]
    fn exact_pairs_give_zero_reprojection_and_bad_sets_are_rejected() -> Result<()> {
        let truth = Calibration::from_homography(oblique())?;
        let pairs: Vec<PointPair> = [[0.0, 5.0], [4.0, 5.0], [4.0, 20.0], [0.0, 20.0]]
            .iter()
            .map(|g| {
                let p = truth.image_from_ground(g[0], g[1]).expect("in front");
                PointPair {
                    image: [p.x, p.y],
                    ground: *g,
                }
            })
            .collect();
        let est = Calibration::from_point_pairs(&pairs)?;
        assert!(est.fit().expect("fit").max_px < 1e-6);
        assert!(Calibration::from_point_pairs(&pairs[..3]).is_err());
        let collinear: Vec<PointPair> = (0..5)
            .map(|k| PointPair {
                image: [k as f64, 2.0 * k as f64],
                ground: [k as f64, 0.0],
            })
            .collect();
        let e = Calibration::from_point_pairs(&collinear)
            .expect_err("collinear")
            .to_string();
        assert!(e.contains("line"), "{e}");
        let toml = "[[points]]\nimage = [1.0, 2.0]\nground = [0.0, 0.0]\n";
        let e = Calibration::from_toml_str(toml, Path::new("c.toml"))
            .expect_err("one pair")
            .to_string();
        assert!(e.contains("c.toml") && e.contains("at least 4"), "{e}");
        Ok(())
    }
}
