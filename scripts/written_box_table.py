#!/usr/bin/env python3
"""Writing the detector's box (docs/EXPERIMENTS.md, "Writing the detection's centre"): each
method with its online box smoothing written (before) and with the detection's box written
(now), on the same frames and the same detections: the sequences' public detections and
the learned detector's boxes, found once per sequence (`roadtrack detect --detector cnn`,
what `track --detector cnn` gives). MOG2 + norfair (scripts/mog2_norfair.py) on the same
sequences with `--peer`. Class-agnostic HOTA, IDF1, MOTA by `roadtrack evaluate`, means
over the seeds.

    python3 scripts/written_box_table.py --roadtrack $CARGO_TARGET_DIR/release/roadtrack \\
        [--frames 300] [--seeds 1,2,3] [--scenes road,intersection,crossing] \\
        [--views aerial,oblique] [--methods relaxation,mrf,pf,phd] [--work /tmp/vidtrack] \\
        [--sources public,cnn] [--peer]

"Before" reverses one setting in a copy of the method's config: relaxation
`write_filtered_centre = true` (configs/relaxation-video.toml), the MRF
`write_smoothed_box = true`, the PF and PHD `[detections] pf_write_detection_centre` and
`phd_write_detection_centre = false` (configs/filters-pedestrians.toml). Run from the
repository root. Not part of the test suite; `--peer` needs
`pip install opencv-python-headless numpy norfair`.
"""
import argparse
import os
import sys
from collections import defaultdict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from video_tracking_table import add_common_arguments, evaluate, learned_detections, run  # noqa: E402

RELAXATION = "configs/relaxation-video.toml"
FILTERS = "configs/filters-pedestrians.toml"


def configs(work):
    """Per method: (flags before, flags now); the "before" files are written into `work`."""
    def copy(src, name, old, new):
        with open(src) as f:
            text = f.read()
        for o, n in zip(old, new):
            if o not in text:
                sys.exit(f"{src}: expected `{o}`")
            text = text.replace(o, n)
        path = os.path.join(work, name)
        with open(path, "w") as f:
            f.write(text)
        return path

    relax = copy(RELAXATION, "relaxation-before.toml", ["write_filtered_centre = false"],
                 ["write_filtered_centre = true"])
    filters = copy(FILTERS, "filters-before.toml",
                   ["pf_write_detection_centre = true", "phd_write_detection_centre = true"],
                   ["pf_write_detection_centre = false", "phd_write_detection_centre = false"])
    mrf = os.path.join(work, "mrf-before.toml")
    with open(mrf, "w") as f:
        f.write("write_smoothed_box = true\n")
    return {
        "relaxation": (["--config", relax], ["--config", RELAXATION]),
        "mrf": (["--config", mrf], []),
        "pf": (["--config", filters], ["--config", FILTERS]),
        "phd": (["--config", filters], ["--config", FILTERS]),
    }


def main():
    ap = argparse.ArgumentParser()
    add_common_arguments(ap)
    ap.add_argument("--sources", default="public,cnn")
    ap.add_argument("--peer", action="store_true")
    a = ap.parse_args()
    rt = a.roadtrack
    os.makedirs(a.work, exist_ok=True)
    flags = configs(a.work)
    methods = [m for m in a.methods.split(",") if m in flags]
    keys = ("HOTA", "IDF1", "MOTA")
    results = defaultdict(list)
    t = os.path.join(a.work, "written_t.txt")
    for scene in a.scenes.split(","):
        for view in a.views.split(","):
            sv = f"{scene}/{view}"
            for seed in [int(s) for s in a.seeds.split(",")]:
                seq = f"{a.work}/{scene}-{view}-{seed}"
                if not os.path.exists(f"{seq}/seqinfo.ini"):
                    run([rt, "-q", "simulate", "--scene", scene, "--view", view,
                         "--frames", str(a.frames), "--seed", str(seed), "-o", seq])
                if a.peer:
                    import mog2_norfair
                    mog2_norfair.main(seq, t)
                    results[(sv, "MOG2 + norfair", "peer", "")].append(evaluate(rt, seq, t))
                for source in a.sources.split(","):
                    dets = learned_detections(rt, seq, "written_cnn.csv") if source == "cnn" else []
                    for method in methods:
                        for name, extra in zip(("before", "now"), flags[method]):
                            run([rt, "-q", "track", seq, "--method", method, "--detector",
                                 "file", *dets, *extra, "--seed", "0", "-o", t])
                            m = evaluate(rt, seq, t)
                            results[(sv, method, source, name)].append(m)
                    print(f"{sv} seed {seed} {source}: done", file=sys.stderr, flush=True)
    mean = {k: {x: sum(m[x] for m in ms) / len(ms) for x in keys} for k, ms in results.items()}
    cell = lambda m: f"{m['HOTA']:.3f} ({m['IDF1']:.3f}, {m['MOTA']:.3f})"
    print(f"Means over seeds {a.seeds}; HOTA (IDF1, MOTA):")
    print()
    print("| scene | method | detections | before | now |")
    print("| --- | --- | --- | --- | --- |")
    for (sv, method, source, name), m in mean.items():
        if name == "now":
            continue
        if source == "peer":
            print(f"| {sv} | MOG2 + norfair | (its own) | {cell(m)} | |")
            continue
        now = mean[(sv, method, source, "now")]
        print(f"| {sv} | {method} | {source} | {cell(m)} | {cell(now)} |")


if __name__ == "__main__":
    main()
