//! Cameras: the nadir (orthographic, metres per pixel) view of seed 000 and the pinhole
//! view from a pole of seed 002.
//!
//! Ground frame: `x`, `y` on the road plane, `z` up, metres. Pinhole model with the camera
//! at `C`, unit axes `right`, `up`, `forward`, focal length `f` px and principal point
//! `(c_x, c_y)` (the image centre):
//!
//! ```text
//! x_c = right·(P − C),  y_c = up·(P − C),  z_c = forward·(P − C)
//! u = c_x + f·x_c / z_c,   v = c_y − f·y_c / z_c
//! ```
//!
//! On the ground plane this is the homography written to `calibration.toml`.

use super::config::{SimConfig, ViewKind};
use super::scene::Scene;
use roadtrack_core::calibration::Calibration;
use roadtrack_core::error::Result;

/// A 3-D ground-frame point or vector, m.
pub type Vec3 = [f64; 3];

fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Nearest distance in front of a pinhole camera that is drawn, m.
const NEAR_M: f64 = 0.5;

/// A camera looking at the scene.
#[derive(Debug, Clone, PartialEq)]
pub enum Camera {
    /// Straight down, orthographic.
    Aerial {
        /// Ground sample distance, m/px.
        metres_per_pixel: f64,
        /// Ground point of pixel (0, 0).
        origin_m: [f64; 2],
        /// Ground direction of image `+x`, radians.
        rotation_rad: f64,
        /// Image shift (camera jitter), px.
        shift_px: [f64; 2],
    },
    /// Pinhole on a pole.
    Pinhole {
        /// Centre of projection, m.
        centre_m: Vec3,
        /// Unit axes: right, up, forward.
        axes: [Vec3; 3],
        /// Focal length, px.
        focal_px: f64,
        /// Principal point, px (image centre plus jitter).
        principal_px: [f64; 2],
    },
}

/// A point in camera space: image coordinates (after projection) and a depth key.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CamPoint {
    /// Camera-space coordinates before the perspective division
    /// (pinhole: `x_c, y_c, z_c`; aerial: `u, v, −z`).
    pub c: Vec3,
}

impl Camera {
    /// The camera of `config.view` placed for `scene`, for images of `width × height` px.
    ///
    /// # Errors
    /// A degenerate placement (never with validated configs).
    pub fn new(config: &SimConfig, scene: &Scene, width: u32, height: u32) -> Result<Camera> {
        let (w, h) = (f64::from(width), f64::from(height));
        Ok(match config.view {
            ViewKind::Aerial => {
                let a = &config.aerial;
                let centre = a.centre_m.unwrap_or(scene.centre_m);
                let rot = a.rotation_deg.to_radians();
                let (s, c) = rot.sin_cos();
                let k = a.metres_per_pixel;
                // centre = origin + k·(w/2·(c, s) + h/2·(s, −c)).
                let origin = [
                    centre[0] - k * (w / 2.0 * c + h / 2.0 * s),
                    centre[1] - k * (w / 2.0 * s - h / 2.0 * c),
                ];
                Camera::Aerial {
                    metres_per_pixel: k,
                    origin_m: origin,
                    rotation_rad: rot,
                    shift_px: [0.0, 0.0],
                }
            }
            ViewKind::Oblique => {
                let o = &config.oblique;
                let place = scene.camera;
                let pos = o.position_m.unwrap_or(place.position_m);
                let yaw = o.yaw_deg.unwrap_or(place.yaw_deg).to_radians();
                let tilt = o.tilt_deg.unwrap_or(place.tilt_deg).to_radians();
                let focal = o.focal_px.unwrap_or(0.8 * w);
                let (sy, cy) = yaw.sin_cos();
                let (st, ct) = tilt.sin_cos();
                let forward = [cy * ct, sy * ct, -st];
                let right = [sy, -cy, 0.0];
                // up = right × forward.
                let up = [
                    right[1] * forward[2] - right[2] * forward[1],
                    right[2] * forward[0] - right[0] * forward[2],
                    right[0] * forward[1] - right[1] * forward[0],
                ];
                Camera::Pinhole {
                    centre_m: [pos[0], pos[1], o.height_m],
                    axes: [right, up, forward],
                    focal_px: focal,
                    principal_px: [w / 2.0, h / 2.0],
                }
            }
        })
    }

    /// The same camera with the image shifted by `d` px (camera jitter).
    pub fn shifted(&self, d: [f64; 2]) -> Camera {
        let mut c = self.clone();
        match &mut c {
            Camera::Aerial { shift_px, .. } => {
                shift_px[0] += d[0];
                shift_px[1] += d[1];
            }
            Camera::Pinhole { principal_px, .. } => {
                principal_px[0] += d[0];
                principal_px[1] += d[1];
            }
        }
        c
    }

    /// Camera-space coordinates of ground-frame point `p`.
    pub fn to_camera(&self, p: Vec3) -> CamPoint {
        match self {
            Camera::Aerial {
                metres_per_pixel,
                origin_m,
                rotation_rad,
                shift_px,
            } => {
                let (s, c) = rotation_rad.sin_cos();
                let d = [p[0] - origin_m[0], p[1] - origin_m[1]];
                CamPoint {
                    c: [
                        (d[0] * c + d[1] * s) / metres_per_pixel + shift_px[0],
                        (d[0] * s - d[1] * c) / metres_per_pixel + shift_px[1],
                        -p[2],
                    ],
                }
            }
            Camera::Pinhole { centre_m, axes, .. } => {
                let d = sub(p, *centre_m);
                CamPoint {
                    c: [dot(axes[0], d), dot(axes[1], d), dot(axes[2], d)],
                }
            }
        }
    }

    /// Whether camera-space point `c` may be drawn (in front of the near plane).
    pub fn in_front(&self, c: &CamPoint) -> bool {
        match self {
            Camera::Aerial { .. } => true,
            Camera::Pinhole { .. } => c.c[2] >= NEAR_M,
        }
    }

    /// Image position `(u, v)` and depth key `q` (larger = nearer; affine in the image over
    /// any plane, so it interpolates linearly across a polygon) of camera-space point `c`
    /// (which must be in front).
    pub fn image_of(&self, c: &CamPoint) -> (f64, f64, f64) {
        match self {
            Camera::Aerial { .. } => (c.c[0], c.c[1], 1000.0 - c.c[2]),
            Camera::Pinhole {
                focal_px,
                principal_px,
                ..
            } => {
                let z = c.c[2];
                (
                    principal_px[0] + focal_px * c.c[0] / z,
                    principal_px[1] - focal_px * c.c[1] / z,
                    1.0 / z,
                )
            }
        }
    }

    /// Image position of ground-frame point `p`, `None` behind the near plane.
    pub fn project(&self, p: Vec3) -> Option<(f64, f64)> {
        let c = self.to_camera(p);
        self.in_front(&c).then(|| {
            let (u, v, _) = self.image_of(&c);
            (u, v)
        })
    }

    /// Projects a planar convex polygon, clipped at the near plane: image points with
    /// depth keys. Empty when it is wholly behind.
    pub fn project_polygon(&self, pts: &[Vec3]) -> Vec<(f64, f64, f64)> {
        let cam: Vec<CamPoint> = pts.iter().map(|p| self.to_camera(*p)).collect();
        let clipped = match self {
            Camera::Aerial { .. } => cam,
            Camera::Pinhole { .. } => {
                // Sutherland–Hodgman against z_c = NEAR_M.
                let n = cam.len();
                let mut out = Vec::with_capacity(n + 2);
                for i in 0..n {
                    let a = cam[i];
                    let b = cam[(i + 1) % n];
                    let (ia, ib) = (a.c[2] >= NEAR_M, b.c[2] >= NEAR_M);
                    if ia {
                        out.push(a);
                    }
                    if ia != ib {
                        let t = (NEAR_M - a.c[2]) / (b.c[2] - a.c[2]);
                        out.push(CamPoint {
                            c: [
                                a.c[0] + t * (b.c[0] - a.c[0]),
                                a.c[1] + t * (b.c[1] - a.c[1]),
                                NEAR_M,
                            ],
                        });
                    }
                }
                out
            }
        };
        clipped.iter().map(|c| self.image_of(c)).collect()
    }

    /// Whether a face through `point` with outward `normal` faces the camera.
    pub fn sees_face(&self, point: Vec3, normal: Vec3) -> bool {
        match self {
            Camera::Aerial { .. } => normal[2] > 1e-9,
            Camera::Pinhole { centre_m, .. } => dot(normal, sub(*centre_m, point)) > 1e-9,
        }
    }

    /// Distance-like sort key of a ground-frame point (larger = farther).
    pub fn distance(&self, p: Vec3) -> f64 {
        match self {
            Camera::Aerial { .. } => -p[2],
            Camera::Pinhole { centre_m, .. } => dot(sub(p, *centre_m), sub(p, *centre_m)).sqrt(),
        }
    }

    /// Ground distance from the camera's foot point (0 for the aerial view).
    pub fn ground_distance(&self, x: f64, y: f64) -> f64 {
        match self {
            Camera::Aerial { .. } => 0.0,
            Camera::Pinhole { centre_m, .. } => (x - centre_m[0]).hypot(y - centre_m[1]),
        }
    }

    /// The image ↔ ground calibration of this camera (without jitter).
    ///
    /// # Errors
    /// A degenerate camera (looking exactly along the horizon through its own foot point).
    pub fn calibration(&self) -> Result<Calibration> {
        match self {
            Camera::Aerial {
                metres_per_pixel,
                origin_m,
                rotation_rad,
                ..
            } => Calibration::from_nadir(*metres_per_pixel, *origin_m, rotation_rad.to_degrees()),
            Camera::Pinhole {
                centre_m,
                axes,
                focal_px,
                principal_px,
            } => {
                // Row of x_c (etc.) acting on (x, y, 1) for ground points (z = 0).
                let row = |a: Vec3| [a[0], a[1], -dot(a, *centre_m)];
                let (xr, yr, zr) = (row(axes[0]), row(axes[1]), row(axes[2]));
                let h = [
                    [0, 1, 2].map(|k| focal_px * xr[k] + principal_px[0] * zr[k]),
                    [0, 1, 2].map(|k| -focal_px * yr[k] + principal_px[1] * zr[k]),
                    zr,
                ];
                Calibration::from_homography(h)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SceneKind;
    use roadtrack_core::geometry::Point;

    fn cameras() -> Vec<Camera> {
        let mut out = Vec::new();
        for scene in [
            SceneKind::Road,
            SceneKind::Intersection,
            SceneKind::Crossing,
        ] {
            for view in [ViewKind::Aerial, ViewKind::Oblique] {
                let cfg = SimConfig {
                    scene,
                    view,
                    ..SimConfig::default()
                };
                let s = Scene::build(&cfg, 0.0);
                out.push(Camera::new(&cfg, &s, 640, 480).expect("camera"));
            }
        }
        out
    }

    #[test]
    fn calibration_agrees_with_projection_on_the_ground() -> Result<()> {
        for cam in cameras() {
            let cal = cam.calibration()?;
            for &(u, v) in &[(10.0, 470.0), (320.0, 240.0), (600.0, 400.0)] {
                let (x, y) = cal
                    .ground_from_image(Point::new(u, v))
                    .ok_or(roadtrack_core::Error::Invalid("horizon".into()))?;
                let (pu, pv) = cam
                    .project([x, y, 0.0])
                    .ok_or(roadtrack_core::Error::Invalid("behind".into()))?;
                assert!(
                    (pu - u).abs() < 1e-6 && (pv - v).abs() < 1e-6,
                    "{cam:?}: {u},{v} -> {pu},{pv}"
                );
            }
        }
        Ok(())
    }

    #[test]
    fn pinhole_looks_down_at_the_scene_centre() {
        let cfg = SimConfig {
            scene: SceneKind::Crossing,
            view: ViewKind::Oblique,
            ..SimConfig::default()
        };
        let s = Scene::build(&cfg, 0.0);
        let cam = Camera::new(&cfg, &s, 640, 480).expect("camera");
        let (u, v) = cam.project([0.0, 0.0, 0.0]).expect("in front");
        assert!(
            (0.0..640.0).contains(&u) && (0.0..480.0).contains(&v),
            "{u} {v}"
        );
        // Higher points appear higher in the image.
        let (_, v_top) = cam.project([0.0, 0.0, 2.0]).expect("in front");
        assert!(v_top < v);
    }
}
