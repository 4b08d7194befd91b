#!/usr/bin/env python3
"""A GPU stage of the learned detector's recipe (docs/DETECTION.md "A GPU stage").

The crops and targets are roadtrack's own: `dump_samples` workers (crate roadtrack-learn,
`examples/dump_samples.rs`) render simulator episodes, corrupt them and cut samples exactly
as `roadtrack train --detector` does, and stream them here. This script only does what the
CPU trainer (burn, one thread) cannot do fast: the optimiser steps. The network, its
initialisation, the loss (CenterNet's focal loss, alpha 2, beta 4, and L1 on
ln(w/4), ln(h/4), dx, dy, both per object centre) and the cosine schedule follow
crates/roadtrack-learn/src/{net,train}.rs. Several networks can train side by side on the
same batches (`--model`), so that variants are compared on the same data.

Weights are written in the JSON that `roadtrack train --detector --from-weights W.json
-o W.onnx` converts. Not byte-deterministic (GPU kernels and the workers' timing decide
which samples meet in a batch): the CPU recipe is the deterministic one.

    python3 scripts/train_gpu.py --dumper target/release/examples/dump_samples \
        --model ft:models/detector.onnx:6e-4 --model wide:16,32,64,96,48:3e-3 \
        --seconds 420 --out OUTDIR

The shipped model's GPU stage (scripts/setup.sh runs it after the CPU stages when torch sees a
CUDA GPU): two runs from the last CPU stage, 450 s at peak rate 1.5e-3 (seed 0, simulator
seeds from 20000), then 255 s at 6e-4 (seed 1, from 60000); on one H200 with 14 workers
they made 19 163 and 22 303 steps of 128 crops, which --steps reproduces as a schedule.
"""

import argparse
import json
import math
import os
import queue
import struct
import subprocess
import sys
import threading
import time

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

CLASSES = 4
STRIDE = 4
PREP = {"input_scale": 1.0 / 255.0, "mean": [0.45] * 3, "std": [0.25] * 3}
HDR = struct.Struct("<4sIIII")
REG = np.dtype([("c", "<u4"), ("v", "<f4", (4,))])


def layer_specs(s):
    """(name, kind, cin, cout, k, stride) as CenterNetShape::layers."""
    return [
        ("conv1", "conv", 3, s["c1"], 3, 2),
        ("conv2", "conv", s["c1"], s["c2"], 3, 2),
        ("conv3", "conv", s["c2"], s["c2"], 3, 1),
        ("conv4", "conv", s["c2"], s["c3"], 3, 2),
        ("conv5", "conv", s["c3"], s["c3"], 3, 1),
        ("conv6", "conv", s["c3"], s["c4"], 3, 2),
        ("conv7", "conv", s["c4"], s["c4"], 3, 1),
        ("up1", "deconv", s["c4"], s["c3"], 2, 2),
        ("up2", "deconv", s["c3"], s["c2"], 2, 2),
        ("head", "conv", s["c2"], s["head"], 1, 1),
        ("heat", "conv", s["head"], CLASSES, 1, 1),
        ("box", "conv", s["head"], 4, 1, 1),
    ]


class CenterNet(nn.Module):
    """crates/roadtrack-learn/src/net.rs in torch (same layer names and weight layouts)."""

    def __init__(self, shape):
        super().__init__()
        self.shape = dict(shape)
        self.specs = layer_specs(shape)
        layers = {}
        for name, kind, cin, cout, k, st in self.specs:
            if kind == "conv":
                layers[name] = nn.Conv2d(cin, cout, k, st, k // 2)
            else:
                layers[name] = nn.ConvTranspose2d(cin, cout, k, st)
        self.layers = nn.ModuleDict(layers)

    def init_like_roadtrack(self, gen):
        """He-uniform, biases 0, output heads +-0.01, heat bias logit(0.1) (net.rs)."""
        with torch.no_grad():
            for name, kind, cin, _cout, k, _st in self.specs:
                m = self.layers[name]
                fan_in = cin * k * k if kind == "conv" else cin
                bound = 0.01 if name in ("heat", "box") else math.sqrt(6.0 / fan_in)
                m.weight.copy_(torch.rand(m.weight.shape, generator=gen) * 2 * bound - bound)
                m.bias.fill_(math.log(0.1 / 0.9) if name == "heat" else 0.0)

    def forward(self, x):
        L = self.layers
        r1 = F.relu(L["conv1"](x))
        r2 = F.relu(L["conv2"](r1))
        r3 = F.relu(L["conv3"](r2))
        r4 = F.relu(L["conv4"](r3))
        r5 = F.relu(L["conv5"](r4))
        r6 = F.relu(L["conv6"](r5))
        r7 = F.relu(L["conv7"](r6))
        m1 = F.relu(L["up1"](r7) + r5)
        m2 = F.relu(L["up2"](m1) + r3)
        h = F.relu(L["head"](m2))
        return L["heat"](h), L["box"](h)

    def to_json(self):
        layers = []
        for name, *_ in self.specs:
            m = self.layers[name]
            layers.append({
                "weight": m.weight.detach().float().cpu().reshape(-1).tolist(),
                "bias": m.bias.detach().float().cpu().tolist(),
            })
        return {"shape": self.shape, "layers": layers, "preprocessing": PREP}

    def load(self, weights):
        """weights: name -> (weight array, bias array)."""
        with torch.no_grad():
            for name, *_ in self.specs:
                w, b = weights[name]
                m = self.layers[name]
                m.weight.copy_(torch.from_numpy(np.asarray(w, np.float32).reshape(m.weight.shape)))
                m.bias.copy_(torch.from_numpy(np.asarray(b, np.float32)))


def shape_of(weights):
    return {
        "c1": weights["conv1"][0].shape[0],
        "c2": weights["conv2"][0].shape[0],
        "c3": weights["conv4"][0].shape[0],
        "c4": weights["conv6"][0].shape[0],
        "head": weights["head"][0].shape[0],
    }


def read_weights(path):
    """A learned detector's .onnx (initialisers NAME.w, NAME.b) or the trainer's JSON."""
    if path.endswith(".onnx"):
        import onnx
        from onnx import numpy_helper

        inits = {i.name: numpy_helper.to_array(i) for i in onnx.load(path).graph.initializer}
        names = [n for n, *_ in layer_specs({"c1": 1, "c2": 1, "c3": 1, "c4": 1, "head": 1})]
        missing = [n for n in names if f"{n}.w" not in inits or f"{n}.b" not in inits]
        if missing:
            sys.exit(f"{path}: not a learned detector written by roadtrack (no {missing[0]}.w/.b)")
        w = {n: (inits[f"{n}.w"], inits[f"{n}.b"]) for n in names}
        return shape_of(w), w
    with open(path) as f:
        j = json.load(f)
    shape = j["shape"]
    w = {}
    for (name, kind, cin, cout, k, _st), lw in zip(layer_specs(shape), j["layers"]):
        dims = (cout, cin, k, k) if kind == "conv" else (cin, cout, k, k)
        w[name] = (np.asarray(lw["weight"], np.float32).reshape(dims), np.asarray(lw["bias"], np.float32))
    return shape, w


def parse_record(f):
    """One dump_samples record, or None at the end of the stream."""
    h = f.read(HDR.size)
    if len(h) < HDR.size:
        return None
    magic, s, p, r, npos = HDR.unpack(h)
    if magic != b"RTS1":
        raise ValueError(f"bad sample record (magic {magic!r})")
    g = s // STRIDE
    n_in, n_neg = 3 * s * s, 4 * CLASSES * g * g
    body = f.read(n_in + n_neg + 4 * p + REG.itemsize * r)
    if len(body) < n_in + n_neg + 4 * p + REG.itemsize * r:
        return None
    inp = np.frombuffer(body, np.uint8, n_in, 0).reshape(3, s, s)
    neg = np.frombuffer(body, "<f4", CLASSES * g * g, n_in).reshape(CLASSES, g, g)
    pidx = np.frombuffer(body, "<u4", p, n_in + n_neg)
    regs = np.frombuffer(body, REG, r, n_in + n_neg + 4 * p)
    pos = np.zeros(CLASSES * g * g, np.uint8)
    pos[pidx] = 1
    reg = np.zeros((4, g * g), np.float32)
    reg[:, regs["c"]] = regs["v"].T
    mask = np.zeros(g * g, np.uint8)
    mask[regs["c"]] = 1
    return inp, neg.astype(np.float16), pos.reshape(CLASSES, g, g), reg.reshape(4, g, g), mask.reshape(1, g, g), npos


def stack(items):
    return tuple(np.stack([it[k] for it in items]) for k in range(5)) + (
        np.asarray([it[5] for it in items], np.int32),
    )


def reader(proc, q, chunk, stop):
    items = []
    while not stop.is_set():
        rec = parse_record(proc.stdout)
        if rec is None:
            break
        items.append(rec)
        if len(items) == chunk:
            q.put(stack(items))
            items = []
    if items:
        q.put(stack(items))


def spawn(dumper, first, step, seed, per_episode, episodes=None, log=None, mix=None):
    """A dump_samples worker; `mix`: {"MOTORCYCLE_SHARE": s, "HEAVY_SHARE": s} for its
    simulated vehicles (unset: the trainer's default mix)."""
    cmd = [dumper, str(first), str(step), str(seed), str(per_episode)]
    if episodes is not None:
        cmd.append(str(episodes))
    env = dict(os.environ)
    for k in ("MOTORCYCLE_SHARE", "HEAVY_SHARE"):
        env.pop(k, None)
    env.update({k: str(v) for k, v in (mix or {}).items() if v is not None})
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=log or subprocess.DEVNULL,
                            bufsize=1 << 20, env=env)


def losses(model, batch):
    """Sums of the focal and box losses over the batch and its object count (train.rs)."""
    x, neg, pos, reg, mask, npos = batch
    z, boxes = model(x)
    p = torch.sigmoid(z)
    pos_l = pos * (1 - p) ** 2 * F.logsigmoid(z)
    neg_l = neg * p**2 * F.logsigmoid(-z)
    heat = -(pos_l + neg_l).sum()
    box = ((boxes - reg).abs() * mask).sum()
    return heat, box, npos.sum()


def to_batch(parts):
    inp, neg, pos, reg, mask, npos = parts
    x = (inp.float() * (1.0 / 255.0) - 0.45) / 0.25
    return x, neg.float(), pos.float(), reg, mask.float(), npos


def check_loss(a):
    """The torch losses of --model's weights on a dump, to compare with burn's."""
    _name, init, _lr = a.model[0].split(":")
    shape, w = read_weights(init)
    m = CenterNet(shape)
    m.load(w)
    m.eval()
    items = []
    with open(a.check_loss, "rb") as f:
        while (rec := parse_record(f)) is not None:
            items.append(rec)
    h = b = n = 0.0
    with torch.no_grad():
        for i in range(0, len(items), 64):
            parts = [torch.from_numpy(v) for v in stack(items[i:i + 64])]
            hh, bb, nn_ = losses(m, to_batch(parts))
            h, b, n = h + hh.item(), b + bb.item(), n + nn_.item()
    print(f"torch losses per object centre: heat {h / n:.6f} box {b / n:.6f} ({len(items)} samples)")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dumper", required=True, help="the dump_samples example binary")
    ap.add_argument("--model", action="append", required=True,
                    help="NAME:INIT:LR, INIT a .onnx/.json to start from or widths c1,c2,c3,c4,head")
    ap.add_argument("--seconds", type=float, default=420.0,
                    help="training time; the schedule is by time unless --steps is given")
    ap.add_argument("--steps", type=int, default=0,
                    help="optimiser steps: the schedule is by step count (--seconds still limits)")
    ap.add_argument("--batch", type=int, default=128)
    ap.add_argument("--workers", type=int, default=max(1, (os.cpu_count() or 2) - 2))
    ap.add_argument("--per-episode", type=int, default=64, help="crops per rendered episode")
    ap.add_argument("--sim-seed-base", type=int, default=20000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--motorcycle-share", type=float, default=None,
                    help="share of motorcycles among the training workers' simulated vehicles "
                         "(as `roadtrack train --detector --motorcycle-share`); the held-out set "
                         "keeps the default mix")
    ap.add_argument("--heavy-share", type=float, default=None,
                    help="the same for lorries and buses (`--heavy-share`)")
    ap.add_argument("--ring", type=int, default=65536, help="samples kept for drawing batches")
    ap.add_argument("--max-reuse", type=float, default=8.0, help="samples drawn per sample rendered, at most")
    ap.add_argument("--val-seed-base", type=int, default=100000)
    ap.add_argument("--val-episodes", type=int, default=32)
    ap.add_argument("--val-workers", type=int, default=2)
    ap.add_argument("--checkpoint-every", type=float, default=60.0, help="seconds")
    ap.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    ap.add_argument("--out", help="folder for the weights (NAME.json), history.json and the log")
    ap.add_argument("--check-loss", metavar="DUMP",
                    help="print the first --model's losses on the records of DUMP (written by "
                         "dump_samples with LOSS_OF=, which prints burn's) and exit")
    a = ap.parse_args()
    if a.check_loss:
        return check_loss(a)
    if not a.out:
        ap.error("--out is required")
    os.makedirs(a.out, exist_ok=True)
    dev = torch.device(a.device)
    torch.backends.cudnn.benchmark = True
    torch.backends.cuda.matmul.allow_tf32 = True
    torch.backends.cudnn.allow_tf32 = True
    gen = torch.Generator().manual_seed(a.seed)
    log_file = open(os.path.join(a.out, "train_gpu.log"), "w")

    def say(msg):
        line = f"[{time.time() - t0:7.1f}s] {msg}"
        print(line, flush=True)
        log_file.write(line + "\n")
        log_file.flush()

    t0 = time.time()
    models = []
    for spec in a.model:
        name, init, lr = spec.split(":")
        if init.endswith((".onnx", ".json")):
            shape, w = read_weights(init)
            m = CenterNet(shape)
            m.load(w)
        else:
            c = [int(v) for v in init.split(",")]
            m = CenterNet(dict(zip(["c1", "c2", "c3", "c4", "head"], c)))
            m.init_like_roadtrack(gen)
        m = m.to(dev)
        opt = torch.optim.Adam(m.parameters(), lr=float(lr), foreach=True)
        n_w = sum(p.numel() for p in m.parameters())
        models.append({"name": name, "net": m, "opt": opt, "lr": float(lr), "run": [0.0, 0.0, 0.0]})
        say(f"model {name}: shape {m.shape}, {n_w} weights, from {init}, peak lr {lr}")

    mix = {"MOTORCYCLE_SHARE": a.motorcycle_share, "HEAVY_SHARE": a.heavy_share}
    # The dumper checks the mix as the trainer does: ask it once (no episode) before
    # starting workers that would otherwise die one by one behind the queue.
    check = spawn(a.dumper, 0, 1, 0, 1, 0, subprocess.PIPE, mix)
    _, why = check.communicate()
    if check.returncode != 0:
        sys.exit(why.decode(errors="replace").strip() or f"{a.dumper} failed")
    stop = threading.Event()
    q = queue.Queue(maxsize=256)
    vq = queue.Queue()
    err = open(os.path.join(a.out, "dump_samples.err"), "w")
    procs, threads = [], []
    for k in range(a.val_workers):
        p = spawn(a.dumper, a.val_seed_base + k, a.val_workers, a.seed + 7, a.per_episode,
                  a.val_episodes // a.val_workers, err)
        procs.append(p)
        threads.append(threading.Thread(target=reader, args=(p, vq, 64, stop), daemon=True))
    for k in range(a.workers):
        # Choice: only the training workers get the mix; the held-out set keeps the default
        # one, so networks trained on different mixes are scored on the same samples.
        p = spawn(a.dumper, a.sim_seed_base + k, a.workers, a.seed, a.per_episode, None, err,
                  mix)
        procs.append(p)
        threads.append(threading.Thread(target=reader, args=(p, q, 32, stop), daemon=True))
    for t in threads:
        t.start()

    # Validation set: every sample of the validation workers.
    for t in threads[: a.val_workers]:
        t.join()
    vparts = []
    while not vq.empty():
        vparts.append(vq.get())
    val = [np.concatenate([vp[k] for vp in vparts]) for k in range(6)]
    val_n = len(val[0])
    val_dev = [torch.from_numpy(v).to(dev) for v in val]
    say(f"validation set: {val_n} samples, {int(val[5].sum())} object centres")

    def validate():
        res = {}
        for mdl in models:
            m = mdl["net"]
            m.eval()
            h = b = n = 0.0
            with torch.no_grad():
                for i in range(0, val_n, 256):
                    part = to_batch([v[i:i + 256] for v in val_dev])
                    hh, bb, nn_ = losses(m, part)
                    h, b, n = h + hh.item(), b + bb.item(), n + nn_.item()
            m.train()
            res[mdl["name"]] = {"heat": h / n, "box": b / n, "total": (h + b) / n}
        return res

    history = [{"t": 0.0, "steps": 0, "val": validate()}]
    say("validation before training: " + json.dumps(history[0]["val"]))

    # The ring of samples on the device.
    R = a.ring - a.ring % 32
    ring = None
    filled = head = inserted = drawn = steps = 0
    t_start = time.time()
    last_log = last_ckpt = t_start

    def write_json(name, value):
        """OUT/name, written whole (temporary file, then rename)."""
        path = os.path.join(a.out, name)
        with open(path + ".tmp", "w") as f:
            json.dump(value, f)
        os.replace(path + ".tmp", path)

    def checkpoint(tag):
        for mdl in models:
            write_json(f"{mdl['name']}.json", mdl["net"].to_json())
        write_json("history.json", history)
        say(f"checkpoint {tag}")

    while True:
        el = time.time() - t_start
        if el >= a.seconds or (a.steps and steps >= a.steps):
            break
        # Take what the workers sent.
        got = 0
        while got < 64:
            try:
                parts = q.get_nowait() if filled >= a.batch else q.get(timeout=1.0)
            except queue.Empty:
                break
            n = len(parts[0])
            if ring is None:
                ring = [torch.empty((R,) + p.shape[1:], dtype=torch.from_numpy(p[:1]).dtype, device=dev)
                        for p in parts]
            end = head + n
            if end > R:  # chunks are 32 except a worker's last; keep the ring simple
                head, end = 0, n
            for r_, p in zip(ring, parts):
                r_[head:end].copy_(torch.from_numpy(p), non_blocking=True)
            head = end % R
            filled = max(filled, end)
            inserted += n
            got += 1
        if filled < max(a.batch, 1024) or drawn > a.max_reuse * inserted:
            if got == 0:
                time.sleep(0.01)
            continue
        # The schedule: a 2 % warm-up, then a cosine decay to a tenth (train.rs).
        frac = steps / a.steps if a.steps else el / a.seconds
        warm = 0.02
        scale = (frac / warm) if frac < warm else 0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * (frac - warm) / (1 - warm)))
        idx = torch.randint(0, filled, (a.batch,), device=dev)
        batch = to_batch([r_[idx] for r_ in ring])
        for mdl in models:
            for g_ in mdl["opt"].param_groups:
                g_["lr"] = mdl["lr"] * scale
            h, b, n = losses(mdl["net"], batch)
            n = n.clamp(min=1).float()
            total = (h + b) / n
            mdl["opt"].zero_grad(set_to_none=True)
            total.backward()
            mdl["opt"].step()
            run = mdl["run"]
            run[0] += h.detach()
            run[1] += b.detach()
            run[2] += n
        drawn += a.batch
        steps += 1
        now = time.time()
        if now - last_log >= 15:
            parts = []
            for mdl in models:
                h, b, n = (float(v) for v in mdl["run"])
                parts.append(f"{mdl['name']} {h / max(n, 1):.3f}+{b / max(n, 1):.3f}")
                mdl["run"] = [0.0, 0.0, 0.0]
            say(f"step {steps} ({steps / (now - t_start):.1f}/s), rendered {inserted}, drawn/rendered "
                f"{drawn / max(inserted, 1):.2f}, ring {filled}; train loss " + ", ".join(parts))
            last_log = now
        if now - last_ckpt >= a.checkpoint_every:
            history.append({"t": now - t_start, "steps": steps, "val": validate()})
            say("validation: " + json.dumps(history[-1]["val"]))
            checkpoint(f"at step {steps}")
            last_ckpt = time.time()

    stop.set()
    for p in procs:
        p.kill()
    history.append({"t": time.time() - t_start, "steps": steps, "rendered": inserted, "val": validate()})
    say("validation after training: " + json.dumps(history[-1]["val"]))
    checkpoint(f"final, step {steps}")


if __name__ == "__main__":
    main()
