#!/usr/bin/env python3
"""Golden files for `roadtrack::eval` parity with TrackEval (and py-motmetrics).

Writes ground-truth / tracker pairs and the metrics TrackEval computes on them into
crates/roadtrack/tests/golden/metrics/ (see the README there for the exact command).
The Rust tests (crates/roadtrack/src/eval/golden_tests.rs) read these files and assert
agreement to 1e-6 on every value; they never run Python.

    python scripts/golden_metrics.py                  # regenerate the golden files
    python scripts/golden_metrics.py --bench DIR      # MOT17-sized input + TrackEval timing

Needs: pip install trackeval motmetrics "numpy<2" scipy pandas.
"""
import argparse
import contextlib
import io
import json
import os
import shutil
import sys
import tempfile
import time

import numpy as np
from scipy.optimize import linear_sum_assignment

import trackeval
from trackeval.datasets._base_dataset import _BaseDataset
import motmetrics as mm

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, '..', 'crates', 'roadtrack', 'tests', 'golden', 'metrics')
MM_DATA = os.path.join(os.path.dirname(mm.__file__), 'data')
DISTRACTORS = [2, 7, 8, 12]
EPS = np.finfo('float').eps


# ---------------------------------------------------------------------------------------
# Files


def fmt(x):
    """Shortest text that parses back to the same double (repr), integers without '.0'."""
    x = float(x)
    return str(int(x)) if x == int(x) and abs(x) < 1e15 else repr(x)


def write_gt(path, rows):
    """rows: (frame, id, left, top, w, h, consider, class, visibility); sorted by frame, id."""
    rows = sorted(rows, key=lambda r: (r[0], r[1]))
    with open(path, 'w') as f:
        for r in rows:
            f.write(','.join([str(int(r[0])), str(int(r[1]))] + [fmt(v) for v in r[2:6]]
                             + [str(int(r[6])), str(int(r[7])), fmt(r[8])]) + '\n')


def write_tracks(path, rows):
    """rows: (frame, id, left, top, w, h[, class]); MOTChallenge layout, class not written."""
    rows = sorted(rows, key=lambda r: (r[0], r[1]))
    with open(path, 'w') as f:
        for r in rows:
            f.write(','.join([str(int(r[0])), str(int(r[1]))] + [fmt(v) for v in r[2:6]]
                             + ['1', '-1', '-1', '-1']) + '\n')


def load_mot15(path):
    rows = []
    for line in open(path):
        p = line.strip().split(',')
        if len(p) < 6:
            continue
        rows.append((int(float(p[0])), int(float(p[1])), *map(float, p[2:6])))
    return rows


# ---------------------------------------------------------------------------------------
# TrackEval runs


def block_from_trackeval(clear, ident, hota, counts):
    """One metrics block with the Rust report's key names."""
    out = {}
    for k in ['MOTA', 'MOTP', 'MODA', 'CLR_Re', 'CLR_Pr', 'MTR', 'PTR', 'MLR', 'sMOTA',
              'CLR_F1', 'FP_per_frame', 'MOTAL', 'MOTP_sum', 'CLR_TP', 'CLR_FN', 'CLR_FP',
              'IDSW', 'MT', 'PT', 'ML', 'Frag', 'CLR_Frames']:
        out[k] = float(clear[k])
    out['TP'], out['FP'], out['FN'] = out['CLR_TP'], out['CLR_FP'], out['CLR_FN']
    for k in ['IDF1', 'IDR', 'IDP', 'IDTP', 'IDFN', 'IDFP']:
        out[k] = float(ident[k])
    per_alpha = {'alpha': [float(a) for a in np.arange(0.05, 0.99, 0.05)]}
    for k in ['HOTA', 'DetA', 'AssA', 'DetRe', 'DetPr', 'AssRe', 'AssPr', 'LocA', 'OWTA']:
        out[k] = float(np.mean(hota[k]))
        per_alpha[k] = [float(v) for v in hota[k]]
    for k in ['HOTA_TP', 'HOTA_FN', 'HOTA_FP']:
        per_alpha[k] = [float(v) for v in hota[k]]
    for k in ['HOTA(0)', 'LocA(0)', 'HOTALocA(0)']:
        out[k] = float(hota[k])
    out['per_alpha'] = per_alpha
    if counts is not None:
        out.update(counts)
    return out


def run_trackeval_mot(gt_file, tr_file, n_frames, do_preproc=True):
    """TrackEval's own MotChallenge2DBox (MOT17, pedestrian) pipeline on one sequence."""
    with tempfile.TemporaryDirectory() as d:
        os.makedirs(os.path.join(d, 'gt', 'seq', 'gt'))
        os.makedirs(os.path.join(d, 'tr', 'T', 'data'))
        shutil.copy(gt_file, os.path.join(d, 'gt', 'seq', 'gt', 'gt.txt'))
        shutil.copy(tr_file, os.path.join(d, 'tr', 'T', 'data', 'seq.txt'))
        ev = trackeval.Evaluator({'USE_PARALLEL': False, 'PRINT_RESULTS': False,
                                  'PRINT_CONFIG': False, 'TIME_PROGRESS': False,
                                  'OUTPUT_SUMMARY': False, 'OUTPUT_DETAILED': False,
                                  'PLOT_CURVES': False, 'DISPLAY_LESS_PROGRESS': True,
                                  'LOG_ON_ERROR': None})
        ds = trackeval.datasets.MotChallenge2DBox({
            'GT_FOLDER': os.path.join(d, 'gt'), 'TRACKERS_FOLDER': os.path.join(d, 'tr'),
            'SKIP_SPLIT_FOL': True, 'SEQ_INFO': {'seq': n_frames}, 'TRACKERS_TO_EVAL': ['T'],
            'BENCHMARK': 'MOT17', 'PRINT_CONFIG': False, 'DO_PREPROC': do_preproc})
        metrics = [trackeval.metrics.HOTA(), trackeval.metrics.CLEAR({'PRINT_CONFIG': False}),
                   trackeval.metrics.Identity({'PRINT_CONFIG': False})]
        with contextlib.redirect_stdout(io.StringIO()):
            res, msg = ev.evaluate([ds], metrics)
        if msg['MotChallenge2DBox']['T'] != 'Success':
            raise RuntimeError(msg)
        r = res['MotChallenge2DBox']['T']['seq']['pedestrian']
        c = r['Count']
        counts = {'gt_dets': float(c['GT_Dets']), 'tracker_dets': float(c['Dets']),
                  'gt_ids': float(c['GT_IDs']), 'tracker_ids': float(c['IDs'])}
        return block_from_trackeval(r['CLEAR'], r['Identity'], r['HOTA'], counts)


def our_preprocess(gt, tr, n_frames, gt_classes, tracker_class, do_preproc=True):
    """Our documented multi-class extension of TrackEval's MOT preprocessing (EVALUATION.md).

    gt rows: (frame, id, l, t, w, h, consider, class, vis); tr rows: (frame, id, l, t, w, h, class).
    With gt_classes = [1] and tracker_class = None this is TrackEval's MOT17 preprocessing
    (checked against TrackEval's own pipeline in `selfcheck`).
    """
    data = {k: [] for k in ['gt_ids', 'tracker_ids', 'similarity_scores']}
    ug, ut = set(), set()
    for t in range(1, n_frames + 1):
        g = sorted([r for r in gt if r[0] == t], key=lambda r: r[1])
        k = sorted([r for r in tr if r[0] == t and (tracker_class is None or r[6] == tracker_class)],
                   key=lambda r: r[1])
        gd = np.array([r[2:6] for r in g], dtype=float).reshape(-1, 4)
        kd = np.array([r[2:6] for r in k], dtype=float).reshape(-1, 4)
        sim = _BaseDataset._calculate_box_ious(gd, kd, box_format='xywh')
        remove = np.array([], int)
        if do_preproc and len(g) and len(k):
            ms = sim.copy()
            ms[ms < 0.5 - EPS] = 0
            rr, cc = linear_sum_assignment(-ms)
            m = ms[rr, cc] > 0 + EPS
            rr, cc = rr[m], cc[m]
            isd = np.isin(np.array([r[7] for r in g])[rr], DISTRACTORS)
            remove = cc[isd]
        kid = np.delete(np.array([r[1] for r in k], int), remove)
        sim = np.delete(sim, remove, axis=1)
        keep = np.array([bool(r[6]) and (not do_preproc or r[7] in gt_classes) for r in g], bool)
        gid = np.array([r[1] for r in g], int)[keep] if len(g) else np.array([], int)
        data['gt_ids'].append(gid)
        data['tracker_ids'].append(kid)
        data['similarity_scores'].append(sim[keep] if len(g) else sim)
        ug |= set(gid.tolist())
        ut |= set(kid.tolist())
    gmap = {v: i for i, v in enumerate(sorted(ug))}
    tmap = {v: i for i, v in enumerate(sorted(ut))}
    data['gt_ids'] = [np.array([gmap[x] for x in a], int) for a in data['gt_ids']]
    data['tracker_ids'] = [np.array([tmap[x] for x in a], int) for a in data['tracker_ids']]
    data['num_gt_ids'], data['num_tracker_ids'] = len(ug), len(ut)
    data['num_gt_dets'] = sum(len(a) for a in data['gt_ids'])
    data['num_tracker_dets'] = sum(len(a) for a in data['tracker_ids'])
    data['num_timesteps'] = n_frames
    data['seq'] = 'seq'
    return data


def metrics_on(data):
    """TrackEval's metric classes on a preprocessed data dict (raw results)."""
    h = trackeval.metrics.HOTA()
    c = trackeval.metrics.CLEAR({'PRINT_CONFIG': False})
    i = trackeval.metrics.Identity({'PRINT_CONFIG': False})
    counts = {'gt_dets': float(data['num_gt_dets']), 'tracker_dets': float(data['num_tracker_dets']),
              'gt_ids': float(data['num_gt_ids']), 'tracker_ids': float(data['num_tracker_ids'])}
    return (c.eval_sequence(data), i.eval_sequence(data), h.eval_sequence(data), counts)


def combine(raws, how):
    h = trackeval.metrics.HOTA()
    c = trackeval.metrics.CLEAR({'PRINT_CONFIG': False})
    i = trackeval.metrics.Identity({'PRINT_CONFIG': False})
    cr = {k: v[0] for k, v in raws.items()}
    ir = {k: v[1] for k, v in raws.items()}
    hr = {k: v[2] for k, v in raws.items()}
    counts = {k: sum(v[3][k] for v in raws.values()) for k in
              ['gt_dets', 'tracker_dets', 'gt_ids', 'tracker_ids']}
    if how == 'det':
        return block_from_trackeval(c.combine_classes_det_averaged(cr),
                                    i.combine_classes_det_averaged(ir),
                                    h.combine_classes_det_averaged(hr), counts)
    return block_from_trackeval(c.combine_classes_class_averaged(cr),
                                i.combine_classes_class_averaged(ir),
                                h.combine_classes_class_averaged(hr), counts)


CLASS_NAMES = {1: 'pedestrian', 3: 'car', 4: 'bicycle', 5: 'motorcycle', 6: 'non_mot_vehicle'}


def custom_report(gt, tr, n_frames, mode, classes):
    if mode == 'class_agnostic':
        b = block_from_trackeval(*metrics_on(our_preprocess(gt, tr, n_frames, classes, None)))
        return dict(b, num_frames=n_frames, mode=mode, per_class={'all': b}, class_averaged=None)
    present = {r[7] for r in gt} | {r[6] for r in tr}
    raws = {}
    for c in sorted(set(classes) & present):
        raws[CLASS_NAMES[c]] = metrics_on(our_preprocess(gt, tr, n_frames, [c], c))
    per = {k: block_from_trackeval(*v) for k, v in raws.items()}
    summary = combine(raws, 'det')
    return dict(summary, num_frames=n_frames, mode=mode, per_class=per,
                class_averaged=combine(raws, 'cls'))


# ---------------------------------------------------------------------------------------
# py-motmetrics


def run_motmetrics(gt_file, tr_file):
    gt = mm.io.loadtxt(gt_file, fmt='mot16', min_confidence=1)
    gt = gt[gt['ClassId'] == 1] if 'ClassId' in gt.columns else gt
    ts = mm.io.loadtxt(tr_file, fmt='mot16')
    acc = mm.utils.compare_to_groundtruth(gt, ts, 'iou', distth=0.5)
    mh = mm.metrics.create()
    names = ['mota', 'motp', 'num_false_positives', 'num_misses', 'num_switches',
             'num_fragmentations', 'mostly_tracked', 'partially_tracked', 'mostly_lost',
             'idf1', 'idp', 'idr', 'idtp', 'idfn', 'idfp', 'num_detections']
    s = mh.compute(acc, metrics=names, name='x')
    r = {k: float(s[k].iloc[0]) for k in names}
    # Same keys as TrackEval; motmetrics' MOTP is a distance (1 − IoU).
    return {'MOTA': r['mota'], 'MOTP': 1.0 - r['motp'], 'CLR_FP': r['num_false_positives'],
            'CLR_FN': r['num_misses'], 'IDSW': r['num_switches'], 'Frag': r['num_fragmentations'],
            'MT': r['mostly_tracked'], 'PT': r['partially_tracked'], 'ML': r['mostly_lost'],
            'CLR_TP': r['num_detections'], 'IDF1': r['idf1'], 'IDP': r['idp'], 'IDR': r['idr'],
            'IDTP': r['idtp'], 'IDFN': r['idfn'], 'IDFP': r['idfp']}


# ---------------------------------------------------------------------------------------
# Inputs


def tud_gt(name):
    """motmetrics' shipped MOT15 ground truth as MOT17 rows (consider 1, pedestrian)."""
    return [(f, i, l, t, w, h, 1, 1, 1.0) for f, i, l, t, w, h in
            load_mot15(os.path.join(MM_DATA, name, 'gt.txt'))]


def tud_shipped_tracker(name):
    return [(f, i, l, t, w, h, 1) for f, i, l, t, w, h in
            load_mot15(os.path.join(MM_DATA, name, 'test.txt'))]


def perturb(gt, rng, p_drop=0.05, n_swaps=2, jitter=3.0, n_fp=30, n_frag=3, id_offset=100):
    """A tracker made from ground truth: random drops, gaps that fragment tracks (new id
    after the gap), id swaps between two tracks from a frame on, box jitter, false positives."""
    rows = [list(r[:6]) + [r[7]] for r in gt if r[6]]
    rows = [r for r in rows if rng.random() > p_drop]
    ids = sorted({r[1] for r in rows})
    frames = sorted({r[0] for r in rows})
    for _ in range(n_frag):
        i = ids[rng.integers(len(ids))]
        own = sorted(r[0] for r in rows if r[1] == i)
        if len(own) < 10:
            continue
        a = own[rng.integers(2, len(own) - 5)]
        gap = int(rng.integers(1, 4))
        rows = [r for r in rows if not (r[1] == i and a <= r[0] < a + gap)]
        for r in rows:
            if r[1] == i and r[0] >= a + gap:
                r[1] = i + id_offset
        id_offset += 100
    for _ in range(n_swaps):
        a, b = rng.choice(ids, 2, replace=False)
        f0 = frames[rng.integers(len(frames))]
        for r in rows:
            if r[0] >= f0 and r[1] in (a, b):
                r[1] = b if r[1] == a else a
    for r in rows:
        r[2] = round(r[2] + rng.normal(0, jitter), 2)
        r[3] = round(r[3] + rng.normal(0, jitter), 2)
        r[4] = round(max(1.0, r[4] * (1 + rng.normal(0, jitter / 100))), 2)
        r[5] = round(max(1.0, r[5] * (1 + rng.normal(0, jitter / 100))), 2)
    boxes = np.array([r[2:6] for r in gt]) if gt else np.array([[0, 0, 50, 100]])
    for k in range(n_fp):
        f = frames[rng.integers(len(frames))]
        l, t, w, h = boxes[rng.integers(len(boxes))]
        rows.append([f, 9000 + k % 7, round(l + rng.normal(0, 60), 2), round(t + rng.normal(0, 20), 2),
                     w, h, 1])
    # Drop any (frame, id) duplicate the swaps or FP ids created.
    seen, out = set(), []
    for r in rows:
        if (r[0], r[1]) not in seen:
            seen.add((r[0], r[1]))
            out.append(tuple(r))
    return out


def synthetic_objects(rng, n_frames, n_objects, classes, area=(640, 480), integer=True):
    """Objects moving on straight lines with class-typical box sizes; integer coordinates
    make exact IoU ties common (a hard case for matching order)."""
    sizes = {1: (24, 60), 3: (90, 50), 4: (40, 50), 5: (45, 50), 6: (120, 70),
             2: (30, 60), 7: (24, 60), 8: (24, 60), 12: (24, 60)}
    gt = []
    for i in range(1, n_objects + 1):
        c = classes[(i - 1) % len(classes)]
        w, h = sizes[c]
        start = int(rng.integers(1, max(2, n_frames // 2)))
        end = int(min(n_frames, start + rng.integers(n_frames // 3, n_frames)))
        x, y = rng.uniform(0, area[0] - w), rng.uniform(0, area[1] - h)
        vx, vy = rng.normal(0, 3), rng.normal(0, 2)
        for f in range(start, end + 1):
            l, t = x + vx * (f - start), y + vy * (f - start)
            if integer:
                l, t = round(l), round(t)
            gt.append((f, i, float(l), float(t), float(w), float(h), 1, c, 1.0))
    return gt


# ---------------------------------------------------------------------------------------
# Cases


def write_case(name, gt, tr, n_frames, config, expected, motmetrics=None, track_classes=False):
    write_gt(os.path.join(OUT, name + '.gt.txt'), gt)
    write_tracks(os.path.join(OUT, name + '.tracks.txt'), tr)
    if track_classes:
        with open(os.path.join(OUT, name + '.track_classes.csv'), 'w') as f:
            f.write('frame,id,class\n')
            for r in sorted(tr, key=lambda r: (r[0], r[1])):
                f.write('%d,%d,%d\n' % (r[0], r[1], r[6]))
    doc = {'config': config, 'trackeval': expected}
    if motmetrics is not None:
        doc['motmetrics'] = motmetrics
    with open(os.path.join(OUT, name + '.json'), 'w') as f:
        json.dump(doc, f, indent=1, sort_keys=True)
        f.write('\n')


def selfcheck(gt, tr, n_frames, te):
    """Our Python preprocessing in pedestrian mode must give TrackEval's pipeline numbers."""
    mine = block_from_trackeval(*metrics_on(our_preprocess(gt, tr, n_frames, [1], None)))
    for k, v in te.items():
        if k == 'per_alpha':
            continue
        assert abs(mine[k] - v) < 1e-12, (k, mine[k], v)


def mot_case(name, gt, tr, rng_note, do_preproc=True):
    n = max(r[0] for r in gt + tr)
    with tempfile.TemporaryDirectory() as d:
        gf, tf = os.path.join(d, 'gt.txt'), os.path.join(d, 'tr.txt')
        write_gt(gf, gt)
        write_tracks(tf, tr)
        te = run_trackeval_mot(gf, tf, n, do_preproc)
        if do_preproc:
            selfcheck(gt, tr, n, te)
        mmr = run_motmetrics(gf, tf) if gt and tr else None
    report = dict(te, num_frames=n, mode='pedestrian', per_class={'pedestrian': te},
                  class_averaged=None)
    write_case(name, gt, tr, n, {'mode': 'pedestrian', 'preprocess': do_preproc,
                                 'num_frames': n, 'note': rng_note}, report, mmr)
    return te, mmr


def main_golden():
    os.makedirs(OUT, exist_ok=True)
    for f in os.listdir(OUT):
        if f.endswith(('.txt', '.json', '.csv')):
            os.remove(os.path.join(OUT, f))
    rng = np.random.default_rng(4)
    summary = {}

    campus, stadt = tud_gt('TUD-Campus'), tud_gt('TUD-Stadtmitte')
    summary['tud_campus_shipped'] = mot_case(
        'tud_campus_shipped', campus, tud_shipped_tracker('TUD-Campus'),
        "motmetrics' TUD-Campus gt and its shipped tracker output")
    summary['tud_campus_perturbed'] = mot_case(
        'tud_campus_perturbed', campus, perturb(campus, rng),
        'drops 5 %, 3 fragmentations, 2 id swaps, jitter 3 px, 30 false positives')
    summary['tud_stadtmitte_shipped'] = mot_case(
        'tud_stadtmitte_shipped', stadt, tud_shipped_tracker('TUD-Stadtmitte'),
        "motmetrics' TUD-Stadtmitte gt and its shipped tracker output")
    summary['tud_stadtmitte_perturbed'] = mot_case(
        'tud_stadtmitte_perturbed', stadt,
        perturb(stadt, rng, p_drop=0.15, n_swaps=4, jitter=8.0, n_fp=80, n_frag=6),
        'drops 15 %, 6 fragmentations, 4 id swaps, jitter 8 px, 80 false positives')

    # Distractors, ignored rows and a non-evaluated class on TUD-Stadtmitte.
    ids = sorted({r[1] for r in stadt})
    recls = {ids[0]: 2, ids[1]: 7, ids[2]: 8, ids[3]: 12, ids[4]: 3}
    dgt = [(f, i, l, t, w, h, 0 if (i == ids[5] and f % 3 == 0) else c, recls.get(i, 1), v)
           for f, i, l, t, w, h, c, _, v in stadt]
    dtr = perturb(stadt, rng, p_drop=0.05, n_swaps=1, jitter=2.0, n_fp=20, n_frag=2)
    summary['stadtmitte_distractors'] = mot_case(
        'stadtmitte_distractors', dgt, dtr,
        'ids relabelled as classes 2, 7, 8, 12 (distractors) and 3 (car), one id with '
        'consider = 0 every third frame; tracker covers them all')
    summary['stadtmitte_distractors_no_preproc'] = mot_case(
        'stadtmitte_distractors_no_preproc', dgt, dtr, 'as stadtmitte_distractors, DO_PREPROC False',
        do_preproc=False)

    crowd = synthetic_objects(rng, 60, 40, [1], area=(200, 160))
    summary['synthetic_crowded'] = mot_case(
        'synthetic_crowded', crowd,
        perturb(crowd, rng, p_drop=0.1, n_swaps=6, jitter=1.0, n_fp=40, n_frag=5),
        '40 pedestrians in 200 × 160 px, integer boxes (exact IoU ties), swaps, jitter 1 px')
    small = synthetic_objects(rng, 20, 5, [1])
    summary['synthetic_empty_tracker'] = mot_case(
        'synthetic_empty_tracker', small, [], 'empty tracks file')
    summary['synthetic_empty_gt'] = mot_case(
        'synthetic_empty_gt', [], perturb(small, rng, p_drop=0, n_swaps=0, n_fp=0, n_frag=0),
        'empty ground-truth file')
    # Perfect tracker: every metric at its best.
    summary['synthetic_perfect'] = mot_case(
        'synthetic_perfect', small, [r[:6] + (1,) for r in small], 'tracker = ground truth')

    # Multi-class: pedestrians, cars, bicycles; tracker classes with misclassifications.
    mgt = synthetic_objects(rng, 40, 18, [1, 3, 4], area=(400, 300), integer=False)
    mgt += [(f, 100, 10.0, 10.0, 24.0, 60.0, 1, 8, 1.0) for f in range(1, 41)]  # distractor
    mtr = perturb([r for r in mgt if r[7] != 8], rng, p_drop=0.08, n_swaps=3, jitter=2.0,
                  n_fp=25, n_frag=3)
    mtr = [r[:6] + ((3 if r[6] == 1 else 1) if rng.random() < 0.05 else r[6],) for r in mtr]
    mtr += [(f, 500, 10.0, 10.0, 24.0, 60.0, 1) for f in range(1, 41)]  # on the distractor
    n = 40
    classes = [1, 3, 4, 5, 6]
    write_case('multiclass_per_class', mgt, mtr, n,
               {'mode': 'per_class', 'classes': classes, 'num_frames': n,
                'note': 'TrackEval metric classes on our per-class preprocessing; combined by '
                        'combine_classes_det_averaged / class_averaged'},
               custom_report(mgt, mtr, n, 'per_class', classes), track_classes=True)
    write_case('multiclass_agnostic', mgt, mtr, n,
               {'mode': 'class_agnostic', 'classes': classes, 'num_frames': n,
                'note': 'TrackEval metric classes on our class-agnostic preprocessing'},
               custom_report(mgt, mtr, n, 'class_agnostic', classes))
    summary['multiclass_pedestrian'] = mot_case(
        'multiclass_pedestrian', mgt, mtr, 'multi-class scene, TrackEval MOT17 pedestrian pipeline')

    # Report where TrackEval and py-motmetrics disagree.
    lines = []
    for name, (te, mmr) in summary.items():
        if mmr is None:
            continue
        diffs = [f'{k}: TrackEval {te[k]:.6g} motmetrics {v:.6g}' for k, v in mmr.items()
                 if abs(te[k] - v) > 1e-9]
        lines.append(f'{name}: ' + ('; '.join(diffs) if diffs else 'all CLEAR/identity values agree'))
    with open(os.path.join(OUT, 'motmetrics_disagreements.txt'), 'w') as f:
        f.write('\n'.join(lines) + '\n')
    print('\n'.join(lines))


# ---------------------------------------------------------------------------------------
# Benchmark input


def main_bench(d, reps):
    os.makedirs(d, exist_ok=True)
    rng = np.random.default_rng(17)
    gt = synthetic_objects(rng, 600, 45, [1], area=(1920, 1080), integer=False)
    tr = perturb(gt, rng, p_drop=0.1, n_swaps=10, jitter=4.0, n_fp=1500, n_frag=15)
    gf, tf = os.path.join(d, 'gt.txt'), os.path.join(d, 'tracks.txt')
    write_gt(gf, gt)
    write_tracks(tf, tr)
    per_frame = len(gt) / 600
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        te = run_trackeval_mot(gf, tf, 600)
        times.append(time.perf_counter() - t0)
    # Phases: loading (file parsing and IoU matrices) vs preprocessing + the three metrics.
    load_t, metric_t = [], []
    with tempfile.TemporaryDirectory() as tmp:
        os.makedirs(os.path.join(tmp, 'gt', 'seq', 'gt'))
        os.makedirs(os.path.join(tmp, 'tr', 'T', 'data'))
        shutil.copy(gf, os.path.join(tmp, 'gt', 'seq', 'gt', 'gt.txt'))
        shutil.copy(tf, os.path.join(tmp, 'tr', 'T', 'data', 'seq.txt'))
        ds = trackeval.datasets.MotChallenge2DBox({
            'GT_FOLDER': os.path.join(tmp, 'gt'), 'TRACKERS_FOLDER': os.path.join(tmp, 'tr'),
            'SKIP_SPLIT_FOL': True, 'SEQ_INFO': {'seq': 600}, 'TRACKERS_TO_EVAL': ['T'],
            'BENCHMARK': 'MOT17', 'PRINT_CONFIG': False})
        ms = [trackeval.metrics.HOTA(), trackeval.metrics.CLEAR({'PRINT_CONFIG': False}),
              trackeval.metrics.Identity({'PRINT_CONFIG': False})]
        for _ in range(reps):
            t0 = time.perf_counter()
            raw = ds.get_raw_seq_data('T', 'seq')
            t1 = time.perf_counter()
            data = ds.get_preprocessed_seq_data(raw, 'pedestrian')
            for m in ms:
                m.eval_sequence(data)
            t2 = time.perf_counter()
            load_t.append(t1 - t0)
            metric_t.append(t2 - t1)
    with open(os.path.join(d, 'expected.json'), 'w') as f:
        json.dump({'trackeval': te, 'trackeval_seconds': times, 'trackeval_load_seconds': load_t,
                   'trackeval_metrics_seconds': metric_t}, f, indent=1)
    print(f'{len(gt)} gt rows ({per_frame:.1f} per frame), {len(tr)} tracker rows, 600 frames')
    print('TrackEval end to end (Evaluator, HOTA + CLEAR + Identity, one process): '
          + ', '.join(f'{t:.3f}' for t in times) + ' s; min %.3f s' % min(times))
    print('TrackEval phases: load + IoU min %.3f s; preprocessing + metrics min %.3f s'
          % (min(load_t), min(metric_t)))
    print('MOTA %.6f IDF1 %.6f HOTA %.6f' % (te['MOTA'], te['IDF1'], te['HOTA']))


if __name__ == '__main__':
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument('--bench', metavar='DIR', help='write the MOT17-sized input to DIR and time TrackEval')
    ap.add_argument('--reps', type=int, default=3)
    a = ap.parse_args()
    if a.bench:
        main_bench(a.bench, a.reps)
    else:
        main_golden()
