//! Upper bounds on every size, count, frame or step number, time span and rate that
//! `roadtrack` reads from a file, a config or a flag (docs/FORMATS.md, "Limits").
//!
//! A value beyond its bound is rejected with an error naming the file and line, the config
//! field or the flag, before anything is allocated or looped over for it: without the
//! bounds one number in an input (a frame of 2 000 000 000, a particle count of 10⁸, a frame
//! rate of 1e308) aborts on a failed allocation or runs for ever.
//!
//! The bounds are far above what the paper's experiments and any realistic recording need;
//! they exist so that a typo or a hostile file cannot take the machine down.

/// The largest frame number (1-based) in any input, and the largest frame count
/// (`--num-frames`, `seqLength`, `SimConfig::frames`).
// Choice: 10 000 000 frames is ≈ 11.6 days at 10 frames/s and ≈ 46 h at 60 frames/s;
// per-frame tables of that length still fit in memory (tens of MB per f64 column).
pub const MAX_FRAME: u32 = 10_000_000;

/// The largest time step in a measurements file (`roadtrack filter`), which filters every
/// step from the first to the last.
// Choice: the same bound as frames; a step is a frame of point data.
pub const MAX_STEP: u64 = MAX_FRAME as u64;

/// The most measurements in one step of a measurements file.
// Choice: the point filter's birth proposal and update cost (birth particles per
// measurement) × measurements²; 1 000 points in one step take about a second and a few
// hundred MB, 5 000 took minutes and 8 GB.
pub const MAX_MEASUREMENTS_PER_STEP: usize = 1_000;

/// The longest image side, px (frames, `seqinfo.ini` `imWidth`/`imHeight`, model inputs).
// Choice: 16 384 px is the largest texture side of common GPUs and above every camera in
// the paper's and MOTChallenge's data (≤ 1 920 px); an RGB frame of 16 384² is 768 MB.
pub const MAX_IMAGE_SIDE: u32 = 16_384;

/// The longest side of a CNN input window, px (`roadtrack train --input-size`).
// Choice: the paper's windows are 64 × 32 and 32 × 16; training keeps a few thousand
// windows and the network's activations in memory, so 1 024 px per side (≈ 4 MB per
// RGB window in f32) is already generous.
pub const MAX_CNN_INPUT_SIDE: usize = 1_024;

/// The largest CNN training batch.
// Choice: the paper's batches are 32 and 64.
pub const MAX_BATCH_SIZE: usize = 4_096;

/// The most input pixels in one CNN training batch (`batch_size × height × width`).
// Choice: 64 Mpx is ≈ 768 MB of f32 RGB input per batch before the activations, 500 times
// the paper's 64 × (64 × 32).
pub const MAX_BATCH_PIXELS: usize = 64 << 20;

/// The most channels of a CNN convolution.
// Choice: the trainer's defaults are 8 and 16.
pub const MAX_CNN_CHANNELS: usize = 1_024;

/// The most training positives (`TrainConfig::max_positives`).
// Choice: the paper's data sets have 900 and 5 000.
pub const MAX_PATCHES: usize = 1_000_000;

/// The most negatives sampled per positive (`TrainConfig::negatives_per_positive`).
// Choice: the paper's ratios are 1 and 2.
pub const MAX_NEGATIVES_PER_POSITIVE: f64 = 100.0;

/// The highest frame rate, frames/s (flags, configs, `seqinfo.ini` `frameRate`).
// Choice: 1 000 frames/s covers high-speed cameras; the lower bound is "> 0".
pub const MAX_FPS: f64 = 1_000.0;

/// The largest magnitude of a point measurement's coordinate (any units).
// Choice: 10⁹ (a million km in metres, or pixels of no camera); beyond it a stray value
// (1e308) stretches the default surveillance region until every density underflows and
// the filter silently reports nothing.
pub const MAX_COORDINATE: f64 = 1e9;

/// The longest time span, s: a time in a trajectories file, `SimConfig::warmup_s`, and the
/// simulated time (warm-up plus frames / fps).
// Choice: one day; a simulation is for minutes to hours of traffic.
pub const MAX_DURATION_S: f64 = 86_400.0;

/// The most traffic time steps one simulation may take (warm-up included):
/// `(warmup_s + frames / fps) / max_step_s`.
// Choice: the same count as frames; 10⁷ steps of a busy scene take hours already.
pub const MAX_SIM_STEPS: f64 = MAX_FRAME as f64;

/// The most iterations of an iterative method (`RelaxationConfig::max_iterations`,
/// `MrfConfig::max_iterations`) and epochs of training (`TrainConfig::epochs`).
// Choice: the paper's methods use 20–50; 100 000 is a run of hours, not of years.
pub const MAX_ITERATIONS: u32 = 100_000;

/// The most frames the background model keeps for its initial median
/// (`BackgroundConfig::bootstrap_frames`).
// Choice: the default is 25; every frame is held in memory until the median is taken.
pub const MAX_BOOTSTRAP_FRAMES: u32 = 1_000;

/// The most two-frame problems `simulate --pairs` writes (`PairsConfig::n_pairs`).
// Choice: the paper's tables use tens to hundreds of problems.
pub const MAX_PAIRS: u32 = 100_000;

/// The most particles per object (`particles_per_object`, `birth_particles_per_detection`,
/// `particles_per_target`, `birth_particles_per_measurement`).
// Choice: the paper uses 70–100; 100 000 is a thousand times that (≈ 5 MB per object).
pub const MAX_PARTICLES_PER_OBJECT: usize = 100_000;

/// The most frames of look-ahead of the PHD's smoothed count
/// (`FilterTrackConfig::count_lag_frames`).
// Choice: 100 frames (10 s at 10 frames/s); each frame held keeps every label's weight.
pub const MAX_COUNT_LAG_FRAMES: u32 = 100;

/// The largest total particle cap (`PhdConfig::max_particles`) and birth grid.
// Choice: 1 000 000 particles are ≈ 50 MB of state; the default cap is 20 000.
pub const MAX_PARTICLES: usize = 1_000_000;

/// The default number of candidate labels the relaxation keeps per object
/// (`RelaxationConfig::max_labels`): the nearest ones inside the gate.
// Choice: twice the most candidates any committed experiment has in a gate (measured:
// golden tracks 9, the paper's road pairs at Δt 1.5–4 s with D 150 and 250 px 16, the
// scale network 14, the library's tests 22), so their outputs stay byte-identical; it
// bounds the label lists, which otherwise grow with the density of the scene (10 000
// detections in a 2 000 px square: ~225 per vehicle).
pub const DEFAULT_MAX_LABELS: usize = 32;

/// A number a bound applies to.
pub trait Bounded: PartialOrd + Copy {
    /// The number as a message shows it.
    fn show(self) -> String;
}

macro_rules! bounded_int {
    ($($t:ty),*) => {$(
        impl Bounded for $t {
            fn show(self) -> String {
                self.to_string()
            }
        }
    )*};
}
bounded_int!(u32, u64, usize);

impl Bounded for f64 {
    fn show(self) -> String {
        // `1e308` rather than 309 digits.
        if self.abs() >= 1e9 {
            format!("{self:e}")
        } else {
            self.to_string()
        }
    }
}

/// The default number of neighbours (eq. 16) the relaxation keeps per vehicle
/// (`RelaxationConfig::max_neighbours`): the nearest ones within `R`.
// Choice: twice the most neighbours within R in any committed experiment (golden tracks
// 8, road pairs 12, scale network 17, the library's tests 23); the support lists grow
// with labels × neighbours (10 000 detections in 2 000 px: ~310 neighbours each).
pub const DEFAULT_MAX_NEIGHBOURS: usize = 32;

/// The largest `max_labels` and `max_neighbours` of the relaxation.
// Choice: 4 096 labels per vehicle already make a dense 10 000-vehicle problem take
// gigabytes; the bound keeps a config typo from removing the cap.
pub const MAX_LABELS: usize = 4_096;

/// Checks `value ≤ max` (a NaN fails), with a message that names the bound.
///
/// # Errors
/// A message `"{value} exceeds the limit {max} ({what}; …)"` for the caller to wrap with
/// its file, line, field or flag.
pub fn at_most<T: Bounded>(value: T, max: T, what: &str) -> std::result::Result<(), String> {
    if value <= max {
        Ok(())
    } else {
        Err(format!(
            "{} exceeds the limit {} ({what}; docs/FORMATS.md, Limits)",
            value.show(),
            max.show()
        ))
    }
}

/// A clap value parser for a frame rate in `(0, MAX_FPS]`.
///
/// # Errors
/// A message naming the range.
pub fn parse_fps(s: &str) -> std::result::Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))?;
    if v.is_finite() && v > 0.0 && v <= MAX_FPS {
        Ok(v)
    } else {
        Err(format!(
            "frame rate must be in (0, {MAX_FPS}] frames/s (docs/FORMATS.md, Limits), found {s}"
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_accept_the_limit_and_reject_above() {
        assert!(at_most(MAX_FRAME, MAX_FRAME, "frame").is_ok());
        let e = at_most(MAX_FRAME + 1, MAX_FRAME, "frame number").unwrap_err();
        assert!(e.contains("10000001") && e.contains("frame number"), "{e}");
        assert_eq!(parse_fps("1000"), Ok(1000.0));
        for bad in ["0", "-1", "1e308", "inf", "NaN", "x"] {
            assert!(parse_fps(bad).is_err(), "{bad}");
        }
    }
}
