"""`make bench` figures of the augmented model (lib/tempcomp/augment.py) in the real MicroPython
VM: time per 3-axis sample of the base model and of each term the gap diagnosis can add, as
ratios to the unpack floor measured in the same run; bytes allocated per sample with every term
on; the worst error against float64 (tools/simgap/devmodel.py) with every term on."""

import json
import time

import numpy as np

from tools.firmware import mpvm
from tools.simgap import devmodel, replay

BASE = {"t_lsb": 0.01, "t_off": 0.0, "raw_lsb": 1.0, "raw_range": [-32768, 32767], "out_scale": 100.0,
        "t0": 25.0, "t_cal": [-10.0, 60.0], "supply_lsb": 0.001, "supply0": 3.3, "acc_lsb": 0.001,
        "offset": [[50, 4, -0.02], [-30, 2, 0.01], [10, -3, 0.015]],
        "sensitivity": [[16.4, 0.002], [16.0, -0.003], [16.2, 0.001]]}

# each term as the export writes it for one axis (x), sized like the generated logs' effects
TERMS = {
    "temp_rate": ([{"kind": "lag", "tau": 150.0, "bound": 10.0}, {"kind": "lag", "tau": 450.0, "bound": 40.0},
                   {"kind": "dT"}, {"kind": "prod", "a": 0, "b": 2}, {"kind": "prod", "a": 1, "b": 2},
                   {"kind": "prod", "a": 0, "b": 0}],
                  [[0, 8.0], [1, -2.0], [3, 0.05], [4, -0.02], [5, 0.1]], [[0, 1e-4], [1, -5e-5]], []),
    "hysteresis": ([{"kind": "play", "width": 1.0}, {"kind": "play", "width": 2.0}, {"kind": "play", "width": 4.0}],
                   [[0, 5.0], [1, -3.0], [2, 6.0]], [], []),
    "drift (exp)": ([{"kind": "drift_exp", "tau": 400.0}], [[0, 80.0]], [], []),
    "drift (hyperbolic)": ([{"kind": "drift_hyp", "tau": 400.0}], [[0, 80.0]], [], []),
    "supply": ([{"kind": "supply", "bound": 0.5}, {"kind": "prod", "a": 0, "b": 0}],
               [[0, 120.0], [1, 10.0]], [[0, 0.01]], []),
    "g_sensitivity": ([{"kind": "acc", "axis": 0, "bound": 2.0}, {"kind": "acc", "axis": 1, "bound": 2.0},
                       {"kind": "acc", "axis": 2, "bound": 2.0}], [[0, 25.0], [1, -15.0], [2, 10.0]], [], []),
    "cross_axis": ([{"kind": "dT"}], [], [], [[1, 0.02, 1e-4], [2, -0.015, 0.0]]),
}


def model(names):
    m = dict(BASE, features=[], offset_terms=[[], [], []], gain_terms=[[], [], []], cross=[[], [], []])
    for name in names:
        feats, off, gain, cross = TERMS[name]
        k = len(m["features"])
        for f in feats:
            f = dict(f)
            if f["kind"] == "prod":
                f["a"] += k
                f["b"] += k
            m["features"].append(f)
        m["offset_terms"][0] += [[fi + k, c] for fi, c in off]
        m["gain_terms"][0] += [[fi + k, c] for fi, c in gain]
        m["cross"][0] += cross
    return m


VM_BENCH = r"""
import time, json
from array import array
from tempcomp.augment import Augmented
MODELS = json.loads(%(models)r)
raw = array('i', [1200, -800, 300])
out = array('i', [0, 0, 0])
acc = array('i', [100, -300, 950])

def unpack(buf, o):
    v = buf[0] << 8 | buf[1]
    if v & 0x8000:
        v -= 0x10000
    o[0] = v
    v = buf[2] << 8 | buf[3]
    if v & 0x8000:
        v -= 0x10000
    o[1] = v
    v = buf[4] << 8 | buf[5]
    if v & 0x8000:
        v -= 0x10000
    o[2] = v

buf = bytearray(b"\x80\x00\x12\x34\x7f\xff")

def floor(n):
    i = 0
    t0 = time.ticks_ms()
    while i < n:
        unpack(buf, out)
        i += 1
    return time.ticks_diff(time.ticks_ms(), t0)

def run(ap, n, mask):
    # mask 63: the temperature reading changes every sample; 0: it stays (read less often)
    i = 0
    t = 2500
    t0 = time.ticks_ms()
    while i < n:
        ap(t + (i & mask), raw, out, 1000, 3300, acc)
        i += 1
    return time.ticks_diff(time.ticks_ms(), t0)

augs = [(name, Augmented(m)) for name, m in MODELS]
best = {}
for rep in range(%(reps)d):
    v = floor(%(n)d * 20) / 20
    best['floor'] = min(best.get('floor', 1e9), v)
    for name, a in augs:
        ap = a.apply
        for mask, tag in ((0, ''), (63, '+t')):
            v = run(ap, %(n)d, mask)
            best[name + tag] = min(best.get(name + tag, 1e9), v)
for k in best:
    print('TIME', best[k], k)
"""


def bench(report):
    t0 = time.time()
    names = ["base"] + list(TERMS) + ["every term"]
    models = [("base", model([]))] + [(n, model([n])) for n in TERMS] + [("every term", model(list(TERMS)))]
    out = mpvm.run(VM_BENCH % dict(models=json.dumps(models), n=3000, reps=3), heap="4m", timeout=900)
    times = {}
    for line in out.splitlines():
        if line.startswith("TIME "):
            _, v, k = line.split(" ", 2)
            times[k] = float(v)
    fl = times["floor"]
    report("augment: base model per 3-axis sample / unpack floor (VM)", times["base"] / fl, "x")
    report("augment: same, temperature reading changing every sample", times["base+t"] / fl, "x")
    for n in names[1:]:
        report("augment: + %s, extra per sample / unpack floor" % n, (times[n] - times["base"]) / fl, "x")
    report("augment: every term, temperature changing every sample / unpack floor", times["every term+t"] / fl, "x")
    # every term on: zero allocation and precision against float64 over a generated run
    m = model(list(TERMS))
    rng = np.random.default_rng(5)
    n = 4000
    ts = np.arange(n)
    T = 25 + 25 * np.sin(ts / 500) + rng.normal(0, 0.05, n)
    inp = {"t": np.round(T / 0.01).astype(np.int64), "dt_ms": np.r_[0, 1000 + rng.integers(-5, 6, n - 1)],
           "supply": np.round((3.3 + 0.2 * np.sin(ts / 70)) / 0.001).astype(np.int64),
           "acc": np.round(rng.uniform(-1, 1, (n, 3)) / 0.001).astype(np.int64), "uptime0_ms": 0}
    ref = rng.uniform(-1800, 1800, (n, 3))
    F = devmodel.features(m, inp)
    inp["raw"] = np.clip(np.round(devmodel.predict(m, inp, ref, F)), -32768, 32767).astype(np.int64)
    y, info = replay.run_device(m, inp)
    err = np.abs(y - devmodel.compensate(m, inp, F) * m["out_scale"])
    report("augment: bytes allocated per sample, every term on (VM)", info["allocated_per_sample"], "B")
    report("augment: clamped feature values in that run (0: all inside their bounds)", info.get("clamped", 0), "")
    report("augment: heap-locked samples, every term on", "ok" if info["heap_locked"] else "FAIL", "")
    report("augment: worst error vs float64, every term, %d samples" % n, float(err.max()), "output LSB")
    report("augment: RMS error vs float64, every term", float(np.sqrt(np.mean(err ** 2))), "output LSB")
    report("augment: VM run wall time", time.time() - t0, "s")
