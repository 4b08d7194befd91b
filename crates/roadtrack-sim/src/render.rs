//! A small rasteriser: textured ground rendered once per sequence, objects as shaded
//! boxes with a z-buffer, cast shadows, illumination drift and sensor noise per frame.
//!
//! Every object is a few convex hexahedra (body, cabin, cargo box, legs, torso, head) in
//! its own colours. Faces are filled with a per-pixel depth test, so occlusion is exact at
//! pixel level; each pixel also records which object drew it. That gives the ground
//! truth's *visibility*: the fraction of an object's own silhouette pixels (all pixels its
//! faces cover when drawn alone, inside the image) that no nearer object covers.

use super::camera::{Camera, Vec3};
use super::config::{SimConfig, SimRenderConfig};
use super::raster::{convex_hull, fill_convex, polygon_area, share_in_frame};
use super::scene::{Area, Scene, Surface};
use super::traffic::AgentState;
use image::RgbImage;
use rand::Rng as _;
use roadtrack_core::class::ObjectClass;
use roadtrack_core::geometry::{BBox, Point};
use roadtrack_core::rng::{Stream, rng_for};

const NONE: u32 = u32::MAX;

/// What the renderer measured about one object in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectPixels {
    /// Bounding box of the projected object clipped to the image (`None` when it does not
    /// reach the image).
    pub bbox: Option<BBox>,
    /// Silhouette pixels inside the image when drawn alone.
    pub own_px: u32,
    /// Of those, the pixels that show this object in the final frame.
    pub visible_px: u32,
    /// Mean colour of the visible pixels in the final (noisy) frame, 8-bit RGB.
    pub mean_rgb: [f64; 3],
    /// Share of the object's projected outline (the convex hull of its projected corners)
    /// inside the image: 1 in the middle of the frame, under 1 where the frame's edge cuts
    /// it. MOT17's visibility counts such cropping as hidden ([`crate::gt_rows`]).
    pub in_frame: f64,
}

impl ObjectPixels {
    /// `visible_px / own_px` (0 when the object has no pixel in the image).
    pub fn visibility(&self) -> f64 {
        if self.own_px == 0 {
            0.0
        } else {
            f64::from(self.visible_px) / f64::from(self.own_px)
        }
    }
}

/// One planar face of an object: world polygon and its colour.
#[derive(Debug, Clone)]
struct Face {
    points: Vec<Vec3>,
    normal: Vec3,
    rgb: [f32; 3],
}

/// Materials of a box part's faces: top, front, back, sides.
#[derive(Clone, Copy)]
struct Materials {
    top: [u8; 3],
    front: [u8; 3],
    back: [u8; 3],
    sides: [u8; 3],
}

impl Materials {
    fn all(c: [u8; 3]) -> Self {
        Self {
            top: c,
            front: c,
            back: c,
            sides: c,
        }
    }
}

const GLASS: [u8; 3] = [36, 44, 54];
const DARK: [u8; 3] = [26, 26, 28];
const SKIN: [u8; 3] = [196, 156, 126];
const HAIR: [u8; 3] = [34, 28, 24];

/// A box part in the object's frame (x forward, y left, z up): bottom rectangle
/// `[x0, x1] × [−hw0, hw0]` at `z0`, top rectangle `[x2, x3] × [−hw1, hw1]` at `z1`.
#[allow(clippy::too_many_arguments)]
fn part(
    faces: &mut Vec<Face>,
    a: &AgentState,
    bottom: [f64; 3],
    top: [f64; 3],
    z: [f64; 2],
    m: Materials,
) {
    let (s, c) = a.heading_rad.sin_cos();
    let world = |x: f64, y: f64, zz: f64| -> Vec3 {
        [a.pos_m[0] + x * c - y * s, a.pos_m[1] + x * s + y * c, zz]
    };
    let b = [
        world(bottom[0], -bottom[2], z[0]),
        world(bottom[1], -bottom[2], z[0]),
        world(bottom[1], bottom[2], z[0]),
        world(bottom[0], bottom[2], z[0]),
    ];
    let t = [
        world(top[0], -top[2], z[1]),
        world(top[1], -top[2], z[1]),
        world(top[1], top[2], z[1]),
        world(top[0], top[2], z[1]),
    ];
    let mut centre = [0.0; 3];
    for p in b.iter().chain(t.iter()) {
        for k in 0..3 {
            centre[k] += p[k] / 8.0;
        }
    }
    let quads: [([Vec3; 4], [u8; 3]); 6] = [
        ([t[0], t[1], t[2], t[3]], m.top),
        ([b[3], b[2], b[1], b[0]], DARK),
        ([b[1], b[2], t[2], t[1]], m.front),
        ([b[0], t[0], t[3], b[3]], m.back),
        ([b[0], b[1], t[1], t[0]], m.sides),
        ([b[2], b[3], t[3], t[2]], m.sides),
    ];
    for (q, rgb) in quads {
        let e1 = [q[1][0] - q[0][0], q[1][1] - q[0][1], q[1][2] - q[0][2]];
        let e2 = [q[3][0] - q[0][0], q[3][1] - q[0][1], q[3][2] - q[0][2]];
        let mut n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if len < 1e-12 {
            continue;
        }
        n = n.map(|v| v / len);
        let fc = [0, 1, 2].map(|k| q.iter().map(|p| p[k]).sum::<f64>() / 4.0);
        let out = [fc[0] - centre[0], fc[1] - centre[1], fc[2] - centre[2]];
        if n[0] * out[0] + n[1] * out[1] + n[2] * out[2] < 0.0 {
            n = n.map(|v| -v);
        }
        faces.push(Face {
            points: q.to_vec(),
            normal: n,
            rgb: rgb.map(f32::from),
        });
    }
}

/// The faces of an object's model.
fn model(a: &AgentState) -> Vec<Face> {
    let mut f = Vec::with_capacity(24);
    let (l, w, h) = (a.length_m, a.width_m, a.height_m);
    let (hl, hw) = (l / 2.0, w / 2.0);
    let paint = a.colour;
    match a.class {
        ObjectClass::Pedestrian => {
            let d = l / 2.0;
            part(
                &mut f,
                a,
                [-d * 0.8, d * 0.8, hw * 0.6],
                [-d * 0.8, d * 0.8, hw * 0.6],
                [0.0, 0.47 * h],
                Materials::all(a.secondary),
            );
            part(
                &mut f,
                a,
                [-d, d, hw],
                [-d * 0.9, d * 0.9, hw * 0.9],
                [0.47 * h, 0.83 * h],
                Materials::all(paint),
            );
            let head = Materials {
                top: HAIR,
                back: HAIR,
                front: SKIN,
                sides: SKIN,
            };
            part(
                &mut f,
                a,
                [-0.1, 0.1, 0.085],
                [-0.09, 0.08, 0.075],
                [0.83 * h, h],
                head,
            );
        }
        ObjectClass::Motorcycle => {
            part(
                &mut f,
                a,
                [-hl, hl, hw * 0.45],
                [-hl * 0.9, hl * 0.9, hw * 0.4],
                [0.25, 0.9],
                Materials::all([55, 56, 60]),
            );
            part(
                &mut f,
                a,
                [-0.45, 0.05, hw * 0.6],
                [-0.4, 0.0, hw * 0.55],
                [0.9, 0.78 * h],
                Materials::all(paint),
            );
            part(
                &mut f,
                a,
                [-0.3, -0.02, 0.15],
                [-0.28, -0.04, 0.13],
                [0.78 * h, h],
                Materials::all([30, 30, 34]),
            );
        }
        ObjectClass::Truck => {
            let cab = 2.2_f64.min(0.35 * l);
            part(
                &mut f,
                a,
                [-hl * 0.95, hl * 0.95, hw * 0.9],
                [-hl * 0.95, hl * 0.95, hw * 0.9],
                [0.25, 0.95],
                Materials::all(DARK),
            );
            part(
                &mut f,
                a,
                [hl - cab, hl, hw],
                [hl - cab, hl, hw],
                [0.5, 1.7],
                Materials::all(paint),
            );
            let cab_top = Materials {
                top: paint,
                front: GLASS,
                back: paint,
                sides: GLASS,
            };
            part(
                &mut f,
                a,
                [hl - cab, hl, hw],
                [hl - cab, hl - 0.25, hw * 0.96],
                [1.7, 0.85 * h],
                cab_top,
            );
            part(
                &mut f,
                a,
                [-hl, hl - cab - 0.2, hw],
                [-hl, hl - cab - 0.2, hw],
                [0.95, h],
                Materials::all(a.secondary),
            );
        }
        ObjectClass::Bus => {
            part(
                &mut f,
                a,
                [-hl * 0.96, hl * 0.96, hw * 0.92],
                [-hl * 0.96, hl * 0.96, hw * 0.92],
                [0.2, 0.5],
                Materials::all(DARK),
            );
            part(
                &mut f,
                a,
                [-hl, hl, hw],
                [-hl, hl, hw],
                [0.5, 1.55],
                Materials::all(paint),
            );
            let band = Materials {
                top: paint,
                front: GLASS,
                back: GLASS,
                sides: GLASS,
            };
            part(
                &mut f,
                a,
                [-hl, hl, hw],
                [-hl, hl, hw],
                [1.55, h - 0.45],
                band,
            );
            part(
                &mut f,
                a,
                [-hl, hl, hw],
                [-hl + 0.1, hl - 0.1, hw * 0.97],
                [h - 0.45, h],
                Materials::all(paint),
            );
        }
        _ => {
            let body_top = 0.58 * h;
            part(
                &mut f,
                a,
                [-hl * 0.86, hl * 0.86, hw * 0.9],
                [-hl * 0.86, hl * 0.86, hw * 0.9],
                [0.0, 0.32],
                Materials::all(DARK),
            );
            part(
                &mut f,
                a,
                [-hl, hl, hw],
                [-hl * 0.97, hl * 0.96, hw * 0.97],
                [0.32, body_top],
                Materials::all(paint),
            );
            let cabin = Materials {
                top: paint,
                front: GLASS,
                back: GLASS,
                sides: GLASS,
            };
            part(
                &mut f,
                a,
                [-0.34 * l, 0.2 * l, hw * 0.94],
                [-0.24 * l, 0.02 * l, hw * 0.8],
                [body_top, h],
                cabin,
            );
        }
    }
    f
}

/// Smooth value noise in `[0, 1)` at ground point `(x, y)` with cells of `cell` m.
fn value_noise(x: f64, y: f64, cell: f64, salt: u64) -> f64 {
    let (gx, gy) = (x / cell, y / cell);
    let (ix, iy) = (gx.floor(), gy.floor());
    let (fx, fy) = (gx - ix, gy - iy);
    let h = |i: f64, j: f64| -> f64 {
        let mut z = (i as i64 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (j as i64 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ salt;
        z = (z ^ (z >> 31)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 29)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (z >> 11) as f64 / (1u64 << 53) as f64
    };
    let sx = fx * fx * (3.0 - 2.0 * fx);
    let sy = fy * fy * (3.0 - 2.0 * fy);
    let a = h(ix, iy) + (h(ix + 1.0, iy) - h(ix, iy)) * sx;
    let b = h(ix, iy + 1.0) + (h(ix + 1.0, iy + 1.0) - h(ix, iy + 1.0)) * sx;
    a + (b - a) * sy
}

/// Colour of `surface` at ground point `(x, y)`.
fn surface_colour(surface: Surface, x: f64, y: f64, salt: u64) -> [f64; 3] {
    let n1 = value_noise(x, y, 0.3, salt) - 0.5;
    let n2 = value_noise(x, y, 3.0, salt ^ 0x55) - 0.5;
    let n3 = value_noise(x, y, 17.0, salt ^ 0xAA) - 0.5;
    let add = |c: [f64; 3], k: f64| c.map(|v| v + k);
    match surface {
        Surface::Asphalt => add([84.0, 86.0, 90.0], 10.0 * n1 + 8.0 * n2 + 8.0 * n3),
        Surface::Sidewalk => {
            let seam = (x.rem_euclid(0.6) < 0.04) || (y.rem_euclid(0.6) < 0.04);
            let base = [172.0, 164.0, 150.0];
            add(base, if seam { -28.0 } else { 8.0 * n1 + 10.0 * n2 })
        }
        Surface::Kerb => add([196.0, 194.0, 188.0], 6.0 * n1),
        Surface::WhitePaint => add([226.0, 226.0, 220.0], 10.0 * n1 + 10.0 * n2),
        Surface::Verge => add([128.0, 118.0, 96.0], 18.0 * n1 + 10.0 * n2),
        Surface::Grass => {
            let k = 14.0 * n1 + 16.0 * n2 + 18.0 * n3;
            [84.0 + k * 0.8, 112.0 + k, 58.0 + k * 0.5]
        }
        Surface::Lot => {
            let seam = (x.rem_euclid(5.0) < 0.12) || (y.rem_euclid(5.0) < 0.12);
            add(
                [146.0, 144.0, 140.0],
                if seam { -30.0 } else { 6.0 * n1 + 12.0 * n2 },
            )
        }
    }
}

/// Renders frames of one sequence.
#[derive(Debug, Clone)]
pub struct SceneRenderer {
    width: usize,
    height: usize,
    margin: usize,
    /// Background with `margin` px on every side, RGB.
    background: Vec<u8>,
    config: SimRenderConfig,
    seed: u64,
    sun: Vec3,
    qbuf: Vec<f32>,
    owner: Vec<u32>,
    stamp: Vec<u32>,
    shadow: Vec<bool>,
    drift_phase: f64,
}

impl SceneRenderer {
    /// Renders the static background of `scene` seen by `camera` (once per sequence).
    pub fn new(
        scene: &Scene,
        camera: &Camera,
        config: &SimConfig,
        seed: u64,
    ) -> roadtrack_core::Result<Self> {
        let (width, height) = (config.width as usize, config.height as usize);
        let margin = (config.render.camera_jitter_px * 4.0).ceil() as usize;
        let (bw, bh) = (width + 2 * margin, height + 2 * margin);
        let cal = camera.calibration()?;
        let salt = roadtrack_core::rng::rng_for(seed, Stream::Render, u64::MAX).next_u64();
        // Per 16 × 16 tile, the areas whose image bounding box reaches it, in paint order.
        const TILE: usize = 16;
        let (tw, th) = (bw.div_ceil(TILE), bh.div_ceil(TILE));
        let mut tiles: Vec<Vec<&Area>> = vec![Vec::new(); tw * th];
        for area in &scene.areas {
            let pts: Vec<Vec3> = area.polygon.iter().map(|p| [p[0], p[1], 0.0]).collect();
            let img = camera.project_polygon(&pts);
            if img.is_empty() {
                continue;
            }
            let m = margin as f64;
            let u0 = img.iter().map(|p| p.0).fold(f64::INFINITY, f64::min) + m - 1.0;
            let u1 = img.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max) + m + 1.0;
            let v0 = img.iter().map(|p| p.1).fold(f64::INFINITY, f64::min) + m - 1.0;
            let v1 = img.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max) + m + 1.0;
            if u1 < 0.0 || v1 < 0.0 || u0 > bw as f64 || v0 > bh as f64 {
                continue;
            }
            let tx0 = (u0.max(0.0) as usize) / TILE;
            let tx1 = ((u1.min(bw as f64 - 1.0)) as usize) / TILE;
            let ty0 = (v0.max(0.0) as usize) / TILE;
            let ty1 = ((v1.min(bh as f64 - 1.0)) as usize) / TILE;
            for ty in ty0..=ty1.min(th - 1) {
                for tx in tx0..=tx1.min(tw - 1) {
                    tiles[ty * tw + tx].push(area);
                }
            }
        }
        let mut background = vec![0u8; bw * bh * 3];
        const SUB: [f64; 3] = [1.0 / 6.0, 0.5, 5.0 / 6.0];
        for j in 0..bh {
            for i in 0..bw {
                let cands = &tiles[(j / TILE) * tw + i / TILE];
                let mut acc = [0.0; 3];
                let mut sky = 0;
                for sy in SUB {
                    for sx in SUB {
                        let p = Point::new(
                            i as f64 - margin as f64 + sx,
                            j as f64 - margin as f64 + sy,
                        );
                        let Some((x, y)) = cal.ground_from_image(p) else {
                            sky += 1;
                            continue;
                        };
                        let surface = cands
                            .iter()
                            .rev()
                            .find(|a| a.contains([x, y]))
                            .map_or(Surface::Grass, |a| a.surface);
                        let mut c = surface_colour(surface, x, y, salt);
                        let d = camera.ground_distance(x, y);
                        if d > 0.0 {
                            let haze = 1.0 - (-d / 500.0).exp();
                            c = [0, 1, 2]
                                .map(|k| c[k] * (1.0 - haze) + [196.0, 204.0, 212.0][k] * haze);
                        }
                        for k in 0..3 {
                            acc[k] += c[k];
                        }
                    }
                }
                if sky > 0 {
                    let t = (j as f64 / bh as f64).clamp(0.0, 1.0);
                    let sky_rgb = [150.0 + 50.0 * t, 172.0 + 36.0 * t, 205.0 + 10.0 * t];
                    for k in 0..3 {
                        acc[k] += sky_rgb[k] * f64::from(sky);
                    }
                }
                let o = (j * bw + i) * 3;
                for k in 0..3 {
                    background[o + k] = (acc[k] / 9.0).round().clamp(0.0, 255.0) as u8;
                }
            }
        }
        let r = &config.render;
        let (sa, ca) = r.sun_azimuth_deg.to_radians().sin_cos();
        let (se, ce) = r.sun_elevation_deg.to_radians().sin_cos();
        let drift_phase = (salt % 10_000) as f64 / 10_000.0 * std::f64::consts::TAU;
        Ok(Self {
            width,
            height,
            margin,
            background,
            config: r.clone(),
            seed,
            sun: [ce * ca, ce * sa, se],
            qbuf: vec![0.0; width * height],
            owner: vec![NONE; width * height],
            stamp: vec![NONE; width * height],
            shadow: vec![false; width * height],
            drift_phase,
        })
    }

    /// The depth-tested owner of each pixel of the last rendered frame (row-major): the
    /// index of the agent in `render`'s `agents`, `u32::MAX` for background.
    pub fn owner(&self) -> &[u32] {
        &self.owner
    }

    /// Renders one frame of `agents` seen by `camera` (already shifted by `shift_px`, the
    /// integer camera jitter of this frame): the image and, per agent in input order,
    /// what is visible of it.
    pub fn render(
        &mut self,
        camera: &Camera,
        shift_px: [i32; 2],
        agents: &[AgentState],
        frame: u32,
        time_s: f64,
    ) -> (RgbImage, Vec<ObjectPixels>) {
        let (w, h) = (self.width, self.height);
        let mut img = vec![0u8; w * h * 3];
        let bw = w + 2 * self.margin;
        let ox =
            (self.margin as i64 - i64::from(shift_px[0])).clamp(0, 2 * self.margin as i64) as usize;
        let oy =
            (self.margin as i64 - i64::from(shift_px[1])).clamp(0, 2 * self.margin as i64) as usize;
        for j in 0..h {
            let src = ((j + oy) * bw + ox) * 3;
            img[j * w * 3..(j + 1) * w * 3].copy_from_slice(&self.background[src..src + w * 3]);
        }
        self.qbuf.fill(f32::NEG_INFINITY);
        self.owner.fill(NONE);
        self.stamp.fill(NONE);
        let models: Vec<Vec<Face>> = agents.iter().map(model).collect();
        // Shadows: the hull of each footprint and its copy moved along the sun's rays.
        if self.config.shadows && self.sun[2] > 0.0 {
            self.shadow.fill(false);
            let k = 1.0 / self.sun[2];
            for (a, faces) in agents.iter().zip(&models) {
                let mut pts: Vec<[f64; 2]> = Vec::new();
                for f in faces {
                    for p in &f.points {
                        pts.push([p[0] - self.sun[0] * p[2] * k, p[1] - self.sun[1] * p[2] * k]);
                        pts.push([p[0], p[1]]);
                    }
                }
                let _ = a;
                let hull = convex_hull(pts);
                let poly: Vec<Vec3> = hull.iter().map(|p| [p[0], p[1], 0.0]).collect();
                let img_poly = camera.project_polygon(&poly);
                let shadow = &mut self.shadow;
                fill_convex(&img_poly, w, h, |i, _| shadow[i] = true);
            }
            for (i, s) in self.shadow.iter().enumerate() {
                if *s {
                    for k in 0..3 {
                        img[i * 3 + k] = (u16::from(img[i * 3 + k]) * 150 / 256) as u8;
                    }
                }
            }
        }
        let mut stats: Vec<ObjectPixels> = Vec::with_capacity(agents.len());
        for (idx, faces) in models.iter().enumerate() {
            let mut own = 0u32;
            let (mut u0, mut v0, mut u1, mut v1) = (
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            );
            let tag = idx as u32;
            let mut outline: Vec<[f64; 2]> = Vec::new();
            for f in faces {
                let poly = camera.project_polygon(&f.points);
                for p in &poly {
                    outline.push([p.0, p.1]);
                    u0 = u0.min(p.0);
                    u1 = u1.max(p.0);
                    v0 = v0.min(p.1);
                    v1 = v1.max(p.1);
                }
                if !camera.sees_face(f.points[0], f.normal) {
                    continue;
                }
                let rgb = self.shade(f);
                let (qbuf, owner, stamp) = (&mut self.qbuf, &mut self.owner, &mut self.stamp);
                fill_convex(&poly, w, h, |i, q| {
                    if stamp[i] != tag {
                        stamp[i] = tag;
                        own += 1;
                    }
                    if q > qbuf[i] {
                        qbuf[i] = q;
                        owner[i] = tag;
                        img[i * 3..i * 3 + 3].copy_from_slice(&rgb);
                    }
                });
            }
            if own == 0
                && self.config.min_one_pixel
                && let Some(([u, v, q], rgb)) = self.largest_face_centre(camera, faces)
                && (0.0..w as f64).contains(&u)
                && (0.0..h as f64).contains(&v)
            {
                let i = v as usize * w + u as usize;
                own = 1;
                self.stamp[i] = tag;
                if (q as f32) > self.qbuf[i] {
                    self.qbuf[i] = q as f32;
                    self.owner[i] = tag;
                    img[i * 3..i * 3 + 3].copy_from_slice(&rgb);
                }
            }
            let bbox = if u0 <= u1 {
                let (l, t) = (u0.max(0.0), v0.max(0.0));
                let (r, b) = (u1.min(w as f64), v1.min(h as f64));
                (r > l && b > t).then(|| BBox::new(l, t, r - l, b - t))
            } else {
                None
            };
            stats.push(ObjectPixels {
                bbox,
                own_px: own,
                visible_px: 0,
                mean_rgb: [0.0; 3],
                in_frame: share_in_frame(outline, w as f64, h as f64),
            });
        }
        self.expose(&mut img, frame, time_s);
        let mut sums = vec![[0u64; 3]; stats.len()];
        for (i, &o) in self.owner.iter().enumerate() {
            if o != NONE {
                let s = &mut sums[o as usize];
                for k in 0..3 {
                    s[k] += u64::from(img[i * 3 + k]);
                }
                stats[o as usize].visible_px += 1;
            }
        }
        for (s, sum) in stats.iter_mut().zip(sums) {
            if s.visible_px > 0 {
                s.mean_rgb = sum.map(|v| v as f64 / f64::from(s.visible_px));
            }
        }
        let image = RgbImage::from_raw(w as u32, h as u32, img).unwrap_or_default();
        (image, stats)
    }

    /// `f`'s colour under the sun: ambient 0.52 plus 0.48 of the direct light.
    fn shade(&self, f: &Face) -> [u8; 3] {
        let light = 0.52
            + 0.48
                * (f.normal[0] * self.sun[0]
                    + f.normal[1] * self.sun[1]
                    + f.normal[2] * self.sun[2])
                    .max(0.0);
        f.rgb.map(|c| (c * light as f32).min(255.0) as u8)
    }

    /// The centroid (`u, v, q` of its projected corners) and colour of the largest face of
    /// `faces` the camera sees (the first of equals), for an object that covers no pixel
    /// centre (`min_one_pixel`).
    fn largest_face_centre(&self, camera: &Camera, faces: &[Face]) -> Option<([f64; 3], [u8; 3])> {
        let mut largest: Option<(f64, [f64; 3], [u8; 3])> = None;
        for f in faces
            .iter()
            .filter(|f| camera.sees_face(f.points[0], f.normal))
        {
            let poly = camera.project_polygon(&f.points);
            if poly.is_empty() {
                continue;
            }
            let area = polygon_area(&poly.iter().map(|p| [p.0, p.1]).collect::<Vec<_>>());
            if largest.as_ref().is_none_or(|l| area > l.0) {
                let n = poly.len() as f64;
                let c = poly
                    .iter()
                    .fold([0.0; 3], |c, p| [c[0] + p.0, c[1] + p.1, c[2] + p.2]);
                largest = Some((area, c.map(|v| v / n), self.shade(f)));
            }
        }
        largest.map(|(_, c, rgb)| (c, rgb))
    }

    /// Illumination drift and sensor noise, in place.
    fn expose(&self, img: &mut [u8], frame: u32, time_s: f64) {
        let c = &self.config;
        let gain = 1.0
            + c.illumination_drift
                * (std::f64::consts::TAU * time_s / c.illumination_period_s + self.drift_phase)
                    .sin();
        let lut: Vec<i32> = (0..256)
            .map(|v| (f64::from(v) * gain).round() as i32)
            .collect();
        // Sum of four uniform bytes: mean 510, sd 147.8; scaled to `noise_sd` in 1/4096.
        let k = (c.noise_sd / 147.8 * 4096.0).round() as i64;
        let mut state = rng_for(self.seed, Stream::Render, u64::from(frame)).next_u64() | 1;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut chunks = img.chunks_exact_mut(2);
        for pair in &mut chunks {
            let r = next();
            let n0 = ((r & 0xFF) + ((r >> 8) & 0xFF) + ((r >> 16) & 0xFF) + ((r >> 24) & 0xFF))
                as i64
                - 510;
            let r2 = r >> 32;
            let n1 = ((r2 & 0xFF) + ((r2 >> 8) & 0xFF) + ((r2 >> 16) & 0xFF) + ((r2 >> 24) & 0xFF))
                as i64
                - 510;
            pair[0] = (lut[pair[0] as usize] + ((n0 * k) >> 12) as i32).clamp(0, 255) as u8;
            pair[1] = (lut[pair[1] as usize] + ((n1 * k) >> 12) as i32).clamp(0, 255) as u8;
        }
        for v in chunks.into_remainder() {
            *v = lut[*v as usize].clamp(0, 255) as u8;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{SceneKind, ViewKind};

    fn agent(id: u64, class: ObjectClass, pos: [f64; 2], heading: f64) -> AgentState {
        let (l, w, h) = match class {
            ObjectClass::Pedestrian => (0.3, 0.46, 1.7),
            ObjectClass::Bus => (11.0, 2.5, 3.1),
            _ => (4.5, 1.8, 1.45),
        };
        AgentState {
            id,
            class,
            pos_m: pos,
            heading_rad: heading,
            speed_mps: 0.0,
            length_m: l,
            width_m: w,
            height_m: h,
            colour: [200, 30, 30],
            secondary: [20, 20, 20],
        }
    }

    fn setup(view: ViewKind) -> (SceneRenderer, Camera) {
        let cfg = SimConfig {
            scene: SceneKind::Crossing,
            view,
            ..SimConfig::default()
        };
        let scene = Scene::build(&cfg, 0.0);
        let cam = Camera::new(&cfg, &scene, cfg.width, cfg.height).expect("camera");
        (
            SceneRenderer::new(&scene, &cam, &cfg, 1).expect("renderer"),
            cam,
        )
    }

    #[test]
    fn isolated_object_is_fully_visible_and_occluded_one_is_not() {
        let (mut r, cam) = setup(ViewKind::Oblique);
        let ped = agent(1, ObjectClass::Pedestrian, [2.0, 2.0], 0.0);
        let (_, stats) = r.render(&cam, [0, 0], std::slice::from_ref(&ped), 1, 0.0);
        assert!(
            stats[0].own_px > 50,
            "pedestrian too small: {}",
            stats[0].own_px
        );
        assert_eq!(stats[0].visibility(), 1.0);
        // A bus between the camera and the pedestrian hides part of it.
        let cpos = match &cam {
            Camera::Pinhole { centre_m, .. } => *centre_m,
            Camera::Aerial { .. } => unreachable!("oblique camera"),
        };
        let t = 0.6;
        let mid = [cpos[0] + (2.0 - cpos[0]) * t, cpos[1] + (2.0 - cpos[1]) * t];
        let bus = agent(2, ObjectClass::Bus, mid, 0.0);
        let (_, stats) = r.render(&cam, [0, 0], &[ped.clone(), bus], 1, 0.0);
        assert!(stats[0].visibility() < 1.0, "{:?}", stats[0]);
        assert_eq!(stats[1].visibility(), 1.0);
        // Alone again: back to 1, whatever the order of drawing.
        let (_, stats) = r.render(&cam, [0, 0], &[ped], 1, 0.0);
        assert_eq!(stats[0].visibility(), 1.0);
    }

    /// `min_one_pixel`: a walker seen from above (under a pixel wide) moved over a pixel
    /// in steps of 0.1 px covers no pixel centre at some steps when point-sampled, and
    /// then vanishes; with the rule it keeps exactly one pixel there, the pixel under its
    /// centre, in the walker's colour, and is wholly visible.
    #[test]
    fn a_walker_under_a_pixel_wide_keeps_one_pixel() {
        let (mut r, cam) = setup(ViewKind::Aerial);
        let metres_per_px = {
            let (a, _) = cam.project([0.0, 0.0, 0.0]).expect("in view");
            let (b, _) = cam.project([1.0, 0.0, 0.0]).expect("in view");
            1.0 / (b - a).abs()
        };
        let (mut vanished, mut kept) = (0, 0);
        for k in 0..100 {
            let x = 0.1 * f64::from(k % 10) * metres_per_px;
            let y = 0.1 * f64::from(k / 10) * metres_per_px;
            // Heading π/2: the walker's 0.3 m length along y, its 0.46 m width along x.
            let ped = agent(
                1,
                ObjectClass::Pedestrian,
                [x, y],
                std::f64::consts::FRAC_PI_2,
            );
            r.config.min_one_pixel = false;
            let (_, before) = r.render(&cam, [0, 0], std::slice::from_ref(&ped), 1, 0.0);
            r.config.min_one_pixel = true;
            let (img, after) = r.render(&cam, [0, 0], std::slice::from_ref(&ped), 1, 0.0);
            if before[0].own_px == 0 {
                vanished += 1;
                assert_eq!(after[0].own_px, 1, "x = {x}");
                assert_eq!(after[0].visibility(), 1.0);
                let (u, v) = cam.project([x, y, 0.0]).expect("in view");
                let i = v as usize * r.width + u as usize;
                assert_eq!(r.owner()[i], 0, "x = {x}: the pixel under the walker");
                let px = img.get_pixel(u as u32, v as u32);
                assert!(
                    px[0] > px[1] + 40,
                    "x = {x}: {px:?} is not the walker's red"
                );
            } else {
                kept += 1;
                assert_eq!(
                    after[0], before[0],
                    "x = {x}: a walker with pixels is unchanged"
                );
            }
        }
        assert!(vanished > 0 && kept > 0, "{vanished} vanished, {kept} kept");
    }

    #[test]
    fn aerial_box_is_centred_on_the_projected_position() {
        let (mut r, cam) = setup(ViewKind::Aerial);
        let car = agent(1, ObjectClass::Car, [3.0, -1.75], 0.4);
        let (_, stats) = r.render(&cam, [0, 0], std::slice::from_ref(&car), 1, 0.0);
        let b = stats[0].bbox.expect("in view");
        let (u, v) = cam.project([3.0, -1.75, 0.0]).expect("in view");
        assert!((b.centre().x - u).abs() < 1e-6 && (b.centre().y - v).abs() < 1e-6);
    }
}
