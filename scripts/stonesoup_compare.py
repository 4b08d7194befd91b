#!/usr/bin/env python3
"""Stone Soup GM-PHD (and SMC-PHD) on the committed point scenario, against roadtrack's
labelled SMC-PHD (`filter_points`).

Reads  crates/roadtrack/tests/golden/filter/{measurements,truth,estimates}.csv
Writes crates/roadtrack/tests/golden/filter/stonesoup_ospa.csv   (OSPA per step, c=20, p=1)
       crates/roadtrack/tests/golden/filter/stonesoup_summary.json
Usage: pip install stonesoup==1.9.1 && python3 scripts/stonesoup_compare.py
The scenario model (matched in both filters) is PointScenarioConfig::default() in
crates/roadtrack-sim/src/points.rs.
"""
import csv
import datetime
import json
import os
import sys
import time

import numpy as np
from scipy.optimize import linear_sum_assignment

import stonesoup
from stonesoup.models.transition.linear import (
    CombinedLinearGaussianTransitionModel, ConstantVelocity)
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.types.detection import Detection
from stonesoup.types.state import TaggedWeightedGaussianState
from stonesoup.predictor.kalman import KalmanPredictor
from stonesoup.updater.kalman import KalmanUpdater
from stonesoup.updater.pointprocess import PHDUpdater
from stonesoup.hypothesiser.distance import DistanceHypothesiser
from stonesoup.hypothesiser.gaussianmixture import GaussianMixtureHypothesiser
from stonesoup.measures import Mahalanobis
from stonesoup.mixturereducer.gaussianmixture import GaussianMixtureReducer

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
GOLDEN = os.path.join(ROOT, "crates/roadtrack/tests/golden/filter")

# PointScenarioConfig::default()
REGION = (0.0, 0.0, 500.0, 500.0)
P_D, P_S = 0.9, 0.99
CLUTTER_RATE, BIRTH_RATE = 10.0, 0.05
SIGMA_Z, SIGMA_A, SPEED_SIGMA = 2.0, 0.1, 2.0
OSPA_C = 20.0


def read_rows(name):
    with open(os.path.join(GOLDEN, name)) as f:
        return list(csv.DictReader(f))


def by_step(rows):
    out = {}
    for r in rows:
        out.setdefault(int(r["step"]), []).append((float(r["x"]), float(r["y"])))
    return out


def ospa(a, b, c=OSPA_C):
    """OSPA of order 1 (Schuhmacher et al. 2008)."""
    a, b = np.asarray(a, float).reshape(-1, 2), np.asarray(b, float).reshape(-1, 2)
    m, n = len(a), len(b)
    if m == 0 and n == 0:
        return 0.0
    if m == 0 or n == 0:
        return c
    d = np.minimum(np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2), c)
    r, k = linear_sum_assignment(d)
    return (d[r, k].sum() + c * abs(m - n)) / max(m, n)


def run_gmphd(steps, meas):
    t0 = datetime.datetime(2024, 1, 1)
    # Stone Soup's CV model is continuous white-noise acceleration (q·[[dt³/3, dt²/2],
    # [dt²/2, dt]]); the scenario draws piecewise-constant acceleration (σ²·[[1/4, 1/2],
    # [1/2, 1]] at dt = 1); q = σ² matches the velocity variance.
    transition = CombinedLinearGaussianTransitionModel(
        [ConstantVelocity(SIGMA_A ** 2), ConstantVelocity(SIGMA_A ** 2)])
    mm = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2) * SIGMA_Z ** 2)
    predictor = KalmanPredictor(transition)
    kupdater = KalmanUpdater(mm)
    area = (REGION[2] - REGION[0]) * (REGION[3] - REGION[1])
    updater = PHDUpdater(kupdater, clutter_spatial_density=CLUTTER_RATE / area,
                         prob_detection=P_D, prob_survival=P_S)
    hyp = GaussianMixtureHypothesiser(
        DistanceHypothesiser(predictor, kupdater, Mahalanobis(), missed_distance=4),
        order_by_detection=True)
    reducer = GaussianMixtureReducer(prune_threshold=1e-8, pruning=True,
                                     merge_threshold=16, merging=True)
    cx, cy = (REGION[0] + REGION[2]) / 2, (REGION[1] + REGION[3]) / 2
    # Birth: one wide Gaussian over the region (≈ uniform), weight = births per step.
    birth_covar = np.diag([(REGION[2] - REGION[0]) / 2, SPEED_SIGMA,
                           (REGION[3] - REGION[1]) / 2, SPEED_SIGMA]) ** 2
    states = set()
    est = {}
    start = time.perf_counter()
    for k in steps:
        ts = t0 + datetime.timedelta(seconds=k)
        birth = TaggedWeightedGaussianState(
            state_vector=[[cx], [0], [cy], [0]], covar=birth_covar,
            weight=BIRTH_RATE, tag="birth", timestamp=ts - datetime.timedelta(seconds=1))
        current = set(states) | {birth}
        dets = {Detection(np.array([[x], [y]]), timestamp=ts, measurement_model=mm)
                for x, y in meas.get(k, [])}
        hypotheses = hyp.hypothesise(current, dets, timestamp=ts, order_by_detection=True)
        updated = updater.update(hypotheses)
        states = set(reducer.reduce(updated))
        est[k] = []
        for s in states:
            # Standard extraction: round(weight) copies of each component of weight ≥ 0.5.
            if s.weight >= 0.5:
                for _ in range(max(1, int(round(float(s.weight))))):
                    est[k].append((float(s.state_vector[0, 0]), float(s.state_vector[2, 0])))
    return est, time.perf_counter() - start


def main():
    truth = by_step(read_rows("truth.csv"))
    meas = by_step(read_rows("measurements.csv"))
    ours = by_step(read_rows("estimates.csv"))
    steps = list(range(1, max(truth) + 1))
    gm, gm_time = run_gmphd(steps, meas)
    rows, summary = [], {}
    for k in steps:
        t = truth.get(k, [])
        rows.append({
            "step": k, "n_true": len(t),
            "n_gmphd": len(gm.get(k, [])), "ospa_gmphd": round(ospa(t, gm.get(k, [])), 4),
            "n_roadtrack": len(ours.get(k, [])), "ospa_roadtrack": round(ospa(t, ours.get(k, [])), 4),
        })
    with open(os.path.join(GOLDEN, "stonesoup_ospa.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    mean = lambda key: round(float(np.mean([r[key] for r in rows])), 4)
    cnt = lambda key: round(float(np.mean([abs(r[key] - r["n_true"]) for r in rows])), 4)
    summary = {
        "stonesoup_version": stonesoup.__version__,
        "python": sys.version.split()[0],
        "ospa_c": OSPA_C, "ospa_p": 1, "steps": len(steps),
        "gmphd": {"mean_ospa": mean("ospa_gmphd"), "mean_abs_count_error": cnt("n_gmphd"),
                  "wall_s": round(gm_time, 3)},
        "roadtrack_smcphd": {"mean_ospa": mean("ospa_roadtrack"),
                             "mean_abs_count_error": cnt("n_roadtrack")},
    }
    with open(os.path.join(GOLDEN, "stonesoup_summary.json"), "w") as f:
        json.dump(summary, f, indent=2)
        f.write("\n")
    print(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
