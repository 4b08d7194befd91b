//! Training data from the simulator (the label source): randomised scenes rendered in
//! process, photometric corruption of whole frames, and random crops with their
//! centre-point targets.
//!
//! Every episode draws a [`SimConfig`] from its own seed ([`random_sim_config`]): scene,
//! view, aerial scale and rotation, oblique camera height, tilt, yaw and focal length,
//! vehicle colours, traffic and pedestrian density, sensor noise, shadows and sun. The
//! rendered frames are then darkened or brightened per channel, blurred and JPEG-compressed
//! at a random quality ([`corrupt`]); each training sample is a crop at a random scale,
//! mirrored half of the time ([`make_sample`]).

use crate::arch::{CLASSES, Preprocessing, STRIDE, class_channel};
use image::RgbImage;
use rand::RngExt;
use roadtrack::error::Result;
use roadtrack::geometry::BBox;
use roadtrack_sim::config::FleetColour;
use roadtrack_sim::{SceneKind, SimConfig, Simulation, ViewKind};

/// One labelled object of a training frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Object {
    /// Box in frame px.
    pub bbox: BBox,
    /// Heat-map channel.
    pub channel: usize,
    /// Fraction of the silhouette not hidden by nearer objects.
    pub visibility: f64,
}

/// A rendered, corrupted frame and its objects.
#[derive(Debug, Clone)]
pub struct TrainFrame {
    /// The image.
    pub image: RgbImage,
    /// The objects with at least one visible pixel.
    pub objects: Vec<Object>,
}

/// What the episodes draw from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DataConfig {
    /// Rendered frame width, px.
    pub width: u32,
    /// Rendered frame height, px.
    pub height: u32,
    /// Frames rendered per episode (one simulation).
    pub frames_per_episode: u32,
    /// Crop side, px (a multiple of 16).
    pub crop: usize,
    /// Objects less visible than this are neither positives nor negatives (their
    /// surroundings are left out of the loss).
    pub min_visibility: f64,
    /// Crop scale, frame px per crop px, of the ordinary crops (uniform in the range).
    pub scale_range: (f64, f64),
    /// Share of crops zoomed out further, log-uniform in `(scale_range.1, zoom_out_max)`
    /// and area-sampled, so that vehicles near an oblique camera (100–300 px) are seen whole
    /// and the detector's coarse pyramid level (`roadtrack_cnn::centernet`) finds them.
    pub zoom_out_share: f64,
    /// Largest zoom-out scale.
    pub zoom_out_max: f64,
    /// Clip each object's box to the crop and place its centre target at the clipped box's
    /// centre, as the ground truth clips boxes to the frame (`roadtrack_sim`'s render). Off
    /// (the recipe's): a box keeps its whole extent, and an object whose centre falls
    /// outside the crop is left out (a negative where its visible part lies).
    pub clip_to_crop: bool,
    /// With [`DataConfig::clip_to_crop`]: an object with less than this fraction of its
    /// box inside the crop is neither a positive nor a negative.
    pub min_in_crop: f64,
    /// Share of crops placed so that one of their edges cuts a random object of at least
    /// [`DataConfig::edge_crop_min_px`] (crop px) across its box, leaving 40–90 % of it
    /// inside: the view of a vehicle leaving the frame, which ordinary crops rarely give.
    /// Meant with [`DataConfig::clip_to_crop`] (the target is then the clipped box, as the
    /// ground truth's at the frame's edge). Default 0 (the recipe's).
    pub edge_crop_share: f64,
    /// See [`DataConfig::edge_crop_share`]: the cut object's box side across the cut, crop
    /// px. Default 16.
    pub edge_crop_min_px: f64,
    /// Weight of each class's box targets (car, bus/truck, bicycle/motorcycle, pedestrian:
    /// the heat-map channels) in the box loss. Default all 1 (the recipe's).
    pub box_class_weights: [f32; CLASSES],
    /// Share of the simulated vehicles that are motorcycles, in `[0, 1)`: the episode's
    /// motorcycle share is set so that it is this fraction of the car, lorry, bus and
    /// motorcycle shares together. `None` (the recipe's): the simulator's 0.08.
    pub motorcycle_share: Option<f64>,
    /// Share of the simulated vehicles that are lorries or buses, in `[0, 1)`, their own
    /// ratio kept: the episode's lorry and bus shares are scaled so that together they are
    /// this fraction of all vehicles. `None` (the recipe's): the simulator's 0.12.
    pub heavy_share: Option<f64>,
}

impl Default for DataConfig {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            frames_per_episode: 6,
            crop: 128,
            min_visibility: 0.25,
            scale_range: (0.7, 1.4),
            // Choice: a third of the crops at 1.4–3.2 frame px per crop px. With only
            // 0.7–1.4 an oblique car 150 px long never fits a 128 px crop whole, and the
            // network learned to put small boxes on its parts (docs/EXPERIMENTS.md).
            zoom_out_share: 1.0 / 3.0,
            zoom_out_max: 3.2,
            // Choice: off. A fifth stage with it, from the shipped model, found no more of
            // the vehicles cut by the frame edge and fewer oblique vehicles overall
            // (docs/EXPERIMENTS.md "Boxes clipped to the crop").
            clip_to_crop: false,
            min_in_crop: 0.25,
            // Choice: off. A stage with 30 % edge crops (and clipped boxes), from the
            // shipped model, found fewer of the vehicles cut by the frame's edge, not more
            // (docs/EXPERIMENTS.md "Edge crops").
            edge_crop_share: 0.0,
            edge_crop_min_px: 16.0,
            // Choice: every class alike. Lorries, buses and motorcycles are a few percent
            // of the objects, and seen from above their boxes took a car's shape
            // (docs/EXPERIMENTS.md "Box errors by class").
            box_class_weights: [1.0; CLASSES],
            // Choice: the simulator's mix. A fine-tune at 0.3 found no more motorcycles and
            // fewer cars (docs/EXPERIMENTS.md "More motorcycles in training").
            motorcycle_share: None,
            // Choice: the simulator's mix (docs/EXPERIMENTS.md "More lorries and buses in
            // training").
            heavy_share: None,
        }
    }
}

impl DataConfig {
    /// The defaults with the vehicle mix read through `var` from `MOTORCYCLE_SHARE` and
    /// `HEAVY_SHARE` ([`DataConfig::motorcycle_share`], [`DataConfig::heavy_share`]; unset:
    /// the simulator's mix), checked as the trainer checks them
    /// ([`TrainConfig::validate`](crate::train::TrainConfig::validate)). The GPU stage's
    /// sample workers (`examples/dump_samples.rs`) take their mix so.
    ///
    /// # Errors
    /// A value that is not a number, or a share the trainer refuses; the message names the
    /// variable or field.
    pub fn with_mix_from(var: impl Fn(&str) -> Option<String>) -> Result<Self> {
        let share = |name: &str| -> Result<Option<f64>> {
            var(name)
                .map(|v| {
                    v.trim().parse::<f64>().map_err(|e| {
                        roadtrack::error::Error::Invalid(format!(
                            "{name}: `{v}` is not a number ({e})"
                        ))
                    })
                })
                .transpose()
        };
        let data = Self {
            motorcycle_share: share("MOTORCYCLE_SHARE")?,
            heavy_share: share("HEAVY_SHARE")?,
            ..Self::default()
        };
        crate::train::TrainConfig {
            data,
            ..Default::default()
        }
        .validate()?;
        Ok(data)
    }
}

fn scale(rng: &mut impl rand::Rng, lo: f64, hi: f64) -> f64 {
    rng.random_range(lo..hi)
}

/// A random simulator configuration for one episode (see the module docs).
pub fn random_sim_config(rng: &mut impl rand::Rng, data: &DataConfig) -> SimConfig {
    let mut c = SimConfig {
        width: data.width,
        height: data.height,
        frames: data.frames_per_episode,
        ..SimConfig::default()
    };
    c.scene = match rng.random_range(0..3) {
        0 => SceneKind::Road,
        1 => SceneKind::Intersection,
        _ => SceneKind::Crossing,
    };
    c.view = if rng.random_bool(0.5) {
        ViewKind::Aerial
    } else {
        ViewKind::Oblique
    };
    // Frames 0.5–2 s apart: different traffic in each.
    c.fps = scale(rng, 0.5, 2.0);
    c.warmup_s = scale(rng, 20.0, 150.0);
    c.aerial.metres_per_pixel = scale(rng, 0.2, 0.45);
    c.aerial.rotation_deg = if rng.random_bool(0.5) {
        f64::from(rng.random_range(0..4) * 90)
    } else {
        scale(rng, 0.0, 360.0)
    };
    let (yaw, tilt) = match c.scene {
        SceneKind::Road => (18.0, 13.0),
        SceneKind::Intersection => (38.0, 20.0),
        SceneKind::Crossing => (62.0, 26.0),
    };
    c.oblique.height_m = scale(rng, 5.0, 14.0);
    c.oblique.yaw_deg = Some(yaw + scale(rng, -15.0, 15.0));
    c.oblique.tilt_deg = Some(tilt + scale(rng, -5.0, 12.0));
    c.oblique.focal_px = Some(f64::from(data.width) * scale(rng, 0.55, 1.3));
    let density = scale(rng, 0.5, 2.5);
    c.road.inflow_veh_per_h *= density;
    c.intersection.inflow_veh_per_h_per_approach *= density;
    c.crossing.inflow_veh_per_h_per_direction *= density;
    let walkers = scale(rng, 0.5, 3.0);
    c.intersection.pedestrian_groups_per_min_per_entry *= walkers;
    c.crossing.pedestrian_groups_per_min_per_entry *= walkers;
    if rng.random_bool(0.5) {
        c.vehicles.colours = (0..9)
            .map(|i| FleetColour {
                name: format!("c{i}"),
                share: scale(rng, 0.05, 1.0),
                rgb: [rng.random(), rng.random(), rng.random()],
            })
            .collect();
    }
    set_vehicle_mix(&mut c.vehicles, data.motorcycle_share, data.heavy_share);
    c.render.noise_sd = scale(rng, 0.0, 8.0);
    c.render.shadows = rng.random_bool(0.8);
    c.render.sun_azimuth_deg = scale(rng, 0.0, 360.0);
    c.render.sun_elevation_deg = scale(rng, 25.0, 80.0);
    // Choice: point-sampled frames, as every shipped model was trained on, so that
    // `scripts/setup.sh --models` trains models/detector.onnx on the same frames.
    // Walkers under a pixel then vanish from some training frames and their labels alike
    // (docs/SIMULATOR.md "Objects under a pixel"); a model trained with the rule is a
    // retrain of its own.
    c.render.min_one_pixel = false;
    c
}

/// Scales the motorcycle and the lorry + bus shares of `v` so that each given one is that
/// fraction of all vehicles; cars (and a class whose share is not given) keep theirs.
fn set_vehicle_mix(
    v: &mut roadtrack_sim::VehicleConfig,
    motorcycle: Option<f64>,
    heavy: Option<f64>,
) {
    let heavy0 = v.truck.share + v.bus.share;
    // The new total of the shares, from the classes that keep theirs.
    let total = match (motorcycle, heavy) {
        (None, None) => return,
        (Some(m), None) => {
            // As before the lorry share existed, to the last bit: the motorcycle fine-tune
            // of docs/EXPERIMENTS.md reruns the same episodes.
            let others = v.car.share + v.truck.share + v.bus.share;
            v.motorcycle.share = others * m / (1.0 - m);
            return;
        }
        (None, Some(h)) => (v.car.share + v.motorcycle.share) / (1.0 - h),
        (Some(m), Some(h)) => v.car.share / (1.0 - m - h),
    };
    if let Some(m) = motorcycle {
        v.motorcycle.share = m * total;
    }
    if let Some(h) = heavy
        && heavy0 > 0.0
    {
        let k = h * total / heavy0;
        v.truck.share *= k;
        v.bus.share *= k;
    }
}

/// Per-channel gain and offset, a light blur and a JPEG round trip at a random quality.
pub fn corrupt(image: &mut RgbImage, rng: &mut impl rand::Rng) -> Result<()> {
    let gain = scale(rng, 0.6, 1.3);
    let g: [f64; 3] = std::array::from_fn(|_| gain * scale(rng, 0.9, 1.1));
    let offset = scale(rng, -20.0, 20.0);
    for p in image.pixels_mut() {
        for (v, gc) in p.0.iter_mut().zip(g) {
            *v = (f64::from(*v) * gc + offset).round().clamp(0.0, 255.0) as u8;
        }
    }
    if rng.random_bool(0.3) {
        *image = blur121(image);
    }
    if rng.random_bool(0.7) {
        let quality = rng.random_range(25..=95u8);
        let mut bytes = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, quality)
            .encode_image(image)
            .map_err(|e| roadtrack::Error::Invalid(format!("JPEG encoding: {e}")))?;
        *image = image::load_from_memory_with_format(&bytes, image::ImageFormat::Jpeg)
            .map_err(|e| roadtrack::Error::Invalid(format!("JPEG decoding: {e}")))?
            .to_rgb8();
    }
    Ok(())
}

/// The separable `[1, 2, 1] / 4` blur, edges replicated.
fn blur121(image: &RgbImage) -> RgbImage {
    let (w, h) = image.dimensions();
    let pass = |src: &RgbImage, dx: i64, dy: i64| {
        RgbImage::from_fn(w, h, |x, y| {
            let at = |k: i64| {
                let xx = (i64::from(x) + k * dx).clamp(0, i64::from(w) - 1) as u32;
                let yy = (i64::from(y) + k * dy).clamp(0, i64::from(h) - 1) as u32;
                src.get_pixel(xx, yy).0
            };
            let (a, b, c) = (at(-1), at(0), at(1));
            image::Rgb(std::array::from_fn(|i| {
                ((u16::from(a[i]) + 2 * u16::from(b[i]) + u16::from(c[i]) + 2) / 4) as u8
            }))
        })
    };
    pass(&pass(image, 1, 0), 0, 1)
}

/// Renders one episode: a simulation of [`random_sim_config`] with seed `sim_seed`, each
/// frame corrupted ([`corrupt`]).
///
/// # Errors
/// The simulator rejects the configuration (should not happen) or JPEG coding fails.
pub fn render_episode(
    sim_seed: u64,
    rng: &mut impl rand::Rng,
    data: &DataConfig,
) -> Result<Vec<TrainFrame>> {
    let config = random_sim_config(rng, data);
    let sim = Simulation::new(&config, sim_seed)?;
    let mut frames = Vec::new();
    for step in sim {
        let step = step?;
        let mut image = step.frame.image;
        corrupt(&mut image, rng)?;
        let objects = step
            .truth
            .iter()
            .filter_map(|t| {
                Some(Object {
                    bbox: t.bbox,
                    channel: class_channel(&t.class)?,
                    visibility: t.visibility,
                })
            })
            .collect();
        frames.push(TrainFrame { image, objects });
    }
    Ok(frames)
}

/// One training sample: the preprocessed crop and its targets on the `G × G` output grid
/// (`G = crop / 4`).
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// `3 × S × S` network input.
    pub input: Vec<f32>,
    /// `4 × G × G`: 1 at object centres (positives of the focal loss).
    pub pos: Vec<f32>,
    /// `4 × G × G`: the negatives' focal-loss weight `(1 − y)⁴` (0 at centres and near
    /// barely visible objects).
    pub neg_weight: Vec<f32>,
    /// `4 × G × G`: `ln(w/4)`, `ln(h/4)`, `dx`, `dy` at centres.
    pub reg: Vec<f32>,
    /// `4 × G × G`: 1 at centres (all four planes).
    pub reg_mask: Vec<f32>,
    /// Number of centres.
    pub n_pos: usize,
}

/// `bbox` (frame px) in crop px: `(centre x, centre y, w, h, fraction inside the crop)`, the
/// crop's left top at `(x0, y0)` in the frame, `sc` frame px per crop px, side `side`,
/// mirrored when `flip`; `None` when the object is not in the crop (see
/// [`DataConfig::clip_to_crop`]).
pub(crate) fn crop_box(
    bbox: &BBox,
    x0: f64,
    y0: f64,
    sc: f64,
    side: f64,
    flip: bool,
    data: &DataConfig,
) -> Option<(f64, f64, f64, f64, f64)> {
    if !data.clip_to_crop {
        // The recipe's first stages: the same arithmetic, so they stay byte-reproducible.
        let c = bbox.centre();
        let mut ox = (c.x - x0) / sc;
        let oy = (c.y - y0) / sc;
        if flip {
            ox = side - ox;
        }
        let inside = (0.0..side).contains(&ox) && (0.0..side).contains(&oy);
        let (w, h) = ((bbox.width / sc).max(1.0), (bbox.height / sc).max(1.0));
        return inside.then_some((ox, oy, w, h, 1.0));
    }
    let (mut l, t) = ((bbox.left - x0) / sc, (bbox.top - y0) / sc);
    let (mut r, b) = (l + bbox.width / sc, t + bbox.height / sc);
    if flip {
        (l, r) = (side - r, side - l);
    }
    let (cl, ct, cr, cb) = (l.max(0.0), t.max(0.0), r.min(side), b.min(side));
    if cr <= cl || cb <= ct {
        return None;
    }
    let area = (r - l) * (b - t);
    let frac = if area > 0.0 {
        (cr - cl) * (cb - ct) / area
    } else {
        1.0
    };
    // The clipped centre lies in [0, side]; the grid cell of `side` itself is dropped by
    // the caller's bounds check, as before.
    Some((
        (cl + cr) / 2.0,
        (ct + cb) / 2.0,
        (cr - cl).max(1.0),
        (cb - ct).max(1.0),
        frac,
    ))
}

/// The centre of an edge crop ([`DataConfig::edge_crop_share`]) of side `span` (frame px,
/// `sc` frame px per crop px): one of `usable`'s objects large enough, a random side of the
/// crop through its box, 40–90 % of the box inside and the rest of it whole where it fits;
/// `None` when no object is large enough.
fn edge_crop(
    usable: &[&Object],
    rng: &mut impl rand::Rng,
    data: &DataConfig,
    sc: f64,
    span: f64,
) -> Option<(f64, f64)> {
    let side = rng.random_range(0..4u8);
    let horizontal = side < 2;
    let big: Vec<&&Object> = usable
        .iter()
        .filter(|o| {
            let across = if horizontal {
                o.bbox.width
            } else {
                o.bbox.height
            };
            across / sc >= data.edge_crop_min_px
        })
        .collect();
    if big.is_empty() {
        return None;
    }
    let b = &big[rng.random_range(0..big.len())].bbox;
    let inside = scale(rng, 0.4, 0.9);
    // Along the cut, the whole box inside the crop where it fits (one edge cuts it, not a
    // corner), else centred.
    let half = 0.5 * if horizontal { b.height } else { b.width } / span;
    let along = if half < 0.5 {
        scale(rng, half, 1.0 - half)
    } else {
        0.5
    };
    let c = b.centre();
    Some(match side {
        // The crop's left edge through the box: its right part inside.
        0 => (
            b.left + (1.0 - inside) * b.width + span / 2.0,
            c.y + (along - 0.5) * span,
        ),
        // The right edge: its left part inside.
        1 => (
            b.left + inside * b.width - span / 2.0,
            c.y + (along - 0.5) * span,
        ),
        // The top edge: its lower part inside.
        2 => (
            c.x + (along - 0.5) * span,
            b.top + (1.0 - inside) * b.height + span / 2.0,
        ),
        _ => (
            c.x + (along - 0.5) * span,
            b.top + inside * b.height - span / 2.0,
        ),
    })
}

/// A crop of `frame` at a random place (near a random object 70 % of the time) and scale
/// (0.7–1.4 frame px per crop px), mirrored half of the time, with its targets.
pub fn make_sample(
    frame: &TrainFrame,
    rng: &mut impl rand::Rng,
    data: &DataConfig,
    prep: &Preprocessing,
) -> Sample {
    let s = data.crop;
    let g = s / STRIDE;
    let (fw, fh) = (
        f64::from(frame.image.width()),
        f64::from(frame.image.height()),
    );
    let sc = if data.zoom_out_share > 0.0 && rng.random_bool(data.zoom_out_share.min(1.0)) {
        scale(rng, data.scale_range.1.ln(), data.zoom_out_max.ln()).exp()
    } else {
        scale(rng, data.scale_range.0, data.scale_range.1)
    };
    // Choice: zoomed-out crops average a k × k grid of bilinear samples over each crop
    // pixel's footprint (k = ⌈scale⌉ − 1, so 1 up to 2 px per crop px), as the detector's
    // area-averaged pyramid level does; plain bilinear sampling would alias.
    let taps = (sc.ceil() as usize).saturating_sub(1).max(1);
    let span = s as f64 * sc;
    let usable: Vec<&Object> = frame
        .objects
        .iter()
        .filter(|o| o.visibility >= data.min_visibility)
        .collect();
    // Choice: the edge crops draw only when asked for, so the recipe's stages, which do not
    // use them, keep their random streams (and outputs) byte for byte.
    let edge = if data.edge_crop_share > 0.0 && rng.random_bool(data.edge_crop_share.min(1.0)) {
        edge_crop(&usable, rng, data, sc, span)
    } else {
        None
    };
    let (cx, cy) = if let Some(c) = edge {
        c
    } else if !usable.is_empty() && rng.random_bool(0.7) {
        let o = usable[rng.random_range(0..usable.len())];
        let c = o.bbox.centre();
        (
            c.x + scale(rng, -0.4, 0.4) * span,
            c.y + scale(rng, -0.4, 0.4) * span,
        )
    } else {
        (scale(rng, 0.0, fw.max(1.0)), scale(rng, 0.0, fh.max(1.0)))
    };
    let x0 = (cx - span / 2.0).clamp(0.0, (fw - span).max(0.0));
    let y0 = (cy - span / 2.0).clamp(0.0, (fh - span).max(0.0));
    let flip = rng.random_bool(0.5);

    // Bilinear resampling, pixel centres aligned; outside the frame: edge replicated.
    let mut input = vec![0.0f32; 3 * s * s];
    let gain: [f32; 3] = std::array::from_fn(|c| prep.input_scale / prep.std[c]);
    let off: [f32; 3] = std::array::from_fn(|c| -prep.mean[c] / prep.std[c]);
    let (iw, ih) = (frame.image.width() as i64, frame.image.height() as i64);
    let bilinear = |fx: f64, fy: f64| -> [f64; 3] {
        let (y_a, ty) = (fy.floor(), fy - fy.floor());
        let ya = (y_a as i64).clamp(0, ih - 1) as u32;
        let yb = (y_a as i64 + 1).clamp(0, ih - 1) as u32;
        let (x_a, tx) = (fx.floor(), fx - fx.floor());
        let xa = (x_a as i64).clamp(0, iw - 1) as u32;
        let xb = (x_a as i64 + 1).clamp(0, iw - 1) as u32;
        let p00 = frame.image.get_pixel(xa, ya).0;
        let p01 = frame.image.get_pixel(xb, ya).0;
        let p10 = frame.image.get_pixel(xa, yb).0;
        let p11 = frame.image.get_pixel(xb, yb).0;
        std::array::from_fn(|c| {
            let top = f64::from(p00[c]) * (1.0 - tx) + f64::from(p01[c]) * tx;
            let bot = f64::from(p10[c]) * (1.0 - tx) + f64::from(p11[c]) * tx;
            top * (1.0 - ty) + bot * ty
        })
    };
    let inv_taps = 1.0 / (taps * taps) as f64;
    for v in 0..s {
        for u in 0..s {
            let uu = if flip { s - 1 - u } else { u };
            let mut acc = [0.0f64; 3];
            for ty in 0..taps {
                let fy = y0 + (v as f64 + (ty as f64 + 0.5) / taps as f64) * sc - 0.5;
                for tx in 0..taps {
                    let fx = x0 + (uu as f64 + (tx as f64 + 0.5) / taps as f64) * sc - 0.5;
                    let p = bilinear(fx, fy);
                    for c in 0..3 {
                        acc[c] += p[c];
                    }
                }
            }
            for c in 0..3 {
                input[c * s * s + v * s + u] = gain[c] * (acc[c] * inv_taps) as f32 + off[c];
            }
        }
    }

    let plane = g * g;
    let mut heat = vec![0.0f32; CLASSES * plane];
    let mut ignore = vec![1.0f32; plane];
    let mut pos = vec![0.0f32; CLASSES * plane];
    let mut reg = vec![0.0f32; 4 * plane];
    let mut reg_mask = vec![0.0f32; 4 * plane];
    let st = STRIDE as f64;
    // Larger objects first, so a small object sharing a centre cell keeps its box targets.
    let mut objs: Vec<&Object> = frame.objects.iter().collect();
    objs.sort_by(|a, b| (b.bbox.width * b.bbox.height).total_cmp(&(a.bbox.width * a.bbox.height)));
    for o in objs {
        let Some((ox, oy, w, h, in_crop)) = crop_box(&o.bbox, x0, y0, sc, s as f64, flip, data)
        else {
            continue;
        };
        let (gx, gy) = (ox / st, oy / st);
        let (ix, iy) = (gx.floor() as usize, gy.floor() as usize);
        if ix >= g || iy >= g {
            continue;
        }
        // TTFNet's elliptical Gaussian: σ = 0.54 · size / 6 (cells), at least 0.5.
        let sx = (0.54 * w / st / 6.0).max(0.5);
        let sy = (0.54 * h / st / 6.0).max(0.5);
        let rx = (3.0 * sx).ceil() as i64;
        let ry = (3.0 * sy).ceil() as i64;
        let visible = o.visibility >= data.min_visibility && in_crop >= data.min_in_crop;
        for dy in -ry..=ry {
            for dx in -rx..=rx {
                let (x, y) = (ix as i64 + dx, iy as i64 + dy);
                if x < 0 || y < 0 || x >= g as i64 || y >= g as i64 {
                    continue;
                }
                let i = y as usize * g + x as usize;
                if visible {
                    let e = (-(dx * dx) as f64 / (2.0 * sx * sx)
                        - (dy * dy) as f64 / (2.0 * sy * sy))
                        .exp() as f32;
                    let k = o.channel * plane + i;
                    heat[k] = heat[k].max(e);
                } else {
                    ignore[i] = 0.0;
                }
            }
        }
        if visible {
            let i = iy * g + ix;
            pos[o.channel * plane + i] = 1.0;
            let t = [(w / st).ln(), (h / st).ln(), gx - ix as f64, gy - iy as f64];
            for (j, v) in t.iter().enumerate() {
                reg[j * plane + i] = *v as f32;
                reg_mask[j * plane + i] = data.box_class_weights[o.channel];
            }
        }
    }
    let mut neg_weight = vec![0.0f32; CLASSES * plane];
    for k in 0..CLASSES {
        for (i, keep) in ignore.iter().enumerate() {
            let j = k * plane + i;
            if pos[j] == 0.0 {
                neg_weight[j] = (1.0 - heat[j]).powi(4) * keep;
            }
        }
    }
    let n_pos = pos.iter().filter(|&&v| v > 0.0).count();
    Sample {
        input,
        pos,
        neg_weight,
        reg,
        reg_mask,
        n_pos,
    }
}
