//! Splitting a foreground region that holds several vehicles in a row (a queue at a red
//! light, a platoon merged by shadows or closing) using the expected vehicle size at that
//! image position from the camera calibration.
//!
//! For a region with principal axis `u` (second moments) and extent `E` along it (pixels):
//! the end of the axis lower in the image is taken as the near end (ground contact in an
//! oblique view), mapped to the ground point `G0`, the far end to `G1`; a row of `k`
//! vehicles (length `L`, width `W`, height `H`, gap `g` between them) is laid on the ground
//! from `G0` towards `G1` and its 3-D box projected; the `k` (1 ..= `max_pieces`) whose
//! projected extent along `u` is closest to `E` is the number of vehicles. The region is
//! then cut across `u` in the middle of each gap, or where a vehicle's projected box ends
//! when it hides the next one's lower part (scaled so that the `k` boxes span exactly `E`).
//!
//! Heights need the camera, which a ground homography alone does not give: it is recovered
//! by assuming square pixels and the principal point at the image centre (true of the
//! simulator's cameras and a fair assumption for most others), solving for the focal length
//! from the orthogonality of the rotation's first two columns ([`Camera3::from_calibration`]).
//! A nadir (scale) calibration is orthographic: heights do not move points.
//!
//! Choice: a row of boxes along the principal axis rather than distance-transform peaks or
//! watershed. Queued vehicles seen from behind overlap in the image (one hides the next's
//! lower part), so their union has no neck for a distance transform to find; what does
//! separate them is the known length of a vehicle at that distance. Limits: a bus or lorry
//! (9–11 m) looks like two cars and is cut in two; vehicles side by side across lanes are
//! not split (the axis then runs across the lanes).

use crate::calibration::Calibration;
use crate::geometry::Point;
use serde::{Deserialize, Serialize};

/// Parameters of region splitting (`[split]`): the row cutter for queued vehicles (needs a
/// calibration) and the column cutter for people side by side (module
/// [`super::columns`]; needs none).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SplitConfig {
    /// Split regions holding several vehicles in a row (needs a calibration:
    /// `--calibration`). Default false.
    ///
    /// Choice: off by default. On the simulator's scenes (docs/EXPERIMENTS.md, "Detection")
    /// it raises car recall and finds most queued vehicles but costs precision (buses and
    /// lorries cut in two, pieces that vary from frame to frame) and the demo's relaxation
    /// HOTA (0.257 → 0.205).
    pub enabled: bool,
    /// Vehicle length, m. Default 4.5 (a car).
    pub vehicle_length_m: f64,
    /// Vehicle width, m. Default 1.8.
    pub vehicle_width_m: f64,
    /// Vehicle height, m. Default 1.5.
    pub vehicle_height_m: f64,
    /// Gap between queued vehicles, m. Default 2 (IDM's standstill gap).
    pub gap_m: f64,
    /// Most pieces one region is cut into. Default 6.
    pub max_pieces: u32,
    /// Cut regions at the valleys of their column profile (people walking side by side;
    /// module [`super::columns`]). Needs no calibration. Default false (it would cut a
    /// vehicle whose mask has a dark gap across it; `configs/detect-pedestrians.toml` turns
    /// it on). A region cut by columns is not cut by rows.
    pub columns: bool,
    /// A valley is at most this fraction of the lower peak beside it. Default 0.5.
    pub column_valley_ratio: f64,
    /// Each side of a valley peaks at least this fraction of the region's highest column.
    /// Default 0.5.
    pub column_min_peak: f64,
    /// Narrowest piece, as a fraction of the region's height (a person is about 0.3–0.45
    /// as wide as tall). Default 0.2.
    pub column_min_width: f64,
}

impl Default for SplitConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            vehicle_length_m: 4.5,
            vehicle_width_m: 1.8,
            vehicle_height_m: 1.5,
            gap_m: 2.0,
            max_pieces: 6,
            columns: false,
            column_valley_ratio: 0.5,
            column_min_peak: 0.5,
            column_min_width: 0.2,
        }
    }
}

impl SplitConfig {
    /// Checks the ranges.
    pub fn validate(&self) -> crate::Result<()> {
        for (v, f) in [
            (self.vehicle_length_m, "vehicle_length_m"),
            (self.vehicle_width_m, "vehicle_width_m"),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(crate::Error::config(
                    "SplitConfig",
                    f,
                    format!("must be finite and positive, found {v}"),
                ));
            }
        }
        for (v, f) in [
            (self.vehicle_height_m, "vehicle_height_m"),
            (self.gap_m, "gap_m"),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(crate::Error::config(
                    "SplitConfig",
                    f,
                    format!("must be finite and ≥ 0, found {v}"),
                ));
            }
        }
        for (v, f) in [
            (self.column_valley_ratio, "column_valley_ratio"),
            (self.column_min_peak, "column_min_peak"),
            (self.column_min_width, "column_min_width"),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 1.0) {
                return Err(crate::Error::config(
                    "SplitConfig",
                    f,
                    format!("must be in (0, 1], found {v}"),
                ));
            }
        }
        if self.max_pieces == 0 {
            return Err(crate::Error::config(
                "SplitConfig",
                "max_pieces",
                "must be at least 1",
            ));
        }
        Ok(())
    }
}

/// A pinhole camera recovered from a ground homography: image point of a 3-D point
/// `(x, y, z)` (metres, `z` up) is `H·(x, y, 1) + z·v` dehomogenised, `v` the image of the
/// vertical direction (zero for an orthographic view).
#[derive(Debug, Clone, PartialEq)]
pub struct Camera3 {
    h: [[f64; 3]; 3],
    vertical: [f64; 3],
}

impl Camera3 {
    /// The camera of `calibration` for images of `width × height` px (principal point at
    /// the centre, square pixels). Falls back to an orthographic view (heights ignored)
    /// for a nadir calibration or when no focal length fits.
    pub fn from_calibration(calibration: &Calibration, width: u32, height: u32) -> Self {
        let h = calibration.image_from_ground_matrix();
        let ortho = Self {
            h,
            vertical: [0.0; 3],
        };
        if calibration.nadir().is_some() {
            return ortho;
        }
        let (cx, cy) = (f64::from(width) / 2.0, f64::from(height) / 2.0);
        // H' = T⁻¹·H: coordinates relative to the principal point.
        let col = |j: usize| [h[0][j] - cx * h[2][j], h[1][j] - cy * h[2][j], h[2][j]];
        let (a, b, c) = (col(0), col(1), col(2));
        // r1 ⊥ r2 with K = diag(f, f, 1): (a0 b0 + a1 b1)/f² + a2 b2 = 0.
        let f2 = if (a[2] * b[2]).abs() > 1e-12 {
            -(a[0] * b[0] + a[1] * b[1]) / (a[2] * b[2])
        } else if (a[2] * a[2] - b[2] * b[2]).abs() > 1e-12 {
            // |r1| = |r2|.
            (b[0] * b[0] + b[1] * b[1] - a[0] * a[0] - a[1] * a[1]) / (a[2] * a[2] - b[2] * b[2])
        } else {
            return ortho;
        };
        if !(f2.is_finite() && f2 > 0.0) {
            return ortho;
        }
        let f = f2.sqrt();
        let kinv = |v: [f64; 3]| [v[0] / f, v[1] / f, v[2]];
        let (q1, q2, q3) = (kinv(a), kinv(b), kinv(c));
        let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let lambda = (norm(q1) * norm(q2)).sqrt();
        if !(lambda.is_finite() && lambda > 0.0) {
            return ortho;
        }
        let r1 = q1.map(|v| v / norm(q1));
        let r2 = q2.map(|v| v / norm(q2));
        let mut r3 = [
            r1[1] * r2[2] - r1[2] * r2[1],
            r1[2] * r2[0] - r1[0] * r2[2],
            r1[0] * r2[1] - r1[1] * r2[0],
        ];
        let t = q3.map(|v| v / lambda);
        // The camera centre −Rᵀt is above the ground: its height −r3·t > 0.
        if r3[0] * t[0] + r3[1] * t[1] + r3[2] * t[2] > 0.0 {
            r3 = r3.map(|v| -v);
        }
        // v = T·λ·K·r3.
        let k = [lambda * f * r3[0], lambda * f * r3[1], lambda * r3[2]];
        Self {
            h,
            vertical: [k[0] + cx * k[2], k[1] + cy * k[2], k[2]],
        }
    }

    /// Image point of the 3-D point `(x, y, z)`, or `None` behind the camera.
    pub fn project(&self, x: f64, y: f64, z: f64) -> Option<Point> {
        let h = &self.h;
        let p: [f64; 3] =
            std::array::from_fn(|i| h[i][0] * x + h[i][1] * y + h[i][2] + z * self.vertical[i]);
        (p[2] > 0.0).then(|| Point::new(p[0] / p[2], p[1] / p[2]))
    }
}

/// A standing person's height, m ([`PersonSize`]).
pub const PERSON_HEIGHT_M: f64 = 1.7;
/// A standing person's box width as a share of its height ([`PersonSize`]; the column
/// cutter takes a person as 0.3–0.45 as wide as tall).
pub const PERSON_WIDTH_SHARE: f64 = 0.4;

/// The image box a standing person would have at each foot point, from a calibration.
#[derive(Debug, Clone)]
pub struct PersonSize {
    calibration: Calibration,
    camera: Camera3,
}

impl PersonSize {
    /// Person sizes in `width × height` images seen through `calibration`.
    pub fn new(calibration: Calibration, width: u32, height: u32) -> Self {
        let camera = Camera3::from_calibration(&calibration, width, height);
        Self {
            calibration,
            camera,
        }
    }

    /// Area, px², of the box of a person standing with the feet at image point `foot`:
    /// [`PERSON_HEIGHT_M`] from the feet's image to the head's, [`PERSON_WIDTH_SHARE`] of
    /// that wide. `None` where the ground is not seen there, and where the calibration does
    /// not see heights (a nadir one, or no focal length fits): the head then projects onto
    /// the feet.
    pub fn box_area_px(&self, foot: Point) -> Option<f64> {
        let (x, y) = self.calibration.ground_from_image(foot)?;
        let feet = self.camera.project(x, y, 0.0)?;
        let head = self.camera.project(x, y, PERSON_HEIGHT_M)?;
        let h = feet.distance(head);
        (h.is_finite() && h >= 1.0).then_some(PERSON_WIDTH_SHARE * h * h)
    }
}

/// Decides how many vehicles a region holds and where to cut it.
#[derive(Debug, Clone)]
pub struct Splitter {
    config: SplitConfig,
    calibration: Calibration,
    camera: Camera3,
}

impl Splitter {
    /// A splitter for `width × height` images seen through `calibration`.
    pub fn new(config: SplitConfig, calibration: Calibration, width: u32, height: u32) -> Self {
        let camera = Camera3::from_calibration(&calibration, width, height);
        Self {
            config,
            calibration,
            camera,
        }
    }

    /// The cuts of a region with centroid `c`, unit principal axis `u` and pixel extent
    /// `[t_min, t_max]` along it (`t = (p − c)·u`): the `t` values at which consecutive
    /// pieces meet, increasing, `k − 1` of them for `k` vehicles (empty: one vehicle).
    pub fn cuts(&self, c: Point, u: (f64, f64), t_min: f64, t_max: f64) -> Vec<f64> {
        let extent = t_max - t_min;
        if extent <= 0.0 || self.config.max_pieces < 2 {
            return Vec::new();
        }
        let at = |t: f64| Point::new(c.x + t * u.0, c.y + t * u.1);
        // The near end is the lower one in the image (larger y).
        let (t_near, t_far) = if at(t_min).y >= at(t_max).y {
            (t_min, t_max)
        } else {
            (t_max, t_min)
        };
        let sign = if t_far > t_near { 1.0 } else { -1.0 };
        let Some(g0) = self.calibration.ground_from_image(at(t_near)) else {
            return Vec::new();
        };
        let dir = self
            .calibration
            .ground_from_image(at(t_far))
            .or_else(|| self.calibration.ground_from_image(at(t_near + sign)))
            .map(|g| (g.0 - g0.0, g.1 - g0.1));
        let Some((dx, dy)) = dir else {
            return Vec::new();
        };
        let n = (dx * dx + dy * dy).sqrt();
        if !(n.is_finite() && n > 0.0) {
            return Vec::new();
        }
        let v = (dx / n, dy / n);
        let w = (-v.1, v.0);
        let cfg = &self.config;
        // Signed distance from the near end, along u towards the far end, of the far edge
        // of a box from ground distance 0 to `len` along v.
        let far_edge = |len: f64| -> Option<f64> {
            let mut best = f64::NEG_INFINITY;
            for s in [0.0, len] {
                for side in [-0.5, 0.5] {
                    let gx = g0.0 + s * v.0 + side * cfg.vehicle_width_m * w.0;
                    let gy = g0.1 + s * v.1 + side * cfg.vehicle_width_m * w.1;
                    for z in [0.0, cfg.vehicle_height_m] {
                        let p = self.camera.project(gx, gy, z)?;
                        let t = ((p.x - c.x) * u.0 + (p.y - c.y) * u.1 - t_near) * sign;
                        best = best.max(t);
                    }
                }
            }
            Some(best)
        };
        // Signed distance of the near edge (on the ground) of the vehicle starting at `s`.
        let near_edge = |s: f64| -> Option<f64> {
            let p = self.camera.project(g0.0 + s * v.0, g0.1 + s * v.1, 0.0)?;
            Some(((p.x - c.x) * u.0 + (p.y - c.y) * u.1 - t_near) * sign)
        };
        let pitch = cfg.vehicle_length_m + cfg.gap_m;
        let mut edges = Vec::new();
        let mut cut_at = Vec::new();
        for k in 1..=cfg.max_pieces {
            let len = f64::from(k - 1) * pitch + cfg.vehicle_length_m;
            match (far_edge(len), near_edge(f64::from(k) * pitch)) {
                (Some(e), Some(next)) if e.is_finite() && e > 0.0 && next.is_finite() => {
                    edges.push(e);
                    // Mid-gap where the gap shows; where this vehicle hides the next one's
                    // lower part (oblique views), where this one's silhouette ends.
                    cut_at.push(e.max((e + next) / 2.0));
                }
                _ => break,
            }
        }
        let Some(k) = edges
            .iter()
            .enumerate()
            .min_by(|a, b| (a.1 - extent).abs().total_cmp(&(b.1 - extent).abs()))
            .map(|(i, _)| i + 1)
        else {
            return Vec::new();
        };
        if k < 2 {
            return Vec::new();
        }
        let scale = extent / edges[k - 1];
        let mut cuts: Vec<f64> = cut_at[..k - 1]
            .iter()
            .map(|e| t_near + sign * e * scale)
            .collect();
        cuts.sort_by(f64::total_cmp);
        cuts
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A camera at height 8 m looking along +y, tilted down 20°, focal 512 px, 640 × 480.
    pub(crate) fn pinhole() -> (Calibration, impl Fn(f64, f64, f64) -> Point) {
        let (f, cx, cy) = (512.0, 320.0, 240.0);
        let tilt = 20f64.to_radians();
        let (s, c) = tilt.sin_cos();
        // Camera axes in ground frame: x_c = (1,0,0), y_c (image down) and z_c (forward).
        let zc = [0.0, c, -s];
        let yc = [0.0, -s, -c];
        let xc = [1.0, 0.0, 0.0];
        let centre = [0.0, 0.0, 8.0];
        let proj = move |x: f64, y: f64, z: f64| {
            let d = [x - centre[0], y - centre[1], z - centre[2]];
            let dot = |a: [f64; 3]| a[0] * d[0] + a[1] * d[1] + a[2] * d[2];
            let (px, py, pz) = (dot(xc), dot(yc), dot(zc));
            Point::new(f * px / pz + cx, f * py / pz + cy)
        };
        // H = K·[r1 r2 t] with rows of R = camera axes, t = −R·centre.
        let r = [xc, yc, zc];
        let t: Vec<f64> = r
            .iter()
            .map(|a| -(a[0] * centre[0] + a[1] * centre[1] + a[2] * centre[2]))
            .collect();
        let m: [[f64; 3]; 3] = std::array::from_fn(|i| [r[i][0], r[i][1], t[i]]);
        let h = [
            std::array::from_fn(|j| f * m[0][j] + cx * m[2][j]),
            std::array::from_fn(|j| f * m[1][j] + cy * m[2][j]),
            m[2],
        ];
        (Calibration::from_homography(h).expect("homography"), proj)
    }

    #[test]
    fn a_person_box_is_the_projected_person_and_unknown_from_above() -> Result<(), crate::Error> {
        let (cal, proj) = pinhole();
        let sizes = PersonSize::new(cal, 640, 480);
        for (x, y) in [(0.0, 6.0), (-3.0, 12.0), (4.0, 30.0)] {
            let (feet, head) = (proj(x, y, 0.0), proj(x, y, PERSON_HEIGHT_M));
            let h = feet.distance(head);
            let a = sizes.box_area_px(feet).expect("ground seen");
            assert!(
                (a - PERSON_WIDTH_SHARE * h * h).abs() < 1e-6 * a,
                "({x}, {y}): {a}"
            );
        }
        // Farther is smaller.
        let near = sizes.box_area_px(proj(0.0, 6.0, 0.0));
        assert!(near > sizes.box_area_px(proj(0.0, 30.0, 0.0)));
        // Above the horizon (the sky) and from a nadir calibration: no person size.
        assert_eq!(sizes.box_area_px(Point::new(320.0, 0.0)), None);
        let nadir = PersonSize::new(Calibration::from_nadir(0.1, [0.0, 0.0], 0.0)?, 640, 480);
        assert_eq!(nadir.box_area_px(Point::new(320.0, 240.0)), None);
        Ok(())
    }

    #[test]
    fn camera_from_homography_projects_heights() {
        let (cal, proj) = pinhole();
        let cam = Camera3::from_calibration(&cal, 640, 480);
        for (x, y, z) in [(0.0, 20.0, 1.5), (3.0, 35.0, 3.0), (-4.0, 15.0, 0.0)] {
            let got = cam.project(x, y, z).expect("in front");
            let want = proj(x, y, z);
            assert!(
                (got.x - want.x).abs() < 1e-6 && (got.y - want.y).abs() < 1e-6,
                "{got:?} vs {want:?}"
            );
        }
    }

    #[test]
    fn a_queue_of_three_is_cut_in_three_and_one_car_is_not_cut() {
        let (cal, proj) = pinhole();
        let split = Splitter::new(SplitConfig::default(), cal, 640, 480);
        // Vertical extent of `k` cars queued from y = 20 m away from the camera (x = 0).
        let span = |k: u32| {
            let len = f64::from(k - 1) * 6.5 + 4.5;
            let near = proj(0.0, 20.0, 0.0).y;
            let far = proj(0.0, 20.0 + len, 1.5).y;
            (far, near)
        };
        for k in 1..=4u32 {
            let (top, bottom) = span(k);
            let c = Point::new(320.0, (top + bottom) / 2.0);
            let half = (bottom - top) / 2.0;
            let cuts = split.cuts(c, (0.0, 1.0), -half, half);
            assert_eq!(cuts.len() as u32, k - 1, "k = {k}: {cuts:?}");
            assert!(cuts.windows(2).all(|w| w[0] < w[1]));
        }
    }
}
