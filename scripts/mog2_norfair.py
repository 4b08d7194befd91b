#!/usr/bin/env python3
"""Peer for tracking from video (docs/EXPERIMENTS.md, "Tracking from video"): OpenCV's
MOG2 background subtractor with contour boxes (`detection_compare.mog2`: defaults,
shadows dropped, 3×3 opening, 7×7 closing, area ≥ 60 px) fed to norfair's IoU tracker
(`norfair_peer.track`, the same settings as the public-detection peer).

    python scripts/mog2_norfair.py SEQ_DIR OUT.txt

Not part of the test suite; needs `pip install opencv-python-headless numpy norfair`."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from detection_compare import mog2  # noqa: E402
from norfair_peer import seq_length, track  # noqa: E402


def main(seq, out):
    n = seq_length(seq)
    track(mog2(seq, n), n, out)


if __name__ == "__main__":
    main(*sys.argv[1:3])
