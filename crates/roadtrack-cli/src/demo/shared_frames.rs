//! One decoding of the demo's sequence for the methods it runs side by side.
//!
//! Each method would otherwise decode the 700 JPEG frames itself: about half of the
//! relaxation run's CPU and a third of the MRF's (perf, dev profile). One thread reads the
//! source once and hands every frame, in order, to each method through a bounded channel.
//! A detector that looks at each frame alone runs once for all of them beside the methods,
//! on frames from the same reader, and hands its detections on through [`Found`].

use roadtrack::Frame;
use roadtrack::detect::FrameDetections;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};

/// Frames a method may run behind the reader before the reader waits for it. A reader of
/// the frames that waits for [`Found`] must take at most this many frames at a time, or
/// the reader, waiting for a method that waits for detections, never sends it the rest.
pub const AHEAD: usize = 8;

/// `n` channels: the senders for [`broadcast`], a receiver for each method.
pub type Channels = (
    Vec<SyncSender<roadtrack::Result<Frame>>>,
    Vec<Receiver<roadtrack::Result<Frame>>>,
);

/// `n` bounded channels of frames.
pub fn channels(n: usize) -> Channels {
    (0..n).map(|_| sync_channel(AHEAD)).unzip()
}

/// Sends every frame of `frames` to each of `to`, in order, until the frames end or no
/// receiver is left (a method that stops early drops its receiver and is skipped from
/// then on). A read error goes to every receiver, as its message, and ends the stream.
// Choice: the error is sent as text because roadtrack::Error is not Clone; the method that
// receives it fails with the reader's message, the frame and file in it.
pub fn broadcast(
    frames: impl IntoIterator<Item = roadtrack::Result<Frame>>,
    to: Vec<SyncSender<roadtrack::Result<Frame>>>,
) {
    let mut to: Vec<Option<SyncSender<roadtrack::Result<Frame>>>> =
        to.into_iter().map(Some).collect();
    for frame in frames {
        match frame {
            Ok(frame) => {
                for slot in &mut to {
                    if slot
                        .as_ref()
                        .is_some_and(|tx| tx.send(Ok(frame.clone())).is_err())
                    {
                        *slot = None;
                    }
                }
                if to.iter().all(Option::is_none) {
                    return;
                }
            }
            Err(e) => {
                let message = e.to_string();
                for tx in to.iter().flatten() {
                    let _ = tx.send(Err(roadtrack::Error::Invalid(message.clone())));
                }
                return;
            }
        }
    }
}

/// Detections found frame by frame by one thread and read, each in frame order, by
/// others, which wait for the frames not found yet.
#[derive(Default)]
pub struct Found {
    state: Mutex<FoundState>,
    more: Condvar,
}

#[derive(Default)]
struct FoundState {
    frames: Vec<FrameDetections>,
    /// `None` while detections may still come; `Some(None)`: all found; `Some(Some(e))`:
    /// the detector failed with `e`.
    end: Option<Option<String>>,
}

impl Found {
    fn state(&self) -> MutexGuard<'_, FoundState> {
        // A panicking reader leaves the detections whole: the state is only appended to.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Adds the next frames' detections.
    pub fn push(&self, frames: Vec<FrameDetections>) {
        self.state().frames.extend(frames);
        self.more.notify_all();
    }

    /// Marks the end: every frame's detections are in, or (`error`) no more will come.
    /// Only the first end counts.
    pub fn finish(&self, error: Option<String>) {
        let mut state = self.state();
        if state.end.is_none() {
            state.end = Some(error);
        }
        drop(state);
        self.more.notify_all();
    }

    /// The detections of the `k`-th frame found (from 0), once found.
    ///
    /// # Errors
    /// The detector's message when it failed first; an internal error when all were found
    /// and there is no `k`-th.
    pub fn get(&self, k: usize) -> roadtrack::Result<FrameDetections> {
        let mut state = self.state();
        loop {
            if let Some(found) = state.frames.get(k) {
                return Ok(found.clone());
            }
            match &state.end {
                Some(Some(error)) => return Err(roadtrack::Error::Invalid(error.clone())),
                Some(None) => {
                    return Err(roadtrack::Error::Invalid(format!(
                        "internal error: no detections kept for the {}th frame",
                        k + 1
                    )));
                }
                None => {
                    state = self
                        .more
                        .wait(state)
                        .unwrap_or_else(PoisonError::into_inner)
                }
            }
        }
    }

    /// How many frames' detections are in.
    pub fn len(&self) -> usize {
        self.state().frames.len()
    }
}

/// Ends a [`Found`] as failed when dropped before [`FinishOnDrop::done`]: a detector that
/// stops early (an error, a panic) must not leave its readers waiting.
pub struct FinishOnDrop<'a>(pub &'a Found);

impl FinishOnDrop<'_> {
    /// Ends the detections with `result`'s error, if any.
    pub fn done<T>(self, result: &roadtrack::Result<T>) {
        self.0
            .finish(result.as_ref().err().map(ToString::to_string));
        std::mem::forget(self);
    }
}

impl Drop for FinishOnDrop<'_> {
    fn drop(&mut self) {
        self.0.finish(Some("the demo's detector stopped".into()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::RgbImage;

    fn frame(index: u32) -> Frame {
        Frame {
            index,
            time_s: f64::from(index) / 10.0,
            image: RgbImage::from_pixel(4, 3, image::Rgb([index as u8, 0, 0])),
        }
    }

    /// Every receiver gets every frame in order, a receiver dropped early does not stall
    /// the others, and a read error reaches every receiver still there and ends the stream.
    #[test]
    fn each_receiver_gets_every_frame_in_order() {
        let frames: Vec<roadtrack::Result<Frame>> = (1..=50)
            .map(|i| {
                if i == 40 {
                    Err(roadtrack::Error::Invalid("frame 40: truncated".into()))
                } else {
                    Ok(frame(i))
                }
            })
            .collect();
        let (tx, rx) = channels(3);
        let got: Vec<(Vec<u32>, Option<String>)> = std::thread::scope(|scope| {
            scope.spawn(move || broadcast(frames, tx));
            let handles: Vec<_> = rx
                .into_iter()
                .enumerate()
                .map(|(k, rx)| {
                    scope.spawn(move || {
                        let mut seen = Vec::new();
                        let mut error = None;
                        for f in rx {
                            match f {
                                Ok(f) => seen.push(f.index),
                                Err(e) => error = Some(e.to_string()),
                            }
                            // The second receiver stops after 5 frames.
                            if k == 1 && seen.len() == 5 {
                                break;
                            }
                        }
                        (seen, error)
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("joined"))
                .collect()
        });
        let all: Vec<u32> = (1..40).collect();
        assert_eq!(got[0].0, all);
        assert_eq!(got[1].0, vec![1, 2, 3, 4, 5]);
        assert_eq!(got[2].0, all);
        for k in [0, 2] {
            assert!(got[k].1.as_deref().is_some_and(|e| e.contains("frame 40")));
        }
    }
}
