//! Scenario tests of the MRF tracker on small synthetic scenes with known truth.

use super::object_map::{NO_OBJECT, ObjectId, ObjectMap};
use super::separation::{TruthRegion, occlusion_rows};
use super::{MrfConfig, MrfTracker, MrfVariant};
use crate::detect::background_model::{BackgroundModel, bootstrap_from_frames};
use crate::error::Result;
use crate::eval::papers::separation_success;
use crate::frame::Frame;
use image::RgbImage;
use roadtrack_sim::testkit::{RectTruth, SynthObject, SynthScene, SynthSequence};
use std::collections::BTreeMap;

/// Tracks `frames` with a background learnt from `empty` (the scene without objects: in a
/// converging group the median of the sequence itself would hold objects); returns every map.
pub(crate) fn run(
    config: &MrfConfig,
    frames: &[Frame],
    empty: &RgbImage,
    seed: u64,
) -> Result<Vec<ObjectMap>> {
    let background =
        BackgroundModel::from_samples(std::slice::from_ref(empty), config.background.clone())?;
    run_with_background(config, frames, background, seed)
}

/// Tracks `frames` with a given background model; returns every map.
pub(crate) fn run_with_background(
    config: &MrfConfig,
    frames: &[Frame],
    background: BackgroundModel,
    seed: u64,
) -> Result<Vec<ObjectMap>> {
    let (w, h) = frames[0].size();
    let mut t = MrfTracker::new(config.clone(), w, h, seed)?;
    t.set_background(background)?;
    let mut maps = Vec::new();
    for f in frames {
        t.step(f)?;
        maps.push(t.object_map().clone());
    }
    Ok(maps)
}

/// Frames `1..=n` of `seq` with the truth on the tracker's block grid: a block is visible for
/// an object when at least half of its pixels show that object.
fn block_truth(seq: &SynthSequence, n: u32) -> (Vec<Frame>, Vec<Vec<TruthRegion>>) {
    let (frames, truth) = seq.frames(n);
    (frames, truth.iter().map(block_regions).collect())
}

fn block_regions(t: &RectTruth) -> Vec<TruthRegion> {
    use super::object_map::{BLOCK_PX, BlockGrid};
    let grid = BlockGrid::for_frame(t.width, t.height);
    let mut counts: std::collections::BTreeMap<u64, Vec<u32>> = t
        .objects
        .iter()
        .map(|o| (o.id, vec![0u32; grid.len()]))
        .collect();
    for (p, id) in t.owner.iter().enumerate() {
        let Some(c) = id.and_then(|id| counts.get_mut(&id)) else {
            continue;
        };
        let (x, y) = ((p as u32) % t.width, (p as u32) / t.width);
        if let Some((bx, by)) = grid.blocks_from_px(x, y) {
            c[grid.index(bx, by)] += 1;
        }
    }
    let half = BLOCK_PX * BLOCK_PX / 2;
    t.objects
        .iter()
        .map(|o| TruthRegion {
            id: o.id,
            bbox: o.bbox,
            visible_blocks: counts[&o.id]
                .iter()
                .enumerate()
                .filter(|(_, c)| **c >= half)
                .map(|(i, _)| i)
                .collect(),
            occluded: o.occluded,
        })
        .collect()
}

/// The output id covering most of each truth object's visible blocks (None when none).
pub(crate) fn dominant_ids(
    truth: &[TruthRegion],
    map: &ObjectMap,
) -> BTreeMap<u64, Option<ObjectId>> {
    truth
        .iter()
        .map(|r| {
            let mut count: BTreeMap<ObjectId, u32> = BTreeMap::new();
            for &b in &r.visible_blocks {
                if map.ids[b] != NO_OBJECT {
                    *count.entry(map.ids[b]).or_insert(0) += 1;
                }
            }
            let best = count
                .into_iter()
                .max_by_key(|&(id, n)| (n, std::cmp::Reverse(id)))
                .map(|(id, _)| id);
            (r.id, best)
        })
        .collect()
}

fn obj(id: u64, left: f64, top: f64, w: u32, h: u32, v: (f64, f64), depth: u32) -> SynthObject {
    SynthObject {
        id,
        left_px: left,
        top_px: top,
        width_px: w,
        height_px: h,
        velocity_px_per_frame: v,
        depth,
    }
}

/// Two 64 × 40 px objects on crossing paths, 16 px apart vertically: the front one hides
/// 60 % of the back one's height while they pass.
pub(crate) fn crossing_scene() -> SynthScene {
    SynthScene {
        width: 320,
        height: 160,
        objects: vec![
            obj(1, 40.0, 50.0, 64, 40, (4.0, 0.0), 0),
            obj(2, 216.0, 66.0, 64, 40, (-4.0, 0.0), 1),
        ],
        noise: 2,
    }
}

/// Three 32 × 80 px "pedestrians" walking side by side to the right; the faster ones
/// behind catch up and are partly hidden by the slower ones in front (the paper's "moving
/// side by side" case).
pub(crate) fn side_by_side_scene() -> SynthScene {
    SynthScene {
        width: 400,
        height: 160,
        objects: vec![
            obj(1, 30.0, 40.0, 32, 80, (4.0, 0.0), 2),
            obj(2, 78.0, 46.0, 32, 80, (3.0, 0.0), 1),
            obj(3, 126.0, 38.0, 32, 80, (2.0, 0.0), 0),
        ],
        noise: 2,
    }
}

/// Four 32 × 80 px "pedestrians" converging into a group and passing each other.
pub(crate) fn group_scene() -> SynthScene {
    SynthScene {
        width: 400,
        height: 160,
        objects: vec![
            obj(1, 30.0, 40.0, 32, 80, (4.0, 0.0), 0),
            obj(2, 100.0, 46.0, 32, 80, (2.0, 0.0), 1),
            obj(3, 240.0, 38.0, 32, 80, (-2.0, 0.0), 2),
            obj(4, 320.0, 44.0, 32, 80, (-4.0, 0.0), 3),
        ],
        noise: 2,
    }
}

/// Objects 1 and 2 carry two distinct output ids at frame index `from` and the same two
/// at frame index `to` (ids from the majority of each object's visible blocks).
fn assert_two_ids_kept(
    variant: MrfVariant,
    truth: &[Vec<TruthRegion>],
    maps: &[ObjectMap],
    from: usize,
    to: usize,
) {
    let first = dominant_ids(&truth[from], &maps[from]);
    let last = dominant_ids(&truth[to], &maps[to]);
    let (a, b) = (first[&1], first[&2]);
    assert!(
        a.is_some() && b.is_some() && a != b,
        "{variant:?}: ids at frame index {from}: {first:?}"
    );
    assert_eq!(
        last[&1], a,
        "{variant:?}: object 1 changed id by frame index {to}"
    );
    assert_eq!(
        last[&2], b,
        "{variant:?}: object 2 changed id by frame index {to}"
    );
}

#[test]
fn crossing_objects_keep_distinct_ids_through_partial_occlusion() -> Result<()> {
    for variant in [MrfVariant::Improved, MrfVariant::Legacy] {
        let seq = crossing_scene().build(11);
        let (frames, truth) = block_truth(&seq, 44);
        let cfg = MrfConfig {
            variant,
            ..MrfConfig::default()
        };
        let maps = run(&cfg, &frames, &seq.empty_frame(), 5)?;
        assert_two_ids_kept(variant, &truth, &maps, 1, 43);
        // While they overlap, each is still its own region in (nearly) every frame.
        let curve = separation_success(&occlusion_rows(&truth, &maps), Some(1));
        assert!(curve[0].n >= 10, "{variant:?}: {curve:?}");
        assert!(curve[0].success_rate >= 0.95, "{variant:?}: {curve:?}");
    }
    Ok(())
}

#[test]
fn pedestrian_group_is_not_merged_when_visible_areas_are_at_least_ten_blocks() -> Result<()> {
    // The improved variant passes since its vector proposals are bounded around each
    // object's representative vector (`local_vector_tolerance_px`, `gibbs::proposals`).
    for variant in [MrfVariant::Improved, MrfVariant::Legacy] {
        let seq = side_by_side_scene().build(21);
        let (frames, truth) = block_truth(&seq, 40);
        let cfg = MrfConfig {
            variant,
            ..MrfConfig::default()
        };
        let maps = run(&cfg, &frames, &seq.empty_frame(), 9)?;
        let curve = separation_success(&occlusion_rows(&truth, &maps), Some(10));
        let big = &curve[9];
        assert!(big.n >= 20, "{variant:?}: {curve:?}");
        assert_eq!(
            big.separated, big.n,
            "{variant:?}: a ≥ 10-block object was absorbed: {curve:?}"
        );
        let first = dominant_ids(&truth[1], &maps[1]);
        let distinct: std::collections::BTreeSet<_> = first.values().flatten().collect();
        assert_eq!(distinct.len(), 3, "{variant:?}: {first:?}");
    }
    Ok(())
}

/// Prints the separation curves of both variants on the side-by-side scene.
#[test]
#[ignore = "measurement for docs/MRF.md; prints the separation curves"]
fn side_by_side_curves() -> Result<()> {
    for (variant, tol) in [
        (MrfVariant::Improved, 0),
        (MrfVariant::Improved, 1),
        (MrfVariant::Improved, 48),
        (MrfVariant::Legacy, 0),
    ] {
        let seq = side_by_side_scene().build(21);
        let (frames, truth) = block_truth(&seq, 40);
        let cfg = MrfConfig {
            variant,
            local_vector_tolerance_px: tol,
            ..MrfConfig::default()
        };
        let maps = run(&cfg, &frames, &seq.empty_frame(), 9)?;
        let curve = separation_success(&occlusion_rows(&truth, &maps), Some(10));
        let line: Vec<String> = curve
            .iter()
            .map(|b| format!("{}:{}/{}", b.visible_blocks, b.separated, b.n))
            .collect();
        eprintln!(
            "side-by-side {variant:?} tolerance {tol}: {}",
            line.join(" ")
        );
    }
    Ok(())
}

/// Known limitation (docs/MRF.md): four pedestrians converging and passing through each
/// other at ±2–4 px/frame; the front object absorbs the others after they cross.
#[test]
#[ignore = "known limitation, documented in docs/MRF.md; prints the separation curve"]
fn converging_group_separation_curve() -> Result<()> {
    for variant in [MrfVariant::Improved, MrfVariant::Legacy] {
        let seq = group_scene().build(21);
        let (frames, truth) = block_truth(&seq, 60);
        let cfg = MrfConfig {
            variant,
            ..MrfConfig::default()
        };
        let maps = run(&cfg, &frames, &seq.empty_frame(), 9)?;
        let curve = separation_success(&occlusion_rows(&truth, &maps), Some(10));
        let line: Vec<String> = curve
            .iter()
            .map(|b| format!("{}:{}/{}", b.visible_blocks, b.separated, b.n))
            .collect();
        eprintln!("converging {variant:?}: {}", line.join(" "));
    }
    Ok(())
}

#[test]
fn tracking_is_deterministic_at_any_thread_count() -> Result<()> {
    let seq = group_scene().build(21);
    let (frames, _) = seq.frames(30);
    let cfg = MrfConfig::default();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| crate::Error::Invalid(e.to_string()))?;
    let four = rayon::ThreadPoolBuilder::new()
        .num_threads(4)
        .build()
        .map_err(|e| crate::Error::Invalid(e.to_string()))?;
    let a = one.install(|| run(&cfg, &frames, &seq.empty_frame(), 3))?;
    let b = four.install(|| run(&cfg, &frames, &seq.empty_frame(), 3))?;
    assert_eq!(a, b);
    Ok(())
}

/// End to end on `vtest.avi` (first 60 frames): people are tracked; writes an overlay PNG
/// of the last frame to `$MRF_OVERLAY` when set, for a visual check.
#[test]
fn runs_on_vtest_avi_and_tracks_walking_people() -> Result<()> {
    let path = std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/vtest.avi"
    ));
    if !path.is_file() || !crate::io::video::ffmpeg_available() {
        eprintln!("skipped: {} or ffmpeg not available", path.display());
        return Ok(());
    }
    let opts = crate::io::SourceOptions {
        end: Some(60),
        ..Default::default()
    };
    let frames: Vec<Frame> = crate::io::source::open(path, &opts)?.collect::<Result<_>>()?;
    let (w, h) = frames[0].size();
    let cfg = MrfConfig::default();
    let mut t = MrfTracker::new(cfg.clone(), w, h, 0)?;
    t.set_background(bootstrap_from_frames(&frames, cfg.background.clone())?)?;
    let mut ids_per_frame = Vec::new();
    let mut last = Vec::new();
    for f in &frames {
        last = t.step(f)?;
        ids_per_frame.push(last.iter().map(|p| p.id).collect::<Vec<_>>());
    }
    // Several people are tracked at the end, and most ids seen at frame 30 are still alive.
    assert!(last.len() >= 4, "only {} objects at frame 60", last.len());
    let mid: std::collections::BTreeSet<_> = ids_per_frame[29].iter().collect();
    let end: std::collections::BTreeSet<_> = ids_per_frame[59].iter().collect();
    let kept = mid.intersection(&end).count();
    assert!(kept >= 3, "ids at frame 30 {mid:?}, at 60 {end:?}");
    Ok(())
}

/// Frames, per-frame truth regions and per-frame visible fractions of a simulated crossing.
type SimulatedCrossing = (Vec<Frame>, Vec<Vec<TruthRegion>>, Vec<Vec<f64>>);

/// Two cars driving towards each other in the two lanes of the simulator's `crossing` scene
/// (oblique view, `w × h` px, 10 frames/s): the eastbound one in the near lane is a tall van
/// (3 m) and hides part of the westbound car while they pass (frames ≈ 17–24). Returns the
/// frames and, per frame, the truth regions from the renderer's per-pixel owner map.
pub(crate) fn simulated_crossing(
    w: u32,
    h: u32,
    frames: u32,
    van_height_m: f64,
) -> Result<SimulatedCrossing> {
    use crate::class::ObjectClass;
    use roadtrack_sim::external::{ExternalTrajectories, TrajectorySample};
    use roadtrack_sim::{SceneKind, SimConfig, Simulation, ViewKind};
    let cfg = SimConfig {
        scene: SceneKind::Crossing,
        view: ViewKind::Oblique,
        frames,
        width: w,
        height: h,
        ..Default::default()
    };
    let mut samples = Vec::new();
    for (id, y, x0, v, height, rgb) in [
        (1u64, -1.75, -10.0, 5.0, van_height_m, [200u8, 40, 30]),
        (2, 1.75, 10.0, -5.0, 1.5, [40, 70, 200]),
    ] {
        for k in 0..=1 {
            let t = f64::from(k) * f64::from(frames) / 10.0;
            samples.push((
                id,
                TrajectorySample {
                    time_s: t,
                    class: ObjectClass::Car,
                    x_m: x0 + v * t,
                    y_m: y,
                    heading_deg: if v > 0.0 { 0.0 } else { 180.0 },
                    length_m: 4.5,
                    width_m: 1.8,
                    height_m: Some(height),
                    rgb: Some(rgb),
                },
            ));
        }
    }
    let ext = ExternalTrajectories::new(samples)?;
    let mut sim = Simulation::from_trajectories(&cfg, 3, ext, Some(frames))?;
    let border = MrfConfig::default().border_blocks;
    let (mut out, mut truth, mut vis) = (Vec::new(), Vec::new(), Vec::new());
    while let Some(step) = sim.next() {
        let step = step?;
        let owner = sim.visible_object_ids();
        let objects: Vec<_> = step
            .truth
            .iter()
            .map(|t| (t.id, t.bbox, t.visibility < 1.0))
            .collect();
        truth.push(super::separation::truth_regions_from_owner(
            &owner, w, h, &objects, border, 16,
        ));
        vis.push(step.truth.iter().map(|t| t.visibility).collect());
        out.push(step.frame);
    }
    Ok((out, truth, vis))
}

#[test]
fn crossing_cars_keep_distinct_ids_through_partial_occlusion_on_the_simulator() -> Result<()> {
    // Two cars pass each other on the simulator's crossing scene (320 × 240 px, oblique);
    // the near-lane van hides up to 57 % of the far car (visible area ≥ 10 blocks).
    let (frames, truth, vis) = simulated_crossing(320, 240, 40, 2.4)?;
    let min_vis = vis.iter().flatten().copied().fold(1.0, f64::min);
    assert!(
        (0.3..0.7).contains(&min_vis),
        "the scene must show a partial occlusion, min visibility {min_vis}"
    );
    let occluded_frames = truth
        .iter()
        .filter(|t| t.iter().any(|r| r.occluded))
        .count();
    assert!(
        occluded_frames >= 5,
        "{occluded_frames} frames with occlusion"
    );
    let cfg = MrfConfig::default();
    let background = bootstrap_from_frames(&frames, cfg.background.clone())?;
    for variant in [MrfVariant::Improved, MrfVariant::Legacy] {
        let cfg = MrfConfig {
            variant,
            ..MrfConfig::default()
        };
        let maps = run_with_background(&cfg, &frames, background.clone(), 5)?;
        // Before the crossing (frame 10) and after it (frame 40): two distinct ids, the same.
        assert_two_ids_kept(variant, &truth, &maps, 9, 39);
        // While partly hidden, the far car is its own region in every frame.
        let curve = separation_success(&occlusion_rows(&truth, &maps), Some(1));
        assert!(curve[0].n >= 5, "{variant:?}: {curve:?}");
        assert_eq!(curve[0].separated, curve[0].n, "{variant:?}: {curve:?}");
    }
    Ok(())
}
