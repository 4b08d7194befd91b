//! Overlays as a pipeline sink: each frame's tracks drawn over it (roadtrack-viz's
//! `Renderer`), optionally beside the ground truth, into a PNG folder or a video.

use roadtrack::error::Result;
use roadtrack::frame::Frame;
use roadtrack::io::sink::FrameSink;
use roadtrack::track::{FramePoints, PointSink};
use roadtrack::track_point::TrackPoint;
use roadtrack_viz::render::{RenderConfig, Renderer, group_by_frame, side_by_side};
use std::collections::BTreeMap;

/// Draws every frame's points into `out`: the tracks alone, or tracks (left) and truth
/// (right) side by side.
pub struct OverlaySink {
    config: RenderConfig,
    tracks: Renderer,
    truth: Option<(Renderer, BTreeMap<u32, Vec<TrackPoint>>)>,
    out: Box<dyn FrameSink>,
    /// A frame to keep as a still, and the image once drawn.
    still: Option<(u32, Option<image::RgbImage>)>,
    /// Frames written.
    pub frames: u32,
}

impl OverlaySink {
    /// A sink into `out`; with `truth`, side by side with it.
    pub fn new(
        config: &RenderConfig,
        truth: Option<&[TrackPoint]>,
        out: Box<dyn FrameSink>,
    ) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config: config.clone(),
            tracks: Renderer::new(config.clone())?,
            truth: match truth {
                Some(t) => Some((Renderer::new(config.clone())?, group_by_frame(t))),
                None => None,
            },
            out,
            still: None,
            frames: 0,
        })
    }

    /// Also keeps the drawing of frame `index` ([`OverlaySink::take_still`]).
    pub fn keep_still(&mut self, index: u32) {
        self.still = Some((index, None));
    }

    /// The kept drawing, once drawn.
    pub fn take_still(&mut self) -> Option<image::RgbImage> {
        self.still.as_mut().and_then(|s| s.1.take())
    }
}

impl PointSink for OverlaySink {
    fn write_frame(&mut self, points: &FramePoints, image: Option<&Frame>) -> Result<()> {
        let frame = image.ok_or_else(|| {
            roadtrack::Error::Invalid("internal error: overlay without the frame".into())
        })?;
        let img = self.tracks.render(frame, &points.points);
        let img = match self.truth.as_mut() {
            Some((renderer, truth)) => {
                let none = Vec::new();
                let right = renderer.render(frame, truth.get(&frame.index).unwrap_or(&none));
                side_by_side(
                    &img,
                    &right,
                    &self.config.tracks_title,
                    &self.config.truth_title,
                )?
            }
            None => img,
        };
        self.out.write_frame(frame.index, &img)?;
        if let Some((index, kept)) = self.still.as_mut()
            && *index == frame.index
        {
            *kept = Some(img);
        }
        self.frames += 1;
        Ok(())
    }

    fn finish(&mut self) -> Result<()> {
        self.out.finish()
    }

    fn wants_images(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{Rgb, RgbImage};
    use roadtrack::class::ObjectClass;
    use roadtrack::geometry::BBox;
    use roadtrack::track::Pipeline;
    use roadtrack::track::replay::ReplayTracker;
    use roadtrack_viz::overlay::id_colour;

    fn frame(i: u32) -> Frame {
        Frame {
            index: i,
            time_s: f64::from(i - 1) / 10.0,
            image: RgbImage::new(120, 80),
        }
    }

    fn point(frame: u32, id: u64, left: f64, top: f64) -> TrackPoint {
        TrackPoint {
            frame,
            time_s: f64::from(frame - 1) / 10.0,
            id,
            class: ObjectClass::Unknown,
            bbox: BBox::new(left, top, 20.0, 10.0),
            score: 1.0,
            ground: None,
        }
    }

    #[test]
    fn replayed_tracks_are_drawn_beside_the_truth_in_every_frame() -> Result<()> {
        let tracks: Vec<_> = (1..=3).map(|f| point(f, 1, 10.0, 10.0)).collect();
        let truth: Vec<_> = (1..=3).map(|f| point(f, 5, 60.0, 40.0)).collect();
        let config = RenderConfig {
            labels: false,
            ..RenderConfig::default()
        };
        let (tx, rx) = std::sync::mpsc::channel();
        struct Forward(std::sync::mpsc::Sender<(u32, RgbImage)>);
        impl FrameSink for Forward {
            fn write_frame(&mut self, index: u32, image: &RgbImage) -> Result<()> {
                let _ = self.0.send((index, image.clone()));
                Ok(())
            }
            fn finish(&mut self) -> Result<()> {
                Ok(())
            }
        }
        let mut sink = OverlaySink::new(&config, Some(&truth), Box::new(Forward(tx)))?;
        sink.keep_still(2);
        let mut p = Pipeline::new(Box::new(ReplayTracker::new(tracks)));
        p.sinks.push(Box::new(&mut sink));
        p.run((1..=3).map(|i| Ok(frame(i))), Some(3), &mut |_, _| {})?;
        drop(p);
        assert_eq!(sink.frames, 3);
        let got: Vec<(u32, RgbImage)> = rx.try_iter().collect();
        assert_eq!(got.iter().map(|g| g.0).collect::<Vec<_>>(), [1, 2, 3]);
        let img = &got[2].1;
        assert_eq!(img.dimensions(), (240, 80));
        // Track 1 on the left half, truth 5 on the right half (offset by 120 px).
        assert_eq!(img.get_pixel(10, 15), &id_colour(1));
        assert_eq!(img.get_pixel(180, 45), &id_colour(5));
        assert_eq!(img.get_pixel(60, 45), &Rgb([0, 0, 0]));
        assert_eq!(sink.take_still().as_ref(), Some(&got[1].1));
        Ok(())
    }
}
