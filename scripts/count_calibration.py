#!/usr/bin/env python3
"""How much of the detection PHD's count error a count could remove by knowing which
labels sit on a visible object (docs/EXPERIMENTS.md "Filters with detections as
measurements", issue 14 target 2).

Reads the per-label rows of the ignored test `count_after_miss_probe`
(`track::filter::count_diagnostics`; configs/filters-pedestrians.toml, 300 frames):

    RT_OUT=/tmp/count_probe RT_SEEDS=1,2,3,4,5,6 RT_SCENES=crossing,intersection,road \
      cargo test --release -p roadtrack --lib count_after_miss_probe -- --ignored
    python3 scripts/count_calibration.py /tmp/count_probe

and prints, per scene: what the labels lie on by misses in a row (seeds 4-6), then the
count MAE on seeds 1-3 (truth: objects >= 0.3 visible) of the filter's counts (the mean
Σw and the mode of the labels' cardinality) and of the same two counts with each label's
weight replaced by P(it lies on a visible object | misses in a row, weight), fitted on
the truth of seeds 4-6 ("held out") and of seeds 1-3 themselves ("fitted in sample",
an optimistic bound). Standard library only.
"""
import argparse
import collections
import csv
import math
import os


def load(folder, scene, seed):
    """Frames of one run: {frame: (true_count, [(w, misses, on)])}."""
    frames = collections.OrderedDict()
    with open(os.path.join(folder, f"{scene}_{seed}.csv")) as f:
        for r in csv.DictReader(f):
            rows = frames.setdefault(int(r["frame"]), (int(r["true_count"]), []))[1]
            if r["on"] != "E":
                rows.append((float(r["w"]), int(r["misses"]), r["on"]))
    return frames


def mode(probabilities):
    """The mode of the number of objects, each label one object with its probability
    (as roadtrack's map_cardinality: ⌊w⌋ sure objects plus one with w − ⌊w⌋; ties to
    the smaller count)."""
    sure, p = 0, [1.0]
    for w in probabilities:
        if not w > 0:
            continue
        whole = math.floor(w)
        sure += whole
        r = w - whole
        if r <= 0:
            continue
        p.append(0.0)
        for n in range(len(p) - 1, 0, -1):
            p[n] = p[n] * (1 - r) + p[n - 1] * r
        p[0] *= 1 - r
    return sure + max(range(len(p)), key=lambda n: (p[n], -n))


def key(w, misses):
    """The calibration's bin: misses in a row (4 or more together), weight in tenths."""
    return min(misses, 4), min(int(w * 10), 10)


def fit(runs):
    """P(on a visible object | bin) over the labels of `runs`."""
    visible, n = collections.Counter(), collections.Counter()
    for frames in runs:
        for _, rows in frames.values():
            for w, k, on in rows:
                n[key(w, k)] += 1
                visible[key(w, k)] += on == "V"
    return {b: visible[b] / n[b] for b in n}


def mae(runs, count):
    """Mean over runs of the mean |count(labels) − true| per frame."""
    per_run = [sum(abs(count(rows) - t) for t, rows in f.values()) / len(f) for f in runs]
    return sum(per_run) / len(per_run)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder")
    ap.add_argument("--scenes", default="crossing,intersection,road")
    ap.add_argument("--test-seeds", default="1,2,3")
    ap.add_argument("--fit-seeds", default="4,5,6")
    a = ap.parse_args()
    test_seeds = [int(s) for s in a.test_seeds.split(",")]
    fit_seeds = [int(s) for s in a.fit_seeds.split(",")]
    for scene in a.scenes.split(","):
        test = [load(a.folder, scene, s) for s in test_seeds]
        train = [load(a.folder, scene, s) for s in fit_seeds]
        print(f"## {scene}\n")
        print(f"What the labels lie on (seeds {a.fit_seeds}): V visible >= 0.3, H hidden, "
              "D another label's object, N none; share of rows / mean weight\n")
        print("| misses in a row | rows | V | H | D | N |")
        print("| ---: | ---: | --- | --- | --- | --- |")
        tab = collections.defaultdict(list)
        for frames in train:
            for _, rows in frames.values():
                for w, k, on in rows:
                    tab[min(k, 4)].append((w, on))
        for k in sorted(tab):
            rows = tab[k]
            cells = []
            for c in "VHDN":
                ws = [w for w, on in rows if on == c]
                cells.append(f"{len(ws) / len(rows):.2f} / {sum(ws) / max(len(ws), 1):.2f}")
            print(f"| {k}{'+' if k == 4 else ''} | {len(rows)} | " + " | ".join(cells) + " |")
        held, own = fit(train), fit(test)

        def p_visible(table):
            return lambda rows: [table.get(key(w, k), min(w, 1.0)) for w, k, _ in rows]

        print(f"\nCount MAE, seeds {a.test_seeds}:\n")
        print("| count | mean (Σ) | mode |")
        print("| --- | ---: | ---: |")
        for name, probs in [
            ("the filter's weights w", lambda rows: [w for w, _, _ in rows]),
            (f"P(visible | misses, w), held out (fit on {a.fit_seeds})", p_visible(held)),
            (f"P(visible | misses, w), fitted in sample ({a.test_seeds})", p_visible(own)),
        ]:
            m_sum = mae(test, lambda rows, p=probs: sum(p(rows)))
            m_mode = mae(test, lambda rows, p=probs: mode(p(rows)))
            print(f"| {name} | {m_sum:.3f} | {m_mode:.3f} |")
        print()


if __name__ == "__main__":
    main()
