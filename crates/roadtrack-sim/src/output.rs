//! Writing a simulated sequence as a MOTChallenge folder.
//!
//! ```text
//! OUT/
//!   img1/000001.jpg …       frames (JPEG by default: MOTChallenge's format, and a noisy
//!                           640×480 frame is ~60 KB as JPEG vs ~900 KB as PNG)
//!   seqinfo.ini             frameRate, seqLength, imWidth, imHeight, imExt
//!   gt/gt.txt               frame,id,left,top,width,height,1,MOT17 class,visibility
//!                           (MOT17's: the border's cropping hides, `TruthRow::in_frame`)
//!   det/det.txt             MOTChallenge public detections (id −1)
//!   det/detections.csv      the same detections with mean colour and class
//!   truth.csv               one row per object per frame (columns below)
//!   calibration.toml        image ↔ ground calibration
//!   simulation.toml         seed and the full configuration used
//! ```
//!
//! `truth.csv` columns: `frame,time_s,id,class,x_m,y_m,x_px,y_px,speed_mps,heading_deg,
//! length_m,width_m,height_m,r,g,b,visibility,bb_left,bb_top,bb_width,bb_height`
//! (`r,g,b` = paint colour before shading; `x_px,y_px` = image of the ground point).

use super::config::{ImageFormat, SimConfig};
use super::external::ExternalTrajectories;
use super::{SimStep, Simulation, TruthRow};
use rayon::prelude::*;
use roadtrack_core::class::ObjectClass;
use roadtrack_core::detection::Detection;
use roadtrack_core::error::{Error, Result};
use roadtrack_core::io::atomic::AtomicDir;
use roadtrack_core::io::detections::csv_word;
use roadtrack_core::io::mot::MotGtRow;
use roadtrack_core::io::seqinfo::SeqInfo;
use roadtrack_core::io::table::num;
use roadtrack_core::io::write_atomic;
use std::path::Path;

/// What [`simulate`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct SimSummary {
    /// Frames written.
    pub frames: u32,
    /// Distinct objects that appeared in the image.
    pub objects: usize,
    /// Vehicles among them.
    pub vehicles: usize,
    /// Pedestrians among them.
    pub pedestrians: usize,
    /// Ground-truth rows.
    pub truth_rows: usize,
    /// Detections written.
    pub detections: usize,
    /// Mean visibility over the ground-truth rows.
    pub mean_visibility: f64,
}

/// MOTChallenge ground-truth rows for `truth` (consider = 1, MOT17 class numbers).
pub fn gt_rows(truth: &[TruthRow]) -> Vec<MotGtRow> {
    truth
        .iter()
        .map(|t| MotGtRow {
            frame: t.frame,
            id: t.id,
            bbox: t.bbox,
            consider: true,
            class: t.class.mot17_id(),
            // Choice: MOT17's visibility, which counts an object's part cut off by the
            // image border as hidden ("due to occlusion and due to image border
            // cropping"): a car 4 px of which show at the edge is not a fully visible car.
            // Before 2026-11-27 the frame's edge did not count (truth.csv still gives that).
            visibility: t.visibility * t.in_frame,
        })
        .collect()
}

/// Writes `truth.csv` (module doc), atomically.
pub fn write_truth_csv(path: &Path, rows: &[TruthRow]) -> Result<()> {
    write_atomic(path, |w| {
        writeln!(
            w,
            "frame,time_s,id,class,x_m,y_m,x_px,y_px,speed_mps,heading_deg,length_m,width_m,height_m,r,g,b,visibility,bb_left,bb_top,bb_width,bb_height"
        )?;
        for t in rows {
            writeln!(
                w,
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                t.frame,
                num(t.time_s, 6),
                t.id,
                csv_word(t.class.name()),
                num(t.x_m, 4),
                num(t.y_m, 4),
                num(t.x_px, 3),
                num(t.y_px, 3),
                num(t.speed_mps, 4),
                num(t.heading_deg, 3),
                num(t.length_m, 3),
                num(t.width_m, 3),
                num(t.height_m, 3),
                t.colour_rgb[0],
                t.colour_rgb[1],
                t.colour_rgb[2],
                num(t.visibility, 6),
                num(t.bbox.left, 3),
                num(t.bbox.top, 3),
                num(t.bbox.width, 3),
                num(t.bbox.height, 3),
            )?;
        }
        Ok(())
    })
}

/// Encodes a rendered frame as `img1/` holds it (`config.image_format`, JPEG quality).
///
/// # Errors
/// The encoder fails.
pub fn encode_frame(step: &SimStep, config: &SimConfig) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    let img = &step.frame.image;
    let res = match config.image_format {
        ImageFormat::Jpeg => {
            // Choice: jpeg-encoder rather than image's encoder, twice as fast (half the
            // simulator's CPU was JPEG encoding). Same standard tables and quality scaling,
            // and 4:4:4 as image's encoder wrote, so the frames differ from before only by
            // the DCT's rounding (docs/SIMULATOR.md "Speed", "The JPEG encoder").
            let (w, h) = img.dimensions();
            let (Ok(w), Ok(h)) = (u16::try_from(w), u16::try_from(h)) else {
                return Err(Error::Invalid(format!(
                    "frame {}: {w} × {h} px is beyond JPEG's 65 535 px a side",
                    step.frame.index
                )));
            };
            let mut enc = jpeg_encoder::Encoder::new(&mut bytes, config.jpeg_quality);
            enc.set_sampling_factor(jpeg_encoder::SamplingFactor::F_1_1);
            enc.encode(img.as_raw(), w, h, jpeg_encoder::ColorType::Rgb)
                .map_err(|e| {
                    Error::Invalid(format!("frame {}: JPEG encoding: {e}", step.frame.index))
                })?;
            Ok(())
        }
        ImageFormat::Png => {
            let enc = image::codecs::png::PngEncoder::new_with_quality(
                &mut bytes,
                image::codecs::png::CompressionType::Fast,
                image::codecs::png::FilterType::Sub,
            );
            img.write_with_encoder(enc)
        }
    };
    res.map_err(|source| Error::Image {
        source,
        path: format!("frame {}", step.frame.index).into(),
    })?;
    Ok(bytes)
}

fn ext(config: &SimConfig) -> &'static str {
    match config.image_format {
        ImageFormat::Jpeg => "jpg",
        ImageFormat::Png => "png",
    }
}

/// Frames rendered ahead of their encoding (and encoded in parallel) at a time.
const BATCH: usize = 8;

/// Writes the sequence produced by `sim` into `out_dir` (module doc).
fn write_sequence(
    mut sim: Simulation,
    seed: u64,
    out_dir: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<SimSummary> {
    let config = sim.config().clone();
    let n = sim.n_frames();
    // The folder is written aside and swapped in at the end: an interrupted run leaves no
    // sequence, and a rerun no stale frames.
    let dest = AtomicDir::create(out_dir)?;
    let tmp = dest.temp_path().to_owned();
    let img_dir = tmp.join("img1");
    std::fs::create_dir_all(&img_dir).map_err(|e| Error::io(&img_dir, e))?;
    let mut truth: Vec<TruthRow> = Vec::new();
    let mut dets: Vec<Detection> = Vec::new();
    let ext = ext(&config);
    progress(0, u64::from(n));
    let mut done = 0u64;
    // Render sequentially (traffic is sequential); encode and write each batch in parallel
    // while the next batch renders.
    // Choice: the two overlap (rayon::join) because encoding is about 60 % of the work and
    // rendering the rest: one after the other left a core idle during every render. The
    // files written are the same either way.
    let write = |batch: &[SimStep]| {
        batch.par_iter().try_for_each(|step| -> Result<()> {
            let bytes = encode_frame(step, &config)?;
            let path = img_dir.join(format!("{:06}.{ext}", step.frame.index));
            roadtrack_core::io::atomic::write_bytes_atomic(&path, &bytes)
        })
    };
    let mut batch: Vec<SimStep> = sim.by_ref().take(BATCH).collect::<Result<_>>()?;
    while !batch.is_empty() {
        let (next, written) = rayon::join(
            || sim.by_ref().take(BATCH).collect::<Result<Vec<SimStep>>>(),
            || write(&batch),
        );
        written?;
        for step in batch {
            done += 1;
            truth.extend(step.truth);
            dets.extend(step.detections);
        }
        progress(done, u64::from(n));
        batch = next?;
    }
    let name = out_dir
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "sim".into());
    SeqInfo {
        name,
        im_dir: "img1".into(),
        frame_rate: config.fps,
        seq_length: n,
        im_width: config.width,
        im_height: config.height,
        im_ext: format!(".{ext}"),
    }
    .write(&tmp.join("seqinfo.ini"))?;
    roadtrack_core::io::mot::write_gt(&tmp.join("gt/gt.txt"), &gt_rows(&truth))?;
    roadtrack_core::io::mot::write_detections(&tmp.join("det/det.txt"), &dets)?;
    roadtrack_core::io::detections::write_detections(&tmp.join("det/detections.csv"), &dets)?;
    write_truth_csv(&tmp.join("truth.csv"), &truth)?;
    sim.calibration().save(&tmp.join("calibration.toml"))?;
    let provenance = format!(
        "# roadtrack simulate: the configuration that produced this folder (usable as --config).\n# seed = {seed}\n\n{}",
        config.to_toml()
    );
    roadtrack_core::io::atomic::write_bytes_atomic(
        &tmp.join("simulation.toml"),
        provenance.as_bytes(),
    )?;
    dest.commit()?;
    let mut ids: Vec<(u64, bool)> = truth
        .iter()
        .map(|t| (t.id, t.class == ObjectClass::Pedestrian))
        .collect();
    ids.sort_unstable();
    ids.dedup();
    let pedestrians = ids.iter().filter(|x| x.1).count();
    let mean_visibility = if truth.is_empty() {
        0.0
    } else {
        truth.iter().map(|t| t.visibility).sum::<f64>() / truth.len() as f64
    };
    Ok(SimSummary {
        frames: n,
        objects: ids.len(),
        vehicles: ids.len() - pedestrians,
        pedestrians,
        truth_rows: truth.len(),
        detections: dets.len(),
        mean_visibility,
    })
}

/// Simulates `config` under `seed` and writes the sequence folder `out_dir` (module doc).
/// `progress(done, total)` is called with frame counts.
///
/// # Errors
/// An invalid configuration; a file that cannot be written.
pub fn simulate(
    config: &SimConfig,
    seed: u64,
    out_dir: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<SimSummary> {
    write_sequence(Simulation::new(config, seed)?, seed, out_dir, progress)
}

/// Renders the trajectories in `trajectories_csv` (see [`super::external`]) in
/// `config.scene`'s setting seen by `config.view`, with the same outputs as [`simulate`].
/// `frames` defaults to the file's whole time span at `config.fps`.
///
/// # Errors
/// A bad trajectories file; an invalid configuration; a file that cannot be written.
pub fn simulate_from_trajectories(
    config: &SimConfig,
    seed: u64,
    trajectories_csv: &Path,
    frames: Option<u32>,
    out_dir: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<SimSummary> {
    let traj = ExternalTrajectories::read(trajectories_csv)?;
    write_sequence(
        Simulation::from_trajectories(config, seed, traj, frames)?,
        seed,
        out_dir,
        progress,
    )
}
