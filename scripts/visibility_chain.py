#!/usr/bin/env python3
"""A count of visible objects from the detection PHD's label histories, tried and not
kept (docs/EXPERIMENTS.md "A count of visible objects from the labels' histories").

Each label's history (detected or not in every frame of its life) is read as the output
of a three-state chain: visible (detected with p_detect; moves to hidden with p_hide, to
none with p_end), hidden (detected with p_spurious; back to visible with p_reveal, to none
with p_end), none (detected with p_spurious; absorbing), starting visible with p_real. The
six probabilities are fitted to all label histories of one run by Baum-Welch (20
iterations, no ground truth); the count at a frame is the sum over labels of P(visible)
given the history up to `lag` frames later (or all of it).

Reads the per-label rows of the ignored test `count_after_miss_probe` (a label's row with
`misses` 0 is a frame where it was detected):

    RT_OUT=/tmp/count_probe RT_SEEDS=1,2,3,4,5,6 RT_SCENES=crossing,intersection,road \\
      cargo test --release -p roadtrack --lib count_after_miss_probe -- --ignored
    python3 scripts/visibility_chain.py /tmp/count_probe --seeds 4,5,6 --lags 2,3,5,0

and prints the count MAE per scene and look-ahead (0: the whole history), the sum and its
mode, with the per-seed sums. Needs numpy.
"""
import argparse
import collections
import csv
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from count_calibration import mode  # noqa: E402

S = 3  # visible, hidden, none


def load(folder, scene, seed):
    """Label histories {label: [(frame, hit)]} and the true count per frame."""
    labels, truth = collections.defaultdict(list), {}
    with open(os.path.join(folder, f"{scene}_{seed}.csv")) as f:
        for r in csv.DictReader(f):
            frame = int(r["frame"])
            truth[frame] = int(r["true_count"])
            if r["on"] != "E":
                labels[int(r["label"])].append((frame, int(r["misses"]) == 0))
    return labels, truth


def chain(p_detect, p_spurious, p_hide, p_reveal, p_end, p_real):
    a = np.array([[1 - p_hide - p_end, p_hide, p_end],
                  [p_reveal, 1 - p_reveal - p_end, p_end],
                  [0.0, 0.0, 1.0]])
    e = np.array([[1 - p_detect, p_detect], [1 - p_spurious, p_spurious],
                  [1 - p_spurious, p_spurious]])
    return a, e, np.array([p_real, 0.0, 1 - p_real])


def forward_backward(obs, a, e, p0):
    n = len(obs)
    al, be, c = np.zeros((n, S)), np.ones((n, S)), np.zeros(n)
    x = p0 * e[:, obs[0]]
    c[0] = x.sum()
    al[0] = x / c[0]
    for t in range(1, n):
        x = (al[t - 1] @ a) * e[:, obs[t]]
        c[t] = x.sum()
        al[t] = x / c[t]
    for t in range(n - 2, -1, -1):
        be[t] = a @ (e[:, obs[t + 1]] * be[t + 1]) / c[t + 1]
    return al, be, c


def fit(histories, iterations=20):
    th = (0.9, 0.02, 0.02, 0.2, 0.01, 0.5)
    for _ in range(iterations):
        a, e, p0 = chain(*th)
        n_move, n_obs, n_start = np.zeros((S, S)), np.zeros((S, 2)), np.zeros(S)
        for obs in histories:
            al, be, c = forward_backward(obs, a, e, p0)
            g = al * be
            g /= g.sum(1, keepdims=True)
            n_start += g[0]
            for t, o in enumerate(obs):
                n_obs[:, o] += g[t]
            for t in range(len(obs) - 1):
                xi = al[t][:, None] * a * (e[:, obs[t + 1]] * be[t + 1])[None, :] / c[t + 1]
                n_move += xi / xi.sum()
        th = (n_obs[0, 1] / n_obs[0].sum(),
              (n_obs[1, 1] + n_obs[2, 1]) / (n_obs[1].sum() + n_obs[2].sum()),
              n_move[0, 1] / n_move[0].sum(), n_move[1, 0] / n_move[1].sum(),
              (n_move[0, 2] + n_move[1, 2]) / (n_move[0].sum() + n_move[1].sum()),
              n_start[0] / n_start.sum())
    return th


def visible(obs, th, lag):
    a, e, p0 = chain(*th)
    al, _, _ = forward_backward(obs, a, e, p0)
    n, out = len(obs), []
    for t in range(n):
        end = n - 1 if lag == 0 else min(n - 1, t + lag)
        b = np.ones(S)
        for j in range(end, t, -1):
            b = a @ (e[:, obs[j]] * b)
            b /= b.sum()
        p = al[t] * b
        out.append(p[0] / p.sum())
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder")
    ap.add_argument("--scenes", default="crossing,intersection,road")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--lags", default="1,2,3,5,0")
    a = ap.parse_args()
    seeds = [int(s) for s in a.seeds.split(",")]
    lags = [int(s) for s in a.lags.split(",")]
    print("| scene | look-ahead | count MAE Σ / mode | per seed Σ |")
    print("| --- | ---: | --- | --- |")
    runs = {}
    for scene in a.scenes.split(","):
        for seed in seeds:
            labels, truth = load(a.folder, scene, seed)
            obs = {k: [int(h) for _, h in v] for k, v in labels.items()}
            runs[scene, seed] = (labels, truth, obs, fit(list(obs.values())))
        for lag in lags:
            sums, modes = [], []
            for seed in seeds:
                labels, truth, obs, th = runs[scene, seed]
                per = collections.defaultdict(list)
                for k, v in labels.items():
                    for (frame, _), p in zip(v, visible(obs[k], th, lag)):
                        per[frame].append(p)
                frames = sorted(truth)
                sums.append(np.mean([abs(sum(per[f]) - truth[f]) for f in frames]))
                modes.append(np.mean([abs(mode(per[f]) - truth[f]) for f in frames]))
            name = "whole" if lag == 0 else str(lag)
            print(f"| {scene} | {name} | {np.mean(sums):.3f} / {np.mean(modes):.3f} | "
                  + ", ".join(f"{s:.2f}" for s in sums) + " |", flush=True)


if __name__ == "__main__":
    main()
