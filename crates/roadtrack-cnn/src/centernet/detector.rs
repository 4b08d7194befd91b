//! [`CenterNetDetector`]: the learned detector (roadtrack's kernels or tract), as a roadtrack
//! [`Detector`] and as a dense score map for the filters' likelihood.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use image::RgbImage;
use tract_onnx::prelude::*;

use super::config::{CenterNetConfig, ZoomMode, box_factor};
use super::native::{Isa, NativeNet};
use super::views::{
    add_zoomed, average_flipped, decode_peaks, drop_nested, drop_second_peaks, flat, flip_input,
    merge_levels, replace_small, score_map_of, shrink, zoom_rows,
};
use super::{CLASSES, INPUT_MULTIPLE, KIND, STRIDE, channel_class};
use crate::detector::decode::{Candidate, nms};
use crate::onnx::{
    metadata, model_error, preprocessing_from_metadata, read_image_model, tract_load,
};
use crate::window::Preprocessing;
use roadtrack::calibration::Calibration;
use roadtrack::class::ObjectClass;
use roadtrack::detect::FrameDetections;
use roadtrack::detection::Detection;
use roadtrack::error::{Error, Result};
use roadtrack::frame::Frame;
use roadtrack::geometry::BBox;
use roadtrack::likelihood::{DenseScorer, ScoreMap};

/// The shipped model's path: `models/detector.onnx` of the current directory, or of the
/// nearest of its parents that has one, else of the repository roadtrack was built from.
// Choice: the working directory and its parents first, so a clone's own model wins over
// the build tree's. Parents: tests run in their crate's folder, and a build folder shared
// by two checkouts of the repository compiles in the other checkout's path (cargo keeps a
// crate built in one checkout as fresh in the other), which may be gone.
pub fn default_model_path() -> PathBuf {
    let built = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/detector.onnx");
    let here = std::env::current_dir().unwrap_or_default();
    model_path_from(&here, &built)
}

/// [`default_model_path`] from the folder `here` and the build tree's model `built`: the
/// relative `models/detector.onnx` when `here` holds it, `models/detector.onnx` of the
/// nearest parent that does, `built` when it is a file; else the relative path, for the
/// caller's error to name.
pub(crate) fn model_path_from(here: &Path, built: &Path) -> PathBuf {
    let local = PathBuf::from("models/detector.onnx");
    if here.join(&local).is_file() {
        return local;
    }
    if let Some(p) = here
        .ancestors()
        .skip(1)
        .map(|d| d.join(&local))
        .find(|p| p.is_file())
    {
        return p;
    }
    if built.is_file() {
        built.to_path_buf()
    } else {
        local
    }
}

/// The network outputs of one frame, cropped to the frame's cells.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatMaps {
    /// Cells across.
    pub cols: usize,
    /// Cells down.
    pub rows: usize,
    /// `CLASSES × rows × cols` probabilities.
    pub heat: Vec<f32>,
    /// `4 × rows × cols`: `ln(w/4)`, `ln(h/4)`, `dx`, `dy`.
    pub boxes: Vec<f32>,
}

/// The network of the model `proto` (at `path`) packed for roadtrack's kernels, when it is
/// the graph `roadtrack train --detector` writes ([`super::onnx_model`]); `None` otherwise.
// Choice: only a graph equal node for node to the one roadtrack writes runs in the native
// kernels, so a model edited by hand still runs as it is written, whole in tract.
fn native_of(proto: &tract_onnx::pb::ModelProto, path: &Path) -> Option<NativeNet> {
    let net = super::weights_of(proto, path).ok()?;
    let ours = super::onnx_model(&net).ok()?;
    if ours.graph.as_ref()?.node != proto.graph.as_ref()?.node {
        return None;
    }
    NativeNet::new(&net)
}

/// The zoomed level's rows (frame px, `[top, bottom)`) and boxes (frame px, best first).
type ZoomLevel = ((f64, f64), Vec<Candidate>);

/// The learned centre-point detector (module docs of [`super`]).
pub struct CenterNetDetector {
    path: PathBuf,
    proto: tract_onnx::pb::ModelProto,
    prep: Preprocessing,
    config: CenterNetConfig,
    plans: Mutex<HashMap<(usize, usize), Arc<TypedRunnableModel>>>,
    /// The network in roadtrack's kernels (`None`: in tract).
    native: Option<NativeNet>,
    /// With the zoom: the camera, to enlarge only the rows where objects are small.
    zoom_calibration: Option<Calibration>,
    /// The box gain's terms per heat-map channel (the model's [`BOX_GAIN_KEY`](super::BOX_GAIN_KEY), all 0 —
    /// factors of 1 — without it or with [`CenterNetConfig::box_gain`] off).
    gain: [[f64; 4]; CLASSES],
}

impl std::fmt::Debug for CenterNetDetector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CenterNetDetector")
            .field("path", &self.path)
            .field("prep", &self.prep)
            .field("config", &self.config)
            .finish_non_exhaustive()
    }
}

impl CenterNetDetector {
    /// Loads a model written by `roadtrack train --detector`.
    ///
    /// # Errors
    /// [`Error::Io`] when unreadable; [`Error::Format`] naming the file when it is not
    /// ONNX, not such a detector (no `roadtrack.kind = centernet` metadata, or outputs other
    /// than `heatmap` 4 × and `boxes` 4 × at stride 4), or tract cannot run it.
    pub fn load(path: &Path, config: &CenterNetConfig) -> Result<Self> {
        roadtrack::config::Validate::validate(config)?;
        let (proto, _dims) = read_image_model(path)?;
        if metadata(&proto, "roadtrack.kind") != Some(KIND) {
            return Err(model_error(
                path,
                "not a roadtrack learned detector (no `roadtrack.kind = centernet` metadata; \
                 write one with `roadtrack train --detector`, or use --detector onnx for \
                 other detectors)",
            ));
        }
        let prep = preprocessing_from_metadata(&proto);
        prep.validate()?;
        let model_gain = super::box_gain_of(&proto, path)?;
        let gain = if config.box_gain {
            model_gain
        } else {
            [[0.0; 4]; CLASSES]
        };
        let native = native_of(&proto, path);
        let det = Self {
            path: path.to_path_buf(),
            proto,
            prep,
            config: config.clone(),
            plans: Mutex::new(HashMap::new()),
            native,
            zoom_calibration: None,
            gain,
        };
        // Fail now on a model tract cannot run or with other outputs.
        let probe = INPUT_MULTIPLE * 2;
        let out = det.run_padded(vec![0.0; 3 * probe * probe], probe, probe)?;
        let want = probe / STRIDE;
        if out.0.shape() != [1, CLASSES, want, want] || out.1.shape() != [1, 4, want, want] {
            return Err(model_error(
                path,
                format!(
                    "not a roadtrack learned detector: outputs {:?} and {:?} on a {probe} × \
                     {probe} input, expected [1, {CLASSES}, {want}, {want}] and [1, 4, {want}, {want}]",
                    out.0.shape(),
                    out.1.shape()
                ),
            ));
        }
        Ok(det)
    }

    /// The same detector with the network run by tract (for comparisons: `roadtrack bench`
    /// and the tests).
    #[must_use]
    pub fn whole_in_tract(mut self) -> Self {
        self.native = None;
        self.plans = Mutex::new(HashMap::new());
        self
    }

    /// Whether the network runs in roadtrack's kernels ([`NativeNet`]); `false`: in tract.
    pub fn is_native(&self) -> bool {
        self.native.is_some()
    }

    /// The model file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The input preprocessing (from the model's metadata).
    pub fn preprocessing(&self) -> &Preprocessing {
        &self.prep
    }

    /// The decoding settings.
    pub fn config(&self) -> &CenterNetConfig {
        &self.config
    }

    /// The box gain's terms `[a_w, b_w, a_h, b_h]` applied per heat-map channel
    /// ([`CenterNetConfig::box_gain`], [`box_factor`]).
    pub fn box_gain(&self) -> [[f64; 4]; CLASSES] {
        self.gain
    }

    fn run_error(&self, e: impl std::fmt::Display) -> Error {
        Error::Invalid(format!("{}: running the model: {e:#}", self.path.display()))
    }

    fn plan(&self, h: usize, w: usize) -> Result<Arc<TypedRunnableModel>> {
        let mut plans = self
            .plans
            .lock()
            .map_err(|_| Error::Invalid("detector plan cache poisoned".into()))?;
        if let Some(p) = plans.get(&(h, w)) {
            return Ok(Arc::clone(p));
        }
        let loaded = tract_load(&self.proto, [1, 3, h, w]);
        let plan =
            loaded.map_err(|e| model_error(&self.path, format!("tract cannot load it: {e:#}")))?;
        plans.insert((h, w), Arc::clone(&plan));
        Ok(plan)
    }

    /// One of the native network's outputs (`c` channels on an `h × w` input) as tract's
    /// `1 × c × h/4 × w/4` array.
    fn array(
        &self,
        c: usize,
        h: usize,
        w: usize,
        v: Vec<f32>,
    ) -> Result<tract_ndarray::ArrayD<f32>> {
        tract_ndarray::ArrayD::from_shape_vec(
            tract_ndarray::IxDyn(&[1, c, h / STRIDE, w / STRIDE]),
            v,
        )
        .map_err(|e| model_error(&self.path, format!("native output: {e}")))
    }

    /// The preprocessed `image` padded to `ph × pw` (as [`CenterNetDetector::input`]),
    /// mirrored left–right (`flip.0`) and/or upside down (`flip.1`) as [`flip_input`] mirrors
    /// it, into the interior of the channels-last `(ph + 2) × (pw + 2) × 3` buffer `out`;
    /// every interior value is written (padding 0).
    fn fill_channels_last(
        &self,
        image: &RgbImage,
        (ph, pw): (usize, usize),
        (fx, fy): (bool, bool),
        out: &mut [f32],
    ) {
        let (w, h) = (image.width() as usize, image.height() as usize);
        let p = &self.prep;
        let gain: [f32; 3] = std::array::from_fn(|c| p.input_scale / p.std[c]);
        let offset: [f32; 3] = std::array::from_fn(|c| -p.mean[c] / p.std[c]);
        let raw = image.as_raw();
        for r in 0..ph {
            let dst = &mut out[((r + 1) * (pw + 2) + 1) * 3..][..pw * 3];
            let y = if fy { ph - 1 - r } else { r };
            if y >= h {
                dst.fill(0.0);
                continue;
            }
            let src = raw[y * w * 3..][..w * 3].chunks_exact(3);
            let put = |d: &mut [f32], s: &[u8]| {
                for k in 0..3 {
                    d[k] = gain[k] * f32::from(s[k]) + offset[k];
                }
            };
            // The image's columns land at 0..w, or mirrored at pw − w..pw; the rest is padding.
            if fx {
                let (pad, img) = dst.split_at_mut((pw - w) * 3);
                pad.fill(0.0);
                img.chunks_exact_mut(3)
                    .zip(src.rev())
                    .for_each(|(d, s)| put(d, s));
            } else {
                let (img, pad) = dst.split_at_mut(w * 3);
                pad.fill(0.0);
                img.chunks_exact_mut(3)
                    .zip(src)
                    .for_each(|(d, s)| put(d, s));
            }
        }
    }

    /// Runs the network on a preprocessed `3 × h × w` input (`h`, `w` multiples of 16).
    fn run_padded(
        &self,
        input: Vec<f32>,
        h: usize,
        w: usize,
    ) -> Result<(tract_ndarray::ArrayD<f32>, tract_ndarray::ArrayD<f32>)> {
        if let Some(native) = &self.native {
            let (heat, boxes) = native.run(&input, h, w, Isa::best());
            return Ok((
                self.array(CLASSES, h, w, heat)?,
                self.array(4, h, w, boxes)?,
            ));
        }
        let plan = self.plan(h, w)?;
        let t = Tensor::from_shape(&[1, 3, h, w], &input).map_err(|e| self.run_error(e))?;
        let out = plan.run(tvec![t.into()]).map_err(|e| self.run_error(e))?;
        if out.len() != 2 {
            return Err(model_error(
                &self.path,
                format!("expected 2 outputs (heatmap, boxes), found {}", out.len()),
            ));
        }
        let get = |i: usize| -> Result<tract_ndarray::ArrayD<f32>> {
            let v = out[i].cast_to::<f32>().map_err(|e| self.run_error(e))?;
            let view = v
                .to_plain_array_view::<f32>()
                .map_err(|e| self.run_error(e))?;
            Ok(view.to_owned())
        };
        Ok((get(0)?, get(1)?))
    }

    /// The raw outputs `(heatmap, boxes)`, row-major `1 × 4 × h/4 × w/4` each, of a
    /// preprocessed `3 × h × w` input (`h`, `w` multiples of 16).
    ///
    /// # Errors
    /// Sides that are not multiples of 16; the model fails to run.
    pub fn forward(&self, input: Vec<f32>, h: usize, w: usize) -> Result<(Vec<f32>, Vec<f32>)> {
        if !h.is_multiple_of(INPUT_MULTIPLE)
            || !w.is_multiple_of(INPUT_MULTIPLE)
            || h == 0
            || w == 0
        {
            return Err(Error::Invalid(format!(
                "detector input {h} × {w}: sides must be positive multiples of {INPUT_MULTIPLE}"
            )));
        }
        let (a, b) = self.run_padded(input, h, w)?;
        Ok((flat(&a).into_owned(), flat(&b).into_owned()))
    }

    /// The preprocessed, padded input of `image`: `(values, padded h, padded w)`. Padding
    /// (right and bottom, to multiples of 16) is 0 after preprocessing, i.e. the mean colour.
    pub fn input(&self, image: &RgbImage) -> (Vec<f32>, usize, usize) {
        let (w, h) = (image.width() as usize, image.height() as usize);
        let ph = h.div_ceil(INPUT_MULTIPLE).max(1) * INPUT_MULTIPLE;
        let pw = w.div_ceil(INPUT_MULTIPLE).max(1) * INPUT_MULTIPLE;
        let mut out = vec![0.0f32; 3 * ph * pw];
        let p = &self.prep;
        let gain: [f32; 3] = std::array::from_fn(|c| p.input_scale / p.std[c]);
        let offset: [f32; 3] = std::array::from_fn(|c| -p.mean[c] / p.std[c]);
        for (y, row) in image.rows().enumerate() {
            for (x, px) in row.enumerate() {
                for c in 0..3 {
                    out[c * ph * pw + y * pw + x] = gain[c] * f32::from(px.0[c]) + offset[c];
                }
            }
        }
        (out, ph, pw)
    }

    /// The network's heat maps and box maps of `image`, cropped to the frame's cells.
    ///
    /// # Errors
    /// The model fails to run.
    pub fn heat_maps(&self, image: &RgbImage) -> Result<HeatMaps> {
        let (w, h) = (image.width() as usize, image.height() as usize);
        let ph = h.div_ceil(INPUT_MULTIPLE).max(1) * INPUT_MULTIPLE;
        let pw = w.div_ceil(INPUT_MULTIPLE).max(1) * INPUT_MULTIPLE;
        let mut flips = Vec::new();
        if self.config.flip {
            flips.push((true, false));
        }
        if self.config.flip_vertical {
            flips.push((false, true));
            if self.config.flip {
                flips.push((true, true));
            }
        }
        // The network's outputs on the frame as it is, then on each mirrored view.
        let mut outs = Vec::with_capacity(flips.len() + 1);
        if let Some(native) = &self.native {
            // The native network reads its channels-last input straight from the image,
            // mirrored as each view asks: no planar copy, no mirrored copy.
            for (x, y) in std::iter::once((false, false)).chain(flips.iter().copied()) {
                let (heat, boxes) = native.run_filled(ph, pw, Isa::best(), &mut |buf| {
                    self.fill_channels_last(image, (ph, pw), (x, y), buf);
                });
                outs.push((
                    self.array(CLASSES, ph, pw, heat)?,
                    self.array(4, ph, pw, boxes)?,
                ));
            }
        } else {
            let (input, _, _) = self.input(image);
            let flipped: Vec<Vec<f32>> = flips
                .iter()
                .map(|&(x, y)| flip_input(&input, ph, pw, x, y))
                .collect();
            outs.push(self.run_padded(input, ph, pw)?);
            for m in flipped {
                outs.push(self.run_padded(m, ph, pw)?);
            }
        }
        let mut outs = outs.into_iter();
        let (mut heat, mut boxes) = outs
            .next()
            .ok_or_else(|| Error::Invalid("the detector ran no pass".into()))?;
        let (oh, ow) = (ph / STRIDE, pw / STRIDE);
        if !flips.is_empty() {
            let mut views = Vec::with_capacity(flips.len());
            for ((mh, mb), &(x, y)) in outs.zip(&flips) {
                if heat.shape() != mh.shape()
                    || boxes.shape() != mb.shape()
                    || boxes.shape() != [1, 4, oh, ow]
                {
                    return Err(model_error(
                        &self.path,
                        format!(
                            "output shape {:?}, expected [1, 4, {oh}, {ow}]",
                            boxes.shape()
                        ),
                    ));
                }
                views.push((mh, mb, x, y));
            }
            average_flipped(&mut heat, &mut boxes, &views);
        }
        let cols = (image.width() as usize).div_ceil(STRIDE).max(1);
        let rows = (image.height() as usize).div_ceil(STRIDE).max(1);
        let crop = |a: &tract_ndarray::ArrayD<f32>, ch: usize| -> Result<Vec<f32>> {
            if a.shape() != [1, ch, oh, ow] {
                return Err(model_error(
                    &self.path,
                    format!(
                        "output shape {:?}, expected [1, {ch}, {oh}, {ow}]",
                        a.shape()
                    ),
                ));
            }
            let flat = flat(a);
            let mut out = Vec::with_capacity(ch * rows * cols);
            for c in 0..ch {
                for r in 0..rows {
                    out.extend_from_slice(&flat[c * oh * ow + r * ow..][..cols]);
                }
            }
            Ok(out)
        };
        Ok(HeatMaps {
            cols,
            rows,
            heat: crop(&heat, CLASSES)?,
            boxes: crop(&boxes, 4)?,
        })
    }

    /// The objects in `image`, best first: `(box in image px, class, score)`.
    ///
    /// # Errors
    /// The model fails to run.
    pub fn detect_boxes(&self, image: &RgbImage) -> Result<Vec<(BBox, ObjectClass, f64)>> {
        let min_side = self.config.min_side;
        let mut cands = self.pyramid_candidates(image)?;
        let mut zoomed = if self.config.zoom_max_side > 0.0 {
            self.zoom_level(image)?
        } else {
            None
        };
        if self.config.zoom_mode == ZoomMode::Level
            && let Some((rows, boxes)) = zoomed.take()
        {
            replace_small(&mut cands, boxes, rows, self.config.zoom_max_side);
        }
        cands.retain(|c| c.w.max(c.h) >= min_side);
        let kept = nms(cands, self.config.iou_threshold, usize::MAX);
        // Cross-class suppression: `kept` is sorted by score.
        let mut out: Vec<Candidate> = Vec::new();
        for c in kept {
            if out.len() >= self.config.max_detections {
                break;
            }
            if out
                .iter()
                .all(|k| k.class == c.class || k.iou(&c) <= self.config.cross_class_iou)
            {
                out.push(c);
            }
        }
        if let Some((_, boxes)) = zoomed {
            add_zoomed(&mut out, boxes, &self.config);
        }
        let out = drop_second_peaks(drop_nested(out, &self.config), &self.config);
        let (w, h) = (f64::from(image.width()), f64::from(image.height()));
        Ok(out
            .into_iter()
            .filter_map(|mut c| {
                let (gw, gh) =
                    box_factor(&self.gain[c.class], c.w * c.gain_scale, c.h * c.gain_scale);
                c.w *= gw;
                c.h *= gh;
                let x0 = (c.cx - c.w / 2.0).clamp(0.0, w);
                let y0 = (c.cy - c.h / 2.0).clamp(0.0, h);
                let x1 = (c.cx + c.w / 2.0).clamp(0.0, w);
                let y1 = (c.cy + c.h / 2.0).clamp(0.0, h);
                (x1 > x0 && y1 > y0).then(|| {
                    (
                        BBox::new(x0, y0, x1 - x0, y1 - y0),
                        channel_class(c.class),
                        c.score,
                    )
                })
            })
            .collect())
    }

    /// Heat-map peaks of the full-size frame and, with [`CenterNetConfig::pyramid`] `k > 1`,
    /// of the frame shrunk `k` times, each level keeping the sizes it is made for; a
    /// full-size vehicle box lying mostly inside a larger coarse vehicle box is dropped.
    fn pyramid_candidates(&self, image: &RgbImage) -> Result<Vec<Candidate>> {
        let cfg = &self.config;
        let fine = decode_peaks(
            &self.heat_maps(image)?,
            &cfg.class_min_score.thresholds(cfg.min_score),
        );
        let k = cfg.pyramid;
        if k <= 1
            || image.width() < k * INPUT_MULTIPLE as u32
            || image.height() < k * INPUT_MULTIPLE as u32
        {
            return Ok(fine);
        }
        let small = shrink(image, k);
        let coarse = decode_peaks(
            &self.heat_maps(&small)?,
            &cfg.class_min_score.thresholds(cfg.coarse_min_score),
        );
        Ok(merge_levels(fine, coarse, k, cfg))
    }

    /// With the zoom ([`CenterNetConfig::zoom_max_side`]): enlarge only the rows where a
    /// car measures under `zoom_max_side` px through `calibration` ([`zoom_rows`]), and
    /// none when there are no such rows (an aerial view of cars larger than that).
    #[must_use]
    pub fn with_zoom_calibration(mut self, calibration: Calibration) -> Self {
        self.zoom_calibration = Some(calibration);
        self
    }

    /// The zoomed level: the rows it covers (frame px, `[top, bottom)`) and the heat-map
    /// peaks of the frame (or, with a calibration, of its [`zoom_rows`] with a margin of
    /// `zoom_max_side` rows) enlarged [`CenterNetConfig::zoom_factor`] times (bilinear),
    /// in frame px, from [`CenterNetConfig::min_side`] up to below
    /// [`CenterNetConfig::zoom_max_side`], centres inside the rows, class-wise NMS at
    /// [`CenterNetConfig::iou_threshold`]; best first. `None` where no row is enlarged.
    fn zoom_level(&self, image: &RgbImage) -> Result<Option<ZoomLevel>> {
        let cfg = &self.config;
        let (w, h) = image.dimensions();
        let rows = match &self.zoom_calibration {
            Some(cal) => match zoom_rows(cal, w, h, cfg.zoom_max_side) {
                Some(r) => r,
                None => return Ok(None),
            },
            None => (0, h),
        };
        let margin = cfg.zoom_max_side.ceil() as u32;
        let top = rows.0.saturating_sub(margin);
        let bottom = (rows.1 + margin).min(h);
        if bottom <= top || w == 0 {
            return Ok(None);
        }
        let band = image::imageops::crop_imm(image, 0, top, w, bottom - top).to_image();
        let zoom = cfg.zoom_factor;
        let big = image::imageops::resize(
            &band,
            w * zoom,
            (bottom - top) * zoom,
            image::imageops::FilterType::Triangle,
        );
        let z = f64::from(zoom);
        let (y0, y1) = (f64::from(rows.0), f64::from(rows.1));
        let floor = cfg.class_min_score.thresholds(cfg.min_score);
        let cands: Vec<Candidate> = decode_peaks(&self.heat_maps(&big)?, &floor)
            .into_iter()
            .map(|c| Candidate {
                cx: c.cx / z,
                cy: c.cy / z + f64::from(top),
                w: c.w / z,
                h: c.h / z,
                gain_scale: z,
                ..c
            })
            .filter(|c| {
                let side = c.w.max(c.h);
                side >= cfg.min_side && side < cfg.zoom_max_side && c.cy >= y0 && c.cy < y1
            })
            .collect();
        Ok(Some(((y0, y1), nms(cands, cfg.iou_threshold, usize::MAX))))
    }

    /// The heat map of `channels` (their maximum per cell) as a score map: cell `(r, c)`
    /// centred at image px `(4c + 2, 4r + 2)`.
    ///
    /// # Errors
    /// The model fails to run.
    pub fn score_map(&self, image: &RgbImage, channels: &[usize]) -> Result<ScoreMap> {
        let maps = self.heat_maps(image)?;
        Ok(score_map_of(&maps, channels))
    }
}

impl CenterNetDetector {
    /// [`Detector::detect`] on `&self`: the result depends on `frame` alone.
    fn frame_detections(&self, frame: &Frame) -> Result<FrameDetections> {
        let boxes = self.detect_boxes(&frame.image)?;
        let detections = boxes
            .into_iter()
            .enumerate()
            .map(|(i, (bbox, class, score))| Detection {
                frame: frame.index,
                id: i as u64 + 1,
                pos_px: bbox.centre(),
                size_px: Some((bbox.width, bbox.height)),
                colour_rgb: roadtrack::detect::file::mean_colour(&frame.image, &bbox),
                class: Some(class),
                score: Some(score),
                area_px: None,
            })
            .collect();
        Ok(FrameDetections {
            detections,
            foreground: None,
        })
    }
}

crate::stateless_detector!(CenterNetDetector);

/// The detector's heat map as the filters' dense likelihood (seed 004's score map): the
/// channels of the filter's target class.
#[derive(Debug, Clone)]
pub struct CenterNetDense {
    /// The detector.
    pub detector: Arc<CenterNetDetector>,
    /// Heat-map channels whose maximum is the score.
    pub channels: Vec<usize>,
}

impl DenseScorer for CenterNetDense {
    fn score_map(&self, image: &RgbImage) -> Result<ScoreMap> {
        self.detector.score_map(image, &self.channels)
    }
}
