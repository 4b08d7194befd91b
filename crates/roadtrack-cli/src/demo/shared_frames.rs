//! One decoding of the demo's sequence for the methods it runs side by side.
//!
//! Each method would otherwise decode the 700 JPEG frames itself: about half of the
//! relaxation run's CPU and a third of the MRF's (perf, dev profile). One thread reads the
//! source once and hands every frame, in order, to each method through a bounded channel.

use roadtrack::Frame;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

/// Frames a method may run behind the reader before the reader waits for it.
const AHEAD: usize = 8;

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
