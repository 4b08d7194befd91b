//! Moving-object extraction for fixed cameras (`roadtrack detect`): background model →
//! foreground mask → clean-up → regions → detections with centre, box, area, mean colour.

use super::FrameDetections;
use super::regions::{Region, RegionConfig, clean_mask, extract_regions_split};
use super::split::{PersonSize, SplitConfig, Splitter};
use crate::calibration::Calibration;
use crate::detect::background_model::{BackgroundConfig, BackgroundModel, sample_frames};
use crate::detection::Detection;
use crate::error::Result;
use crate::frame::Frame;
use image::{GrayImage, RgbImage};
use serde::{Deserialize, Serialize};

/// Parameters of foreground extraction.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BackgroundDetectorConfig {
    /// The background model.
    pub background: BackgroundConfig,
    /// Mask clean-up and region size limits.
    pub regions: RegionConfig,
    /// Splitting regions that hold several vehicles (needs `calibration`) or people side by
    /// side (`columns`).
    pub split: SplitConfig,
    /// Dots found beside another detector (`--dots`, [`super::dots::WithDots`]) against
    /// this background model. `[dots]` in the TOML.
    pub dots: super::dots::DotConfig,
    /// Boxes fitted to the pixels that differ from this background model
    /// (`--refine-boxes`, [`super::refine::RefinedBoxes`]). `[refine]` in the TOML.
    pub refine: super::refine::RefineConfig,
    /// The camera's ground calibration, when known (`--calibration`; not part of the TOML):
    /// gives the expected vehicle size for [`SplitConfig`] and the person size for
    /// `regions.min_person_share`.
    #[serde(skip)]
    pub calibration: Option<Box<Calibration>>,
}

impl crate::config::Validate for BackgroundDetectorConfig {
    fn validate(&self) -> crate::error::Result<()> {
        BackgroundDetectorConfig::validate(self)
    }
}

impl BackgroundDetectorConfig {
    /// Checks every field.
    pub fn validate(&self) -> Result<()> {
        self.background
            .validate()
            .map_err(|e| e.in_table("background"))?;
        self.regions.validate().map_err(|e| e.in_table("regions"))?;
        self.split.validate().map_err(|e| e.in_table("split"))?;
        self.dots.validate().map_err(|e| e.in_table("dots"))?;
        self.refine.validate().map_err(|e| e.in_table("refine"))
    }

    /// The same config with the detector's later additions off (median start-up, no
    /// shadow suppression, no hold, no ghost suppression, no splitting, no age cut, no
    /// person share, centroid as the centre): the detector `--as-published` runs use.
    pub fn as_published(mut self) -> Self {
        self.regions.min_person_share = 0.0;
        self.background = self.background.as_published();
        self.split.enabled = false;
        self.split.columns = false;
        self.regions.position = super::regions::RegionPosition::Centroid;
        self.regions.age_gap_s = 0.0;
        self
    }
}

/// The foreground of one frame: the cleaned mask and the regions in it.
#[derive(Debug, Clone)]
pub struct Foreground {
    /// The cleaned foreground mask (255 = foreground).
    pub mask: GrayImage,
    /// The regions kept, in raster order of their first pixel.
    pub regions: Vec<Region>,
}

/// Background subtraction and region extraction over a sequence.
#[derive(Debug, Clone)]
pub struct BackgroundDetector {
    config: BackgroundDetectorConfig,
    model: BackgroundModel,
    /// Made on the first frame from the calibration (needs the image size).
    splitter: Option<Splitter>,
    /// For `regions.min_person_share`, when it is set and there is a calibration.
    person: Option<PersonSize>,
    /// The region settings regions are extracted (and ghosts looked for) with:
    /// `config.regions` with the area floor lowered to `person_min_area_px` when `person`
    /// is there (the rest of the floor is applied with the person share, [`person_sized`]).
    extract: super::regions::RegionConfig,
    /// How long each pixel has been foreground, for `regions.age_gap_s`.
    ages: super::age_cut::AgeMap,
}

impl BackgroundDetector {
    /// A detector whose background starts as the median of `samples`.
    pub fn new(config: BackgroundDetectorConfig, samples: &[RgbImage]) -> Result<Self> {
        config.validate()?;
        let model = BackgroundModel::from_samples(samples, config.background.clone())?;
        Ok(Self::assemble(config, model))
    }

    /// A detector over an existing background model (e.g. from
    /// [`super::background_model::bootstrap_from_source`]).
    ///
    /// # Errors
    /// An invalid config.
    pub fn with_model(config: BackgroundDetectorConfig, model: BackgroundModel) -> Result<Self> {
        config.validate()?;
        Ok(Self::assemble(config, model))
    }

    fn assemble(config: BackgroundDetectorConfig, model: BackgroundModel) -> Self {
        let (w, h) = model.size();
        let splitter = match (&config.calibration, config.split.enabled) {
            (Some(cal), true) => Some(Splitter::new(config.split.clone(), (**cal).clone(), w, h)),
            _ => None,
        };
        let person = match &config.calibration {
            Some(cal) if config.regions.min_person_share > 0.0 => {
                Some(PersonSize::new((**cal).clone(), w, h))
            }
            _ => None,
        };
        let mut extract = config.regions.clone();
        if person.is_some() && extract.person_min_area_px > 0 {
            extract.min_area_px = extract.min_area_px.min(extract.person_min_area_px);
        }
        Self {
            config,
            model,
            splitter,
            person,
            extract,
            ages: super::age_cut::AgeMap::default(),
        }
    }

    /// A detector bootstrapped from a frame source: reads `frames` (normally a first pass
    /// over the same source; `total` frames if known) and keeps
    /// `config.background.bootstrap_frames` of them spread evenly.
    pub fn bootstrap(
        config: BackgroundDetectorConfig,
        frames: impl Iterator<Item = Result<Frame>>,
        total: Option<u32>,
    ) -> Result<Self> {
        config.validate()?;
        let samples = sample_frames(frames, total, config.background.bootstrap_frames)?;
        Self::new(config, &samples)
    }

    /// A detector bootstrapped by a first, read-only pass over `input` (see
    /// [`BackgroundDetector::bootstrap`]).
    pub fn bootstrap_source(
        config: BackgroundDetectorConfig,
        input: &std::path::Path,
        options: &crate::io::SourceOptions,
    ) -> Result<Self> {
        config.validate()?;
        let model = crate::detect::background_model::bootstrap_from_source(
            input,
            options,
            config.background.clone(),
        )?;
        Ok(Self::assemble(config, model))
    }

    /// The background model.
    pub fn background(&self) -> &BackgroundModel {
        &self.model
    }

    /// Runs on one frame and updates the background: classify, clean the mask, drop and
    /// repair ghosts ([`super::ghosts`]), learn outside the held (cleaned) foreground, then
    /// regions (split by the calibration's expected vehicle size when there is one).
    pub fn process(&mut self, frame: &Frame) -> Result<Foreground> {
        let raw = self.model.classify(frame.index, &frame.image)?;
        let mut mask = clean_mask(&raw, &self.config.regions);
        super::ghosts::suppress(
            &mut self.model,
            &mut mask,
            None,
            &frame.image,
            frame.time_s,
            self.extract.min_area_px,
        );
        self.model
            .update_held(frame.index, &frame.image, &mask, frame.time_s)?;
        let gap = self.config.regions.age_gap_s;
        let mut cut = (gap > 0.0)
            .then(|| {
                self.ages
                    .update(&mask, frame.time_s, self.config.regions.age_grace_s);
                self.ages
                    .cut(&mask, gap as f32, self.config.regions.age_min_piece_px)
            })
            .flatten();
        if let Some(pieces) = cut.as_mut() {
            // Choice: the ghost test again on the age cut's pieces. A ghost beside a vehicle
            // that queued there later is one region with it in the cleaned mask, and the
            // vehicle's edges on that region's outline pass the test; cut at the age jump,
            // the ghost is a piece of its own (docs/DETECTION.md "Ghosts"). Only a piece's
            // outline against the background counts: a cut through a vehicle that moved up
            // in a queue (its older part a piece) shows no edge in the frame.
            let ghosts = super::ghosts::suppress(
                &mut self.model,
                pieces,
                Some(&mask),
                &frame.image,
                frame.time_s,
                self.extract.min_area_px,
            );
            for runs in &ghosts {
                super::ghosts::clear_runs(&mut mask, runs);
            }
        }
        let mut regions = extract_regions_split(
            cut.as_ref().unwrap_or(&mask),
            &frame.image,
            &self.extract,
            self.splitter.as_ref(),
            self.config.split.columns.then_some(&self.config.split),
        );
        if let Some(person) = &self.person {
            let (share, floor) = (
                self.config.regions.min_person_share,
                self.config.regions.min_area_px,
            );
            regions.retain(|r| person_sized(person, share, floor, r));
        }
        Ok(Foreground { mask, regions })
    }

    /// Runs on one frame and returns detections numbered 1.. in raster order.
    pub fn detect(&mut self, frame: &Frame) -> Result<Vec<Detection>> {
        Ok(self.detect_with_mask(frame)?.detections)
    }

    /// Runs on one frame: detections numbered 1.. in raster order, and the cleaned mask.
    pub fn detect_with_mask(&mut self, frame: &Frame) -> Result<FrameDetections> {
        let found = self.process(frame)?;
        let position = self.config.regions.position;
        Ok(FrameDetections {
            detections: found
                .regions
                .iter()
                .enumerate()
                .map(|(i, r)| r.to_detection(frame.index, i as u64 + 1, position))
                .collect(),
            foreground: Some(found.mask),
        })
    }
}

impl super::Detector for BackgroundDetector {
    fn detect(&mut self, frame: &Frame) -> Result<FrameDetections> {
        self.detect_with_mask(frame)
    }
}

/// Whether region `r`'s box covers at least `share` of the box of a person standing at its
/// foot point (`regions.min_person_share`). Where no person size is known there, whether it
/// has `min_area_px` pixels (the floor of regions without the person share).
// Choice: the region's box, not its pixel count, is compared with the person's box: a
// walker's mask fills a varying share of its box (legs apart or together).
fn person_sized(person: &PersonSize, share: f64, min_area_px: u32, r: &Region) -> bool {
    let b = &r.bbox;
    let foot = crate::geometry::Point::new(b.left + b.width / 2.0, b.top + b.height);
    match person.box_area_px(foot) {
        Some(a) => b.width * b.height >= share * a,
        None => r.area_px >= min_area_px,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    /// Frames 1..=n at 10 frames/s, frame `i` drawn by `draw(i)`.
    fn frames_at_10_fps(n: u32, draw: impl Fn(u32) -> RgbImage) -> Vec<Frame> {
        (1..=n)
            .map(|i| Frame {
                index: i,
                time_s: f64::from(i - 1) / 10.0,
                image: draw(i),
            })
            .collect()
    }

    /// A 640 × 480 grey road with red blocks `(left, top, width, height)`, px.
    fn road_with_blocks(blocks: &[(u32, u32, u32, u32)]) -> RgbImage {
        let mut img = RgbImage::from_pixel(640, 480, Rgb([90, 90, 90]));
        for &(x0, y0, w, h) in blocks {
            for y in y0..y0 + h {
                for x in x0..x0 + w {
                    img.put_pixel(x, y, Rgb([200, 60, 40]));
                }
            }
        }
        img
    }

    /// Detections per frame of a detector with `cfg`, started from all of `frames`.
    fn detections_per_frame(cfg: BackgroundDetectorConfig, frames: &[Frame]) -> Result<Vec<usize>> {
        let total = Some(frames.len() as u32);
        let mut det = BackgroundDetector::bootstrap(cfg, frames.iter().cloned().map(Ok), total)?;
        frames.iter().map(|f| Ok(det.detect(f)?.len())).collect()
    }

    /// Frames of a grey background with `n` coloured 8×8 squares moving right 2 px/frame.
    fn scene(n: u32, frames: u32) -> Vec<Frame> {
        frames_at_10_fps(frames, |i| {
            let mut img = RgbImage::from_pixel(96, 64, Rgb([90, 90, 90]));
            for k in 0..n {
                let x0 = 4 + 2 * i + 20 * k;
                let y0 = 8 + 16 * k;
                for y in y0..y0 + 8 {
                    for x in x0..x0 + 8 {
                        img.put_pixel(x % 96, y, Rgb([200, 40 + 50 * k as u8, 40]));
                    }
                }
            }
            img
        })
    }

    #[test]
    fn finds_every_moving_square_in_every_frame() -> Result<()> {
        let frames = scene(3, 12);
        let cfg = BackgroundDetectorConfig::default();
        let mut det = BackgroundDetector::bootstrap(cfg, frames.iter().cloned().map(Ok), Some(12))?;
        for f in &frames {
            let d = det.detect(f)?;
            assert_eq!(d.len(), 3, "frame {}", f.index);
            for (k, dd) in d.iter().enumerate() {
                let expected_x = 4.0 + 2.0 * f64::from(f.index) + 20.0 * k as f64 + 4.0;
                assert!(
                    (dd.pos_px.x - expected_x).abs() < 1e-9,
                    "frame {} square {k}: {:?}",
                    f.index,
                    dd.pos_px
                );
                assert_eq!(dd.size_px, Some((8.0, 8.0)));
            }
        }
        Ok(())
    }

    /// With a calibration, `min_person_share` drops a region much smaller than a person
    /// standing there and keeps a person-sized one; without the setting both stay.
    #[test]
    fn min_person_share_drops_pieces_smaller_than_a_person_there() -> Result<()> {
        let (cal, _) = crate::detect::split::tests::pinhole();
        let person = PersonSize::new(cal.clone(), 640, 480);
        let foot_y = 400u32;
        let area = person
            .box_area_px(crate::geometry::Point::new(200.0, f64::from(foot_y)))
            .expect("ground seen");
        // A person's box (0.4 H × H) and a piece 0.3 H square: 0.225 of the person's box.
        let h = (area / crate::detect::split::PERSON_WIDTH_SHARE).sqrt();
        let (pw, ph, piece) = ((0.4 * h) as u32, h as u32, (0.3 * h) as u32);
        let frames = frames_at_10_fps(20, |i| {
            road_with_blocks(&[
                (100 + 3 * i, foot_y - ph, pw, ph),
                (400 + 3 * i, foot_y - piece, piece, piece),
            ])
        });
        let run = |share: f64| -> Result<Vec<usize>> {
            let mut cfg = BackgroundDetectorConfig::default();
            cfg.regions.min_person_share = share;
            cfg.calibration = Some(Box::new(cal.clone()));
            detections_per_frame(cfg, &frames)
        };
        assert!(run(0.0)?.iter().all(|&n| n == 2), "both kept when off");
        let on = run(0.25)?;
        assert!(on.iter().all(|&n| n == 1), "only the person kept: {on:?}");
        // On by default; off as published.
        let cfg = BackgroundDetectorConfig {
            calibration: Some(Box::new(cal.clone())),
            ..Default::default()
        };
        let default = detections_per_frame(cfg.clone(), &frames)?;
        assert!(default.iter().all(|&n| n == 1), "default: {default:?}");
        let published = detections_per_frame(cfg.as_published(), &frames)?;
        assert!(
            published.iter().all(|&n| n == 2),
            "as published: {published:?}"
        );
        Ok(())
    }

    /// A row far from the pinhole test camera where a standing person's box is 30–50 px²,
    /// and that person's box width and height there, px.
    fn far_person(cal: &crate::calibration::Calibration) -> (u32, u32, u32) {
        let person = PersonSize::new(cal.clone(), 640, 480);
        let at = |y: u32| person.box_area_px(crate::geometry::Point::new(300.0, f64::from(y)));
        let foot_y = (0..480u32)
            .rev()
            .find(|&y| at(y).is_some_and(|a| (30.0..=50.0).contains(&a)))
            .expect("a far row");
        let h = (at(foot_y).expect("far row") / crate::detect::split::PERSON_WIDTH_SHARE).sqrt();
        (foot_y, (0.4 * h).round() as u32, h.round() as u32)
    }

    /// A far person, a region of fewer pixels than `min_area_px` but person-sized for where
    /// it stands, is kept with the person share on (its floor `person_min_area_px`); a speck
    /// as small where no person size is known (above the horizon) is not.
    #[test]
    fn a_far_person_under_the_area_floor_is_kept_by_the_person_share() -> Result<()> {
        let (cal, _) = crate::detect::split::tests::pinhole();
        let (foot_y, pw, ph) = far_person(&cal);
        assert!(pw * ph < 60, "{pw} × {ph}");
        // A row above the horizon: no person size known there.
        let person = PersonSize::new(cal.clone(), 640, 480);
        let sky_y = (0..480u32)
            .find(|&y| {
                person
                    .box_area_px(crate::geometry::Point::new(300.0, f64::from(y)))
                    .is_none()
            })
            .expect("a row above the horizon");
        for x in [400.0, 450.0] {
            let foot = crate::geometry::Point::new(x, f64::from(sky_y + ph));
            assert!(
                person.box_area_px(foot).is_none(),
                "the speck's foot {foot:?}"
            );
        }
        let frames = frames_at_10_fps(20, |i| {
            road_with_blocks(&[
                (100 + 2 * i, foot_y - ph, pw, ph),
                (400 + 2 * i, sky_y, pw, ph),
            ])
        });
        let run = |floor: u32| -> Result<Vec<usize>> {
            let mut cfg = BackgroundDetectorConfig::default();
            cfg.regions.min_person_share = 0.4;
            cfg.regions.person_min_area_px = floor;
            cfg.regions.open_radius_px = 0;
            cfg.calibration = Some(Box::new(cal.clone()));
            detections_per_frame(cfg, &frames)
        };
        assert!(run(0)?.iter().all(|&n| n == 0), "both under min_area_px");
        let on = run(20)?;
        assert!(on.iter().all(|&n| n == 1), "the far person kept: {on:?}");
        Ok(())
    }

    /// The ghost of a far person (one who stood through the start-up and then left) is
    /// under `min_area_px` but above `person_min_area_px`: with the person share on it is
    /// a region, and the ghost test, which looks at regions down to the same floor, drops
    /// it after `ghost_still_s`.
    #[test]
    fn a_far_persons_ghost_under_the_area_floor_is_dropped() -> Result<()> {
        let (cal, _) = crate::detect::split::tests::pinhole();
        let (foot_y, pw, ph) = far_person(&cal);
        let road = road_with_blocks(&[]);
        let standing = road_with_blocks(&[(300, foot_y - ph, pw, ph)]);
        // Four start-up samples of five with the person: the background holds them.
        let boot = [&standing, &standing, &road, &standing, &standing].map(|i| i.clone());
        let run = |ghost_edge_ratio: f64| -> Result<Vec<usize>> {
            let mut cfg = BackgroundDetectorConfig::default();
            cfg.regions.min_person_share = 0.4;
            cfg.regions.person_min_area_px = 20;
            cfg.background.ghost_edge_ratio = ghost_edge_ratio;
            cfg.calibration = Some(Box::new(cal.clone()));
            let mut det = BackgroundDetector::new(cfg, &boot)?;
            frames_at_10_fps(20, |_| road.clone())
                .iter()
                .map(|f| Ok(det.detect(f)?.len()))
                .collect()
        };
        assert!(
            run(0.0)?.iter().all(|&n| n == 1),
            "the ghost stays without the test"
        );
        let on = run(0.5)?;
        assert_eq!(on[0], 1, "a region at first: {on:?}");
        assert!(on[10..].iter().all(|&n| n == 0), "then dropped: {on:?}");
        Ok(())
    }

    /// A block drives in, waits 3 s and leaves; while it waits a smaller block walks down
    /// past its right side, touching it. Without the age cut the two are one region in the
    /// frames where they touch; with it, two.
    #[test]
    fn a_walker_passing_a_waiting_vehicle_is_cut_from_it_by_age() -> Result<()> {
        let frames = frames_at_10_fps(80, |i| {
            let mut img = RgbImage::from_pixel(120, 80, Rgb([90, 90, 90]));
            // The vehicle: 24 × 12 px, x0 = 3i − 24 until it stops at 6 (frame 10), leaves
            // from frame 40.
            let x0 = match i {
                ..=10 => 3 * i as i32 - 24,
                11..=40 => 6,
                _ => 6 + 3 * (i as i32 - 40),
            };
            // The walker: 6 × 16 px at x 30–35, its top at y = 2i − 36 (down 2 px per
            // frame).
            let y0 = 2 * i as i32 - 36;
            for y in 0..80i32 {
                for x in 0..120i32 {
                    let car = (x0..x0 + 24).contains(&x) && (30..42).contains(&y);
                    let walker = (30..36).contains(&x) && (y0..y0 + 16).contains(&y);
                    if car {
                        img.put_pixel(x as u32, y as u32, Rgb([200, 40, 40]));
                    } else if walker {
                        img.put_pixel(x as u32, y as u32, Rgb([40, 40, 200]));
                    }
                }
            }
            img
        });
        let run = |gap: f64| -> Result<Vec<usize>> {
            let mut cfg = BackgroundDetectorConfig::default();
            cfg.regions.age_gap_s = gap;
            cfg.regions.min_area_px = 20;
            detections_per_frame(cfg, &frames)
        };
        let (joined, cut) = (run(0.0)?, run(1.0)?);
        // Frames 27–33: the walker's rows overlap the vehicle's (30–41) and its columns touch
        // the vehicle's right edge (x 29).
        for i in 27..=33usize {
            assert_eq!(joined[i - 1], 1, "frame {i} without the cut: {joined:?}");
            assert_eq!(cut[i - 1], 2, "frame {i} with the cut: {cut:?}");
        }
        // Frame 20: the walker is still 10 rows above the waiting vehicle: two regions
        // either way, the vehicle not cut along its own pixels.
        assert_eq!((joined[19], cut[19]), (2, 2));
        Ok(())
    }

    #[test]
    fn an_age_gap_below_zero_is_refused_by_name() {
        let mut cfg = BackgroundDetectorConfig::default();
        cfg.regions.age_gap_s = -1.0;
        let e = cfg.validate().expect_err("refused").to_string();
        assert!(e.contains("regions.age_gap_s"), "{e}");
    }

    #[test]
    fn a_person_share_outside_zero_to_one_is_refused_by_name() {
        for bad in [-0.1, 1.5, f64::NAN] {
            let mut cfg = BackgroundDetectorConfig::default();
            cfg.regions.min_person_share = bad;
            let e = cfg.validate().expect_err("refused").to_string();
            assert!(e.contains("regions.min_person_share"), "{e}");
        }
    }

    /// The per-pixel passes split the frame over the threads (large frames only): detections,
    /// masks and the learnt background are the same at 1 and 2 threads.
    #[test]
    fn same_output_at_one_and_two_threads() -> Result<()> {
        let frames = roadtrack_sim::testkit::moving_boxes(400, 240, 30, 6);
        let run = |threads: usize| -> Result<(Vec<FrameDetections>, RgbImage)> {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| crate::Error::Invalid(e.to_string()))?;
            pool.install(|| {
                let cfg = BackgroundDetectorConfig::default();
                let mut det =
                    BackgroundDetector::bootstrap(cfg, frames.iter().cloned().map(Ok), Some(30))?;
                let out = frames
                    .iter()
                    .map(|f| det.detect_with_mask(f))
                    .collect::<Result<Vec<_>>>()?;
                Ok((out, det.background().background()))
            })
        };
        let (one, bg_one) = run(1)?;
        let (two, bg_two) = run(2)?;
        let found: usize = one.iter().map(|f| f.detections.len()).sum();
        assert!(found >= 100, "{found} detections");
        assert_eq!(one, two);
        assert_eq!(bg_one, bg_two);
        Ok(())
    }
}
