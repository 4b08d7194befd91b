//! Spatio-temporal MRF tracker (Kamijo & Sakauchi; METHODS.md §2, seed 002).
//!
//! Vehicles and pedestrians are tracked as regions of `8 × 8` px blocks straight from the
//! pixels. Each frame:
//!
//! 1. background subtraction ([`BackgroundModel`]) marks moving blocks (a block is moving
//!    when at least [`MrfConfig::moving_fraction`] of its 64 pixels are foreground);
//!    block matching ([`block_matching`]) gives every labelled block of `X(t − 1)` a vector;
//! 2. the Object-map `X(t − 1)` is moved by the rounded vectors ([`propagate`]); blocks
//!    reached by several ids become sites to optimise;
//! 3. – 5. the Gibbs sampler ([`gibbs`]) minimises eq. 5 ([`energy`]) over (id, vector)
//!    with double buffering until the stop rule holds;
//!
//! then unclaimed moving regions are born as new objects, and every object's box is
//! reported as a [`TrackPoint`].
//!
//! Two variants ([`MrfVariant`]): the 2000 model (representative vector per object, no `f`
//! term) and the 2004 model (local vectors and the `f` term), compared in Fig. 10.

pub mod block_matching;
pub mod energy;
pub mod gibbs;
pub mod object_map;
pub mod propagate;
#[cfg(test)]
mod scenarios;
pub mod separation;

use crate::class::ObjectClass;
use crate::detect::background_model::{BackgroundConfig, BackgroundModel};
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::track_point::TrackPoint;
use block_matching::{BlockMatch, gray_from_rgb, match_blocks};
use image::GrayImage;
use object_map::{BLOCK_PX, BlockGrid, MotionMap, NO_OBJECT, ObjectId, ObjectMap, Vector};
use serde::{Deserialize, Serialize};

/// Which model of the paper to run (METHODS.md §2 "Two variants").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum MrfVariant {
    /// 2000 model: `M` and `D` use each object's representative (most frequent) vector;
    /// no `f` term; vectors are not optimised.
    #[cfg_attr(
        feature = "clap",
        value(help = "2000: representative vector per object, no smoothness term")
    )]
    Legacy,
    /// 2004 model: local per-block vectors, optimised jointly with the ids, and the `f`
    /// smoothness term (eq. 4).
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "2004: local vectors with the smoothness term")
    )]
    Improved,
}

/// Parameters of the MRF tracker (METHODS.md §2). `Default` is the paper's values where
/// the paper gives them (weights `a, b, c, f`, `μ_N`, `μ_M`, 8-px blocks, ±24 px window,
/// 3-block border); the rest are this project's choices, documented in docs/MRF.md.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MrfConfig {
    /// Model variant. Default improved (2004).
    pub variant: MrfVariant,
    /// `a`, eq. 3/5: weight of the neighbour term. Default 1/2.
    pub neighbour_weight: f64,
    /// `b`, eq. 1/5: weight of the overlap term. Default 1/256.
    pub overlap_weight: f64,
    /// `c`, eq. 1/5: weight of the texture term (luminance SAD). Default 32/1 000 000.
    pub texture_weight: f64,
    /// `f`, eq. 4/5: weight of the motion-vector smoothness term (improved only). Default 1/4.
    pub smoothness_weight: f64,
    /// `μ_N`, eq. 3: neighbours with the same id at the minimum. Default 8.
    pub neighbour_target: f64,
    /// `μ_M`, eq. 1: overlapping pixels at the minimum. Default 64.
    pub overlap_target: f64,
    /// Block side, px. Default 8 (the only value supported: the matching kernel is
    /// specialised for 8-px rows).
    pub block_px: u32,
    /// Block-matching search window half-width in each axis, px (Step 1). Default 24.
    pub search_radius_px: u32,
    /// Gibbs temperature of the first sweep (energy units). Default 4.
    pub initial_temperature: f64,
    /// Factor applied to the temperature after each sweep. Default 0.7.
    pub cooling: f64,
    /// Floor of the temperature. Default 0.05.
    pub min_temperature: f64,
    /// Sweep cap (Step 5). Default 20.
    pub max_iterations: u32,
    /// Step 5: stop when fewer than this many blocks changed id in a sweep… Default 1.
    pub n_th_id: u32,
    /// …and fewer than this many changed vector by more than `v_diff_px`. Default 1.
    pub n_th_mv: u32,
    /// Step 5: a vector change `|Δv_x| + |Δv_y|` above this counts as a change, px. Default 1.
    pub v_diff_px: u32,
    /// A `t − 1` block moved by its vector offers its id to every block of `X(t)` it
    /// overlaps by at least this many pixels, besides its rounded target (Step 2
    /// extension, see docs/MRF.md; 65 = the paper's rounding only). Default 65: the
    /// extension did not help on our scenes (docs/MRF.md).
    pub min_overlap_px: u32,
    /// Improved variant: the vectors the sampler proposes for an id lie within this many px
    /// (per axis) of the id's representative vector (see `gibbs::proposals`). Default 0;
    /// 48 switches the bound off.
    pub local_vector_tolerance_px: u32,
    /// Blocks along each frame edge excluded from tracking (the paper's experiment: 3).
    pub border_blocks: u32,
    /// Smallest connected region of unclaimed moving blocks that becomes a new object,
    /// blocks. Default 4.
    pub birth_min_blocks: u32,
    /// A block is moving when at least this fraction of its pixels are foreground.
    /// Default 0.25.
    pub moving_fraction: f64,
    /// Objects smaller than this many blocks are not reported (they are still tracked).
    /// Default 2.
    pub min_output_blocks: u32,
    /// Background subtraction (the spine's model; the paper says only "background
    /// subtraction"). Default: median start-up, no shadow suppression, no hold.
    pub background: BackgroundConfig,
}

impl Default for MrfConfig {
    fn default() -> Self {
        Self {
            variant: MrfVariant::Improved,
            neighbour_weight: 0.5,
            overlap_weight: 1.0 / 256.0,
            texture_weight: 32.0 / 1_000_000.0,
            smoothness_weight: 0.25,
            neighbour_target: 8.0,
            overlap_target: 64.0,
            block_px: BLOCK_PX,
            search_radius_px: 24,
            initial_temperature: 4.0,
            cooling: 0.7,
            min_temperature: 0.05,
            max_iterations: 20,
            n_th_id: 1,
            n_th_mv: 1,
            v_diff_px: 1,
            min_overlap_px: 65,
            local_vector_tolerance_px: 0,
            border_blocks: 3,
            birth_min_blocks: 4,
            moving_fraction: 0.25,
            min_output_blocks: 2,
            // Choice: the MRF keeps the median start-up without shadow suppression or hold
            // (`BackgroundConfig::as_published`). With the detector's newer defaults its
            // occlusion scenarios lose ids (a parked-looking object held in the foreground
            // is split between regions) and on vtest.avi fewer walkers keep their ids from
            // frame 30 to 60; the MRF reads every foreground block, not regions, so it gains
            // little from them. `[background] startup = "persistent"` opts in.
            background: BackgroundConfig::default().as_published(),
        }
    }
}

impl crate::config::Validate for MrfConfig {
    fn validate(&self) -> crate::error::Result<()> {
        MrfConfig::validate(self)
    }
}

impl MrfConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<()> {
        let err = |field, reason: String| Err(Error::config("MrfConfig", field, reason));
        for (field, v) in [
            ("neighbour_weight", self.neighbour_weight),
            ("overlap_weight", self.overlap_weight),
            ("texture_weight", self.texture_weight),
            ("smoothness_weight", self.smoothness_weight),
            ("neighbour_target", self.neighbour_target),
            ("overlap_target", self.overlap_target),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return err(field, format!("must be finite and ≥ 0, found {v}"));
            }
        }
        if self.block_px != BLOCK_PX {
            return err(
                "block_px",
                format!("only {BLOCK_PX} is supported, found {}", self.block_px),
            );
        }
        if self.search_radius_px > 127 {
            return err(
                "search_radius_px",
                format!("must be ≤ 127, found {}", self.search_radius_px),
            );
        }
        if !(self.initial_temperature.is_finite() && self.initial_temperature > 0.0) {
            return err(
                "initial_temperature",
                format!("must be > 0, found {}", self.initial_temperature),
            );
        }
        if !(self.min_temperature.is_finite() && self.min_temperature > 0.0) {
            return err(
                "min_temperature",
                format!("must be > 0, found {}", self.min_temperature),
            );
        }
        if !(self.cooling > 0.0 && self.cooling <= 1.0) {
            return err(
                "cooling",
                format!("must be in (0, 1], found {}", self.cooling),
            );
        }
        if self.max_iterations == 0 {
            return err("max_iterations", "must be at least 1".into());
        }
        if let Err(m) = crate::limits::at_most(
            self.max_iterations,
            crate::limits::MAX_ITERATIONS,
            "iterations",
        ) {
            return err("max_iterations", m);
        }
        if !(self.moving_fraction > 0.0 && self.moving_fraction <= 1.0) {
            return err(
                "moving_fraction",
                format!("must be in (0, 1], found {}", self.moving_fraction),
            );
        }
        if self.birth_min_blocks == 0 {
            return err("birth_min_blocks", "must be at least 1".into());
        }
        self.background
            .validate()
            .map_err(|e| e.in_table("background"))
    }
}

/// What happened in one [`MrfTracker::step`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StepStats {
    /// Moving blocks in the frame.
    pub moving_blocks: u32,
    /// Blocks of `X(t − 1)` that were block-matched.
    pub matched_blocks: u32,
    /// Contested blocks the sampler optimised.
    pub sites: u32,
    /// The sampler's summary.
    pub gibbs: gibbs::GibbsStats,
    /// Objects born in this frame.
    pub births: u32,
    /// Objects alive after the frame.
    pub objects: u32,
}

/// Wall time spent in each stage of [`MrfTracker::step`], s (accumulated over calls; for
/// profiling, see docs/PERFORMANCE.md "MRF").
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct MrfStageTimes {
    /// RGB → luminance.
    pub luminance_s: f64,
    /// Background subtraction and moving blocks.
    pub background_s: f64,
    /// Step 1, block matching.
    pub matching_s: f64,
    /// Step 2, propagation (and the representative vectors).
    pub propagation_s: f64,
    /// Steps 3–5, the Gibbs sampler.
    pub gibbs_s: f64,
    /// Births, regions and output boxes.
    pub output_s: f64,
}

/// The spatio-temporal MRF tracker: one Object-map per frame.
#[derive(Debug, Clone)]
pub struct MrfTracker {
    config: MrfConfig,
    grid: BlockGrid,
    width: u32,
    height: u32,
    seed: u64,
    background: Option<BackgroundModel>,
    prev_gray: Option<GrayImage>,
    map: ObjectMap,
    /// Local vector each block of the current map carries (its motion from `t − 1` to `t`),
    /// used as the block-matching guess of the next frame.
    vectors: Vec<Option<Vector>>,
    motion: MotionMap,
    moving: Vec<bool>,
    next_id: ObjectId,
    stats: StepStats,
    times: MrfStageTimes,
}

impl MrfTracker {
    /// A tracker for `width × height` px frames. Without [`MrfTracker::set_background`],
    /// the background starts as the first frame.
    pub fn new(config: MrfConfig, width: u32, height: u32, seed: u64) -> Result<Self> {
        config.validate()?;
        let grid = BlockGrid::for_frame(width, height);
        if grid.is_empty() {
            return Err(Error::Invalid(format!(
                "frames of {width}×{height} px hold no {BLOCK_PX}×{BLOCK_PX} block"
            )));
        }
        Ok(Self {
            config,
            grid,
            width,
            height,
            seed,
            background: None,
            prev_gray: None,
            map: ObjectMap::empty(grid),
            vectors: vec![None; grid.len()],
            motion: MotionMap::empty(grid),
            moving: vec![false; grid.len()],
            next_id: 1,
            stats: StepStats::default(),
            times: MrfStageTimes::default(),
        })
    }

    /// Uses `model` (e.g. bootstrapped from a median of frames) as the background.
    pub fn set_background(&mut self, model: BackgroundModel) -> Result<()> {
        if model.size() != (self.width, self.height) {
            return Err(Error::FrameSize {
                frame: 0,
                got: model.size(),
                expected: (self.width, self.height),
            });
        }
        self.background = Some(model);
        Ok(())
    }

    /// The configuration.
    pub fn config(&self) -> &MrfConfig {
        &self.config
    }

    /// The current Object-map `X(t)`.
    pub fn object_map(&self) -> &ObjectMap {
        &self.map
    }

    /// The last Motion-Vector-map `V(t − 1; t)` on the grid of `t − 1` (block matching).
    pub fn motion_map(&self) -> &MotionMap {
        &self.motion
    }

    /// Which blocks of the last frame were moving.
    pub fn moving_blocks(&self) -> &[bool] {
        &self.moving
    }

    /// What the last step did.
    pub fn stats(&self) -> StepStats {
        self.stats
    }

    /// Wall time per stage accumulated over every [`MrfTracker::step`] so far.
    pub fn stage_times(&self) -> MrfStageTimes {
        self.times
    }

    /// Marks blocks whose foreground fraction reaches `moving_fraction`.
    fn moving_from_mask(&self, mask: &GrayImage) -> Vec<bool> {
        let cols = self.grid.cols as usize;
        let mut counts = vec![0u32; self.grid.len()];
        let stride = self.width as usize;
        let raw = mask.as_raw();
        for by in 0..self.grid.rows as usize {
            for r in 0..BLOCK_PX as usize {
                let row = &raw[(by * BLOCK_PX as usize + r) * stride..][..cols * BLOCK_PX as usize];
                for (bx, chunk) in row.chunks_exact(BLOCK_PX as usize).enumerate() {
                    counts[by * cols + bx] += chunk.iter().filter(|&&p| p != 0).count() as u32;
                }
            }
        }
        let need = (self.config.moving_fraction * f64::from(BLOCK_PX * BLOCK_PX)).ceil() as u32;
        counts.into_iter().map(|c| c >= need.max(1)).collect()
    }

    /// Tracks one frame: Steps 1–5 of METHODS.md §2, births and deaths. Returns a box per
    /// object of at least `min_output_blocks` blocks, sorted by id.
    ///
    /// # Errors
    /// The frame does not have the tracker's size.
    pub fn step(&mut self, frame: &Frame) -> Result<Vec<TrackPoint>> {
        if frame.size() != (self.width, self.height) {
            return Err(Error::FrameSize {
                frame: frame.index,
                got: frame.size(),
                expected: (self.width, self.height),
            });
        }
        let mut clock = std::time::Instant::now();
        let mut lap = |acc: &mut f64| {
            let now = std::time::Instant::now();
            *acc += (now - clock).as_secs_f64();
            clock = now;
        };
        let mut times = self.times;
        let gray = gray_from_rgb(&frame.image);
        lap(&mut times.luminance_s);
        let background = match self.background.as_mut() {
            Some(b) => b,
            None => self.background.insert(BackgroundModel::from_samples(
                std::slice::from_ref(&frame.image),
                self.config.background.clone(),
            )?),
        };
        let mask = background.apply(frame.index, &frame.image)?;
        let moving = self.moving_from_mask(&mask);
        lap(&mut times.background_s);
        let border = self.config.border_blocks;
        let mut stats = StepStats {
            moving_blocks: moving.iter().filter(|&&m| m).count() as u32,
            ..StepStats::default()
        };
        let (mut ids, mut vectors) = match self.prev_gray.as_ref() {
            None => (
                vec![NO_OBJECT; self.grid.len()],
                vec![None; self.grid.len()],
            ),
            Some(prev_gray) => {
                // Step 1: block matching of every labelled block of X(t − 1).
                let blocks: Vec<usize> = (0..self.grid.len())
                    .filter(|&i| self.map.ids[i] != NO_OBJECT)
                    .collect();
                let guesses: Vec<Vector> = blocks
                    .iter()
                    .map(|&i| self.vectors[i].unwrap_or([0, 0]))
                    .collect();
                let found = match_blocks(
                    prev_gray,
                    &gray,
                    self.grid.cols,
                    &blocks,
                    &guesses,
                    self.config.search_radius_px,
                );
                let mut matches: Vec<Option<BlockMatch>> = vec![None; self.grid.len()];
                let mut motion = MotionMap::empty(self.grid);
                for (&b, m) in blocks.iter().zip(found) {
                    matches[b] = Some(m);
                    motion.vectors[b] = Some(m.vector);
                }
                stats.matched_blocks = blocks.len() as u32;
                lap(&mut times.matching_s);
                // Step 2.
                let p = propagate::propagate(
                    &self.map,
                    &matches,
                    &moving,
                    border,
                    self.config.min_overlap_px,
                );
                let (mut ids, mut vectors) = (p.ids, p.vectors);
                // Steps 3–5.
                let representative = gibbs::representative_vectors(&self.map, &motion.vectors);
                let ctx = gibbs::Context {
                    prev_gray,
                    cur_gray: &gray,
                    prev_map: &self.map,
                    config: &self.config,
                    representative: &representative,
                    seed: self.seed,
                    frame: frame.index,
                };
                stats.sites = p.sites.len() as u32;
                lap(&mut times.propagation_s);
                stats.gibbs = gibbs::optimise(&ctx, &p.sites, &mut ids, &mut vectors);
                lap(&mut times.gibbs_s);
                self.motion = motion;
                (ids, vectors)
            }
        };
        let born = propagate::births(
            &mut ids,
            &self.grid,
            &moving,
            border,
            self.config.birth_min_blocks,
            &mut self.next_id,
        );
        for (i, id) in ids.iter().enumerate() {
            if *id == NO_OBJECT {
                vectors[i] = None;
            }
        }
        stats.births = born.len() as u32;
        self.map = ObjectMap {
            grid: self.grid,
            ids,
        };
        self.vectors = vectors;
        self.moving = moving;
        self.prev_gray = Some(gray);
        let regions = self.map.regions();
        stats.objects = regions.len() as u32;
        self.stats = stats;
        let out = regions
            .into_iter()
            .filter(|r| r.area_blocks >= self.config.min_output_blocks)
            .map(|r| TrackPoint {
                frame: frame.index,
                time_s: frame.time_s,
                id: u64::from(r.id),
                // Choice: the tracker does not classify (a size rule would need a camera
                // model); every object is Unknown.
                class: ObjectClass::Unknown,
                bbox: r.bbox,
                score: 1.0,
                ground: None,
            })
            .collect();
        lap(&mut times.output_s);
        self.times = times;
        Ok(out)
    }
}

impl crate::track::Tracker for MrfTracker {
    /// Tracks from the pixels alone (Steps 1–5 of METHODS.md §2); `detections` are not used
    /// by seed 002's model.
    fn step(
        &mut self,
        frame: &Frame,
        _detections: &crate::detect::FrameDetections,
    ) -> Result<Vec<crate::track::FramePoints>> {
        let points = MrfTracker::step(self, frame)?;
        Ok(vec![crate::track::FramePoints::new(frame, points)])
    }

    fn finish(&mut self) -> Result<Vec<crate::track::FramePoints>> {
        Ok(Vec::new())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers() {
        let c = MrfConfig::default(); // METHODS.md §2
        assert_eq!(
            (
                c.neighbour_weight,
                c.overlap_weight,
                c.texture_weight,
                c.smoothness_weight
            ),
            (0.5, 1.0 / 256.0, 32e-6, 0.25)
        );
        assert_eq!((c.neighbour_target, c.overlap_target), (8.0, 64.0));
        assert_eq!(
            (c.block_px, c.search_radius_px, c.border_blocks),
            (8, 24, 3)
        );
        assert_eq!(c.variant, MrfVariant::Improved);
        assert!(c.validate().is_ok());
    }

    #[test]
    fn config_reads_from_toml_and_rejects_typos() -> Result<()> {
        let c: MrfConfig = toml::from_str("variant = \"legacy\"\nsearch_radius_px = 16\n")
            .map_err(|e| Error::Invalid(e.to_string()))?;
        assert_eq!(c.variant, MrfVariant::Legacy);
        assert_eq!(c.search_radius_px, 16);
        assert!(toml::from_str::<MrfConfig>("serch_radius_px = 16").is_err());
        let bad = MrfConfig {
            block_px: 16,
            ..MrfConfig::default()
        };
        assert!(bad.validate().is_err());
        Ok(())
    }
}
