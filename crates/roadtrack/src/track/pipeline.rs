//! The one loop from frames to written tracks:
//!
//! ```text
//! source ─▶ Detector ─▶ Tracker ─▶ PointStage… ─▶ PointSink…
//! ```
//!
//! Each frame is read, detected and tracked; the frames the tracker returns as final go
//! through the point stages in order (a stage may hold frames back, as the ground-speed
//! smoother does for half its window) and then to every sink. Nothing keeps the whole
//! video: the pipeline holds only the frames not yet final (their images only when a sink
//! draws them), and the file sinks stream each frame's rows to a temporary file that is
//! renamed into place when the run succeeds, so peak memory does not grow with the video
//! and an interrupted run leaves no file that looks complete.

use super::{FramePoints, Tracker};
use crate::detect::{Detector, FrameDetections};
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::io::geojson::GeoJsonWriter;
use crate::io::mot::TracksWriter;
use crate::io::trajectories::TrajectoriesWriter;
use crate::track_point::TrackPoint;
use std::collections::{BTreeSet, VecDeque};
use std::path::Path;

/// A step between the tracker and the sinks that transforms final frames in order (e.g.
/// putting points on the ground). Like a [`Tracker`], it returns every frame it is given
/// exactly once and in order, possibly later.
pub trait PointStage {
    /// Takes one frame; returns the frames that leave the stage now.
    ///
    /// # Errors
    /// A point the stage cannot transform.
    fn push(&mut self, frame: FramePoints) -> Result<Vec<FramePoints>>;

    /// Ends the run: the frames still held.
    ///
    /// # Errors
    /// As [`PointStage::push`].
    fn finish(&mut self) -> Result<Vec<FramePoints>>;

    /// Whether the stage looks at the frames' images ([`PointStage::see_image`]).
    fn wants_images(&self) -> bool {
        false
    }

    /// Called just before [`PointStage::push`] with that frame's image, when the stage
    /// [wants images](PointStage::wants_images). The pipeline keeps an image only until
    /// the last stage that wants it has seen it (or a sink has drawn it), so a stage that
    /// holds points does not make the pipeline hold frames.
    fn see_image(&mut self, _points: &FramePoints, _image: &Frame) {}

    /// Whether the stage looks at the detections the tracker is given
    /// ([`PointStage::see_detections`]).
    fn wants_detections(&self) -> bool {
        false
    }

    /// Called with each frame's detections as the tracker is given them, in frame order,
    /// before that frame's points reach the stage, when the stage
    /// [wants detections](PointStage::wants_detections).
    fn see_detections(&mut self, _frame: u32, _detections: &FrameDetections) {}
}

/// Where final track points go: one call per frame, in frame order, points sorted by id.
pub trait PointSink {
    /// Writes one frame's points; `image` is the frame itself when the sink
    /// [wants images](PointSink::wants_images).
    ///
    /// # Errors
    /// The sink cannot write.
    fn write_frame(&mut self, points: &FramePoints, image: Option<&Frame>) -> Result<()>;

    /// Completes the output (a file is in place only after this).
    ///
    /// # Errors
    /// The output cannot be completed.
    fn finish(&mut self) -> Result<()>;

    /// Whether [`PointSink::write_frame`] needs the frame's image (an overlay does).
    fn wants_images(&self) -> bool {
        false
    }
}

/// What a run did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RunSummary {
    /// Frames read.
    pub frames: u64,
    /// Track points written.
    pub points: u64,
    /// Distinct track ids.
    pub tracks: usize,
}

/// The stages of one run: a detector (none for trackers that read pixels themselves or
/// replay a file), a tracker, point stages and sinks.
pub struct Pipeline<'a> {
    /// Frame → detections; `None` gives the tracker empty detections.
    pub detector: Option<Box<dyn Detector + 'a>>,
    /// The tracking method.
    pub tracker: Box<dyn Tracker + 'a>,
    /// Transformations of the final points, applied in order.
    pub stages: Vec<Box<dyn PointStage + 'a>>,
    /// Outputs.
    pub sinks: Vec<Box<dyn PointSink + 'a>>,
}

impl std::fmt::Debug for Pipeline<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pipeline")
            .field("detector", &self.detector.is_some())
            .field("stages", &self.stages.len())
            .field("sinks", &self.sinks.len())
            .finish_non_exhaustive()
    }
}

/// Frames read but not yet written, with their images when a sink draws them.
struct Waiting {
    keep_images: bool,
    frames: VecDeque<(u32, Option<Frame>)>,
}

impl<'a> Pipeline<'a> {
    /// A pipeline of `tracker` alone (no detector, stages or sinks).
    pub fn new(tracker: Box<dyn Tracker + 'a>) -> Self {
        Self {
            detector: None,
            tracker,
            stages: Vec::new(),
            sinks: Vec::new(),
        }
    }

    /// Runs over `frames` (`total` frames when known, for `progress(done, total)`, total 0
    /// when unknown) and completes every sink.
    ///
    /// # Errors
    /// A frame that cannot be read, a stage that fails, a sink that cannot write; a tracker
    /// or stage that breaks the frame contract (an internal error). Sinks are not completed
    /// after an error, so no output file appears.
    pub fn run(
        &mut self,
        frames: impl IntoIterator<Item = Result<Frame>>,
        total: Option<u64>,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<RunSummary> {
        let mut waiting = Waiting {
            keep_images: self.sinks.iter().any(|s| s.wants_images())
                || self.stages.iter().any(|s| s.wants_images()),
            frames: VecDeque::new(),
        };
        let mut summary = RunSummary::default();
        let mut ids = BTreeSet::new();
        let empty = FrameDetections::default();
        let batch_len = self.detector.as_ref().map_or(1, |d| d.batch_len().max(1));
        let mut frames = frames.into_iter();
        let mut batch: Vec<Frame> = Vec::with_capacity(batch_len);
        let mut found: Vec<FrameDetections> = Vec::new();
        loop {
            // Choice: a detector that takes several frames at once (the networks) gets them
            // as one batch; the tracker still steps through them one at a time, in order.
            if !crate::detect::next_batch(&mut frames, batch_len, &mut batch)? {
                break;
            }
            found.clear();
            if let Some(d) = self.detector.as_mut() {
                found = crate::detect::detect_checked(d.as_mut(), &batch)?;
            }
            for (i, frame) in batch.drain(..).enumerate() {
                self.step_frame(
                    frame,
                    found.get(i).unwrap_or(&empty),
                    &mut waiting,
                    &mut summary,
                    &mut ids,
                )?;
                progress(summary.frames, total.unwrap_or(0));
            }
        }
        let out = self.tracker.finish()?;
        self.through_stages(0, out, &mut waiting, &mut summary, &mut ids)?;
        for i in 0..self.stages.len() {
            let out = self.stages[i].finish()?;
            self.through_stages(i + 1, out, &mut waiting, &mut summary, &mut ids)?;
        }
        if let Some((index, _)) = waiting.frames.front() {
            return Err(Error::Invalid(format!(
                "internal error: frame {index} was never returned by the tracker"
            )));
        }
        for s in &mut self.sinks {
            s.finish()?;
        }
        summary.tracks = ids.len();
        Ok(summary)
    }

    /// Steps the tracker through one frame and passes what it returns on.
    fn step_frame(
        &mut self,
        frame: Frame,
        detections: &FrameDetections,
        waiting: &mut Waiting,
        summary: &mut RunSummary,
        ids: &mut BTreeSet<u64>,
    ) -> Result<()> {
        for s in self.stages.iter_mut().filter(|s| s.wants_detections()) {
            s.see_detections(frame.index, detections);
        }
        let out = self.tracker.step(&frame, detections)?;
        waiting.frames.push_back((
            frame.index,
            if waiting.keep_images {
                Some(frame)
            } else {
                None
            },
        ));
        self.through_stages(0, out, waiting, summary, ids)?;
        summary.frames += 1;
        Ok(())
    }

    /// Passes `frames` through the stages from `first` on, then to the sinks.
    fn through_stages(
        &mut self,
        first: usize,
        frames: Vec<FramePoints>,
        waiting: &mut Waiting,
        summary: &mut RunSummary,
        ids: &mut BTreeSet<u64>,
    ) -> Result<()> {
        let mut batch = frames;
        if first == 0 {
            for f in &mut batch {
                f.points.sort_by_key(|p| p.id);
            }
        }
        let sinks_draw = self.sinks.iter().any(|s| s.wants_images());
        let last_looking = self.stages.iter().rposition(|s| s.wants_images());
        for (i, stage) in self.stages.iter_mut().enumerate().skip(first) {
            let mut next = Vec::new();
            for f in batch {
                if stage.wants_images() {
                    // Frames wait in read order, so the deque is sorted by index.
                    if let Ok(k) = waiting.frames.binary_search_by_key(&f.frame, |(j, _)| *j) {
                        if let Some(image) = &waiting.frames[k].1 {
                            stage.see_image(&f, image);
                        }
                        if Some(i) == last_looking && !sinks_draw {
                            waiting.frames[k].1 = None;
                        }
                    }
                }
                next.extend(stage.push(f)?);
            }
            batch = next;
        }
        for f in batch {
            let (index, image) = waiting.frames.pop_front().ok_or_else(|| {
                Error::Invalid(format!(
                    "internal error: frame {} returned twice or never read",
                    f.frame
                ))
            })?;
            if index != f.frame {
                return Err(Error::Invalid(format!(
                    "internal error: frame {} returned while frame {index} was due",
                    f.frame
                )));
            }
            for s in &mut self.sinks {
                s.write_frame(&f, image.as_ref())?;
            }
            summary.points += f.points.len() as u64;
            ids.extend(f.points.iter().map(|p| p.id));
        }
        Ok(())
    }
}

/// Runs `detector` (if any) and `tracker` over frames in memory or any iterator and returns
/// every point, by frame then id: [`Pipeline::run`] with one collecting sink (tests,
/// experiments).
///
/// # Errors
/// As [`Pipeline::run`].
pub fn run_frames<'a>(
    detector: Option<Box<dyn Detector + 'a>>,
    tracker: Box<dyn Tracker + 'a>,
    frames: impl IntoIterator<Item = Result<Frame>>,
) -> Result<Vec<TrackPoint>> {
    let mut points = Vec::new();
    let mut p = Pipeline {
        detector,
        tracker,
        stages: Vec::new(),
        sinks: vec![Box::new(&mut points)],
    };
    p.run(frames, None, &mut |_, _| {})?;
    drop(p);
    Ok(points)
}

/// MOTChallenge tracks file ([`crate::io::mot::write_tracks`]'s format), streamed.
#[derive(Debug)]
pub struct MotSink(Option<TracksWriter>);

impl MotSink {
    /// Starts `path` (`-` = standard output).
    ///
    /// # Errors
    /// As [`TracksWriter::create`].
    pub fn create(path: &Path) -> Result<Self> {
        Ok(Self(Some(TracksWriter::create(path)?)))
    }
}

impl PointSink for MotSink {
    fn write_frame(&mut self, points: &FramePoints, _image: Option<&Frame>) -> Result<()> {
        let w = self.0.as_mut().ok_or_else(finished)?;
        points.points.iter().try_for_each(|p| w.write_point(p))
    }

    fn finish(&mut self) -> Result<()> {
        self.0.take().map_or(Ok(()), TracksWriter::commit)
    }
}

/// Trajectories CSV ([`crate::io::trajectories::write_trajectories`]'s format), streamed.
#[derive(Debug)]
pub struct TrajectoriesSink(Option<TrajectoriesWriter>);

impl TrajectoriesSink {
    /// Starts `path` (`-` = standard output); with the ground columns when `with_ground`
    /// (every point must then have a ground state, none otherwise).
    ///
    /// # Errors
    /// As [`TrajectoriesWriter::create`].
    pub fn create(path: &Path, with_ground: bool) -> Result<Self> {
        Ok(Self(Some(TrajectoriesWriter::create(path, with_ground)?)))
    }
}

impl PointSink for TrajectoriesSink {
    fn write_frame(&mut self, points: &FramePoints, _image: Option<&Frame>) -> Result<()> {
        let w = self.0.as_mut().ok_or_else(finished)?;
        points.points.iter().try_for_each(|p| w.write_point(p))
    }

    fn finish(&mut self) -> Result<()> {
        self.0.take().map_or(Ok(()), TrajectoriesWriter::commit)
    }
}

/// GeoJSON trajectories on the ground ([`crate::io::geojson`]), written at the end.
#[derive(Debug)]
pub struct GeoJsonSink(Option<GeoJsonWriter>);

impl GeoJsonSink {
    /// A sink for `path` (`-` = standard output).
    pub fn new(path: &Path) -> Self {
        Self(Some(GeoJsonWriter::new(path)))
    }
}

impl PointSink for GeoJsonSink {
    fn write_frame(&mut self, points: &FramePoints, _image: Option<&Frame>) -> Result<()> {
        let w = self.0.as_mut().ok_or_else(finished)?;
        points.points.iter().try_for_each(|p| w.add_point(p))
    }

    fn finish(&mut self) -> Result<()> {
        self.0.take().map_or(Ok(()), GeoJsonWriter::commit)
    }
}

/// A sink borrowed for the run, so the caller can read it afterwards.
impl<T: PointSink + ?Sized> PointSink for &mut T {
    fn write_frame(&mut self, points: &FramePoints, image: Option<&Frame>) -> Result<()> {
        (**self).write_frame(points, image)
    }

    fn finish(&mut self) -> Result<()> {
        (**self).finish()
    }

    fn wants_images(&self) -> bool {
        (**self).wants_images()
    }
}

/// Keeps every point, in frame then id order (for callers that need them all, such as the
/// demo's evaluation; memory grows with the video).
impl PointSink for Vec<TrackPoint> {
    fn write_frame(&mut self, points: &FramePoints, _image: Option<&Frame>) -> Result<()> {
        self.extend(points.points.iter().cloned());
        Ok(())
    }

    fn finish(&mut self) -> Result<()> {
        Ok(())
    }
}

fn finished() -> Error {
    Error::Invalid("internal error: write after the sink was finished".to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::class::ObjectClass;
    use crate::geometry::BBox;
    use image::RgbImage;

    fn frames(n: u32) -> Vec<Result<Frame>> {
        (1..=n)
            .map(|i| {
                Ok(Frame {
                    index: i,
                    time_s: f64::from(i - 1) / 10.0,
                    image: RgbImage::new(4, 4),
                })
            })
            .collect()
    }

    fn point(frame: u32, id: u64) -> TrackPoint {
        TrackPoint {
            frame,
            time_s: f64::from(frame - 1) / 10.0,
            id,
            class: ObjectClass::Unknown,
            bbox: BBox::new(0.0, 0.0, 1.0, 1.0),
            score: 1.0,
            ground: None,
        }
    }

    /// Holds every frame back by `delay` frames and returns two points per frame, ids in
    /// descending order.
    struct Delayed {
        delay: usize,
        held: VecDeque<FramePoints>,
    }

    impl Tracker for Delayed {
        fn step(&mut self, frame: &Frame, _d: &FrameDetections) -> Result<Vec<FramePoints>> {
            self.held.push_back(FramePoints::new(
                frame,
                vec![point(frame.index, 9), point(frame.index, 2)],
            ));
            let mut out = Vec::new();
            while self.held.len() > self.delay {
                out.extend(self.held.pop_front());
            }
            Ok(out)
        }

        fn finish(&mut self) -> Result<Vec<FramePoints>> {
            Ok(self.held.drain(..).collect())
        }
    }

    /// Records the frames a sink sees and whether it had their images.
    #[derive(Default)]
    struct Seen(Vec<(u32, Vec<u64>, bool)>);

    impl PointSink for Seen {
        fn write_frame(&mut self, p: &FramePoints, image: Option<&Frame>) -> Result<()> {
            if let Some(img) = image {
                assert_eq!(img.index, p.frame);
            }
            self.0.push((
                p.frame,
                p.points.iter().map(|q| q.id).collect(),
                image.is_some(),
            ));
            Ok(())
        }

        fn finish(&mut self) -> Result<()> {
            Ok(())
        }

        fn wants_images(&self) -> bool {
            true
        }
    }

    #[test]
    fn delayed_frames_reach_the_sinks_in_order_with_their_images_and_sorted_ids() -> Result<()> {
        let mut seen = Seen::default();
        let mut all = Vec::new();
        let mut p = Pipeline::new(Box::new(Delayed {
            delay: 3,
            held: VecDeque::new(),
        }));
        p.sinks.push(Box::new(&mut seen));
        p.sinks.push(Box::new(&mut all));
        let mut calls = 0;
        let s = p.run(frames(6), Some(6), &mut |_, _| calls += 1)?;
        drop(p);
        assert_eq!(calls, 6);
        assert_eq!(
            s,
            RunSummary {
                frames: 6,
                points: 12,
                tracks: 2
            }
        );
        let order: Vec<u32> = seen.0.iter().map(|s| s.0).collect();
        assert_eq!(order, vec![1, 2, 3, 4, 5, 6]);
        assert!(seen.0.iter().all(|s| s.1 == vec![2, 9] && s.2));
        assert_eq!(all.len(), 12);
        Ok(())
    }

    /// A stage that holds every frame to the end and records the images it was shown.
    #[derive(Default)]
    struct Looking {
        held: Vec<FramePoints>,
        saw: Vec<u32>,
    }

    impl PointStage for &mut Looking {
        fn push(&mut self, frame: FramePoints) -> Result<Vec<FramePoints>> {
            self.held.push(frame);
            Ok(Vec::new())
        }

        fn finish(&mut self) -> Result<Vec<FramePoints>> {
            Ok(std::mem::take(&mut self.held))
        }

        fn wants_images(&self) -> bool {
            true
        }

        fn see_image(&mut self, points: &FramePoints, image: &Frame) {
            assert_eq!(points.frame, image.index);
            self.saw.push(image.index);
        }
    }

    /// Records whether each frame came with its image.
    #[derive(Default)]
    struct Blind(Vec<bool>, bool);

    impl PointSink for &mut Blind {
        fn write_frame(&mut self, _p: &FramePoints, image: Option<&Frame>) -> Result<()> {
            self.0.push(image.is_some());
            Ok(())
        }

        fn finish(&mut self) -> Result<()> {
            Ok(())
        }

        fn wants_images(&self) -> bool {
            self.1
        }
    }

    #[test]
    fn a_stage_sees_each_image_once_and_the_pipeline_keeps_it_only_for_a_sink_that_draws()
    -> Result<()> {
        for sink_draws in [false, true] {
            let mut stage = Looking::default();
            let mut sink = Blind(Vec::new(), sink_draws);
            let mut p = Pipeline::new(Box::new(Delayed {
                delay: 2,
                held: VecDeque::new(),
            }));
            p.stages.push(Box::new(&mut stage));
            p.sinks.push(Box::new(&mut sink));
            p.run(frames(6), Some(6), &mut |_, _| {})?;
            drop(p);
            assert_eq!(stage.saw, vec![1, 2, 3, 4, 5, 6]);
            // Without a drawing sink the images were dropped once the stage had seen them,
            // although the stage held every frame to the end.
            assert_eq!(sink.0, vec![sink_draws; 6]);
        }
        Ok(())
    }

    /// A detector that marks each frame's detection with the frame index and counts its
    /// batches; `short` drops the last result of every batch (a broken detector).
    struct Batching {
        len: usize,
        batches: std::rc::Rc<std::cell::RefCell<Vec<Vec<u32>>>>,
        short: bool,
    }

    impl Detector for Batching {
        fn detect(&mut self, frame: &Frame) -> Result<FrameDetections> {
            Ok(FrameDetections {
                detections: vec![crate::detection::Detection::at(
                    frame.index,
                    u64::from(frame.index) * 10,
                    crate::geometry::Point::new(0.0, 0.0),
                )],
                foreground: None,
            })
        }

        fn batch_len(&self) -> usize {
            self.len
        }

        fn detect_batch(&mut self, frames: &[Frame]) -> Result<Vec<FrameDetections>> {
            self.batches
                .borrow_mut()
                .push(frames.iter().map(|f| f.index).collect());
            let mut out: Vec<FrameDetections> = frames
                .iter()
                .map(|f| self.detect(f))
                .collect::<Result<_>>()?;
            if self.short {
                out.pop();
            }
            Ok(out)
        }
    }

    /// Records, per step, the frame and the ids of the detections it was given.
    #[derive(Default)]
    struct Given(Vec<(u32, Vec<u64>)>);

    impl Tracker for Given {
        fn step(&mut self, frame: &Frame, d: &FrameDetections) -> Result<Vec<FramePoints>> {
            self.0
                .push((frame.index, d.detections.iter().map(|x| x.id).collect()));
            Ok(vec![FramePoints::new(frame, Vec::new())])
        }

        fn finish(&mut self) -> Result<Vec<FramePoints>> {
            Ok(Vec::new())
        }
    }

    #[test]
    fn a_batching_detector_gets_frames_in_batches_and_the_tracker_each_frame_in_order() -> Result<()>
    {
        for len in [1, 3, 10] {
            let mut given = Given::default();
            let batches = std::rc::Rc::default();
            let det = Batching {
                len,
                batches: std::rc::Rc::clone(&batches),
                short: false,
            };
            let mut p = Pipeline::new(Box::new(&mut given));
            p.detector = Some(Box::new(det));
            let mut calls = Vec::new();
            let s = p.run(frames(7), Some(7), &mut |done, _| calls.push(done))?;
            drop(p);
            assert_eq!(s.frames, 7);
            assert_eq!(calls, (1..=7).collect::<Vec<u64>>());
            let want: Vec<(u32, Vec<u64>)> =
                (1..=7).map(|i| (i, vec![u64::from(i) * 10])).collect();
            assert_eq!(given.0, want, "batch length {len}");
            let expect: Vec<Vec<u32>> = (1..=7u32)
                .collect::<Vec<_>>()
                .chunks(len)
                .map(<[u32]>::to_vec)
                .collect();
            assert_eq!(*batches.borrow(), expect, "batch length {len}");
        }
        Ok(())
    }

    #[test]
    fn a_detector_that_returns_too_few_results_is_an_error() {
        let mut given = Given::default();
        let det = Batching {
            len: 3,
            batches: std::rc::Rc::default(),
            short: true,
        };
        let mut p = Pipeline::new(Box::new(&mut given));
        p.detector = Some(Box::new(det));
        let err = p
            .run(frames(4), None, &mut |_, _| {})
            .expect_err("short batch")
            .to_string();
        assert!(err.contains("returned 2 results for 3 frames"), "{err}");
    }

    /// Drops frame 2: a broken tracker is an error, not a silently shorter output.
    struct Dropping;

    impl Tracker for Dropping {
        fn step(&mut self, frame: &Frame, _d: &FrameDetections) -> Result<Vec<FramePoints>> {
            Ok(if frame.index == 2 {
                Vec::new()
            } else {
                vec![FramePoints::new(frame, Vec::new())]
            })
        }

        fn finish(&mut self) -> Result<Vec<FramePoints>> {
            Ok(Vec::new())
        }
    }

    #[test]
    fn a_tracker_that_skips_a_frame_is_an_error() {
        let mut p = Pipeline::new(Box::new(Dropping));
        let err = p
            .run(frames(3), None, &mut |_, _| {})
            .expect_err("frame 2 skipped")
            .to_string();
        assert!(
            err.contains("frame 3 returned while frame 2 was due"),
            "{err}"
        );
    }

    #[test]
    fn file_sinks_appear_only_when_the_run_succeeds() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let path = dir.path().join("t.txt");
        let mut p = Pipeline::new(Box::new(Dropping));
        p.sinks.push(Box::new(MotSink::create(&path)?));
        assert!(p.run(frames(3), None, &mut |_, _| {}).is_err());
        drop(p);
        assert!(!path.exists());
        let mut p = Pipeline::new(Box::new(Delayed {
            delay: 1,
            held: VecDeque::new(),
        }));
        p.sinks.push(Box::new(MotSink::create(&path)?));
        p.run(frames(2), None, &mut |_, _| {})?;
        drop(p);
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        assert_eq!(text.lines().count(), 4);
        assert!(text.starts_with("1,2,"));
        Ok(())
    }
}
