"""`make bench` figures of the augmented model (lib/tempcomp/augment.py): per-sample cost of the
base model and of each term the gap diagnosis can add, as executed instructions on the
MicroPython 1.27 firmware for a Cortex-M3 (qemu -icount: exact, whatever the host's load; the
VM's time ratios to the unpack floor when the firmware is not built); bytes allocated per sample
and the worst error against float64 (tools/simgap/devmodel.py) with every term on, in the VM."""

import json
import os
import sys
import time

import numpy as np

from tools import REPO
from tools.bench.core import UNPACK_FLOOR
from tools.firmware import interp, mpvm
from tools.simgap import devmodel, export, replay
from tools.simgap.diagnose import diagnose

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

%(unpack)s
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


FW_BENCH = r"""
import gc, time
from array import array
from tempcomp.augment import Augmented
pad = bytearray(%(pad)d)  # moves the objects: the attribute caches then hit differently
a = Augmented(%(model)s)
raw = array('i', [1200, -800, 300]); out = array('i', [0, 0, 0]); acc = array('i', [100, -300, 950])
ap = a.apply
buf = bytearray(b"\x80\x00\x12\x34\x7f\xff")

%(unpack)s
def run(n, mask):
    i = 0
    t0 = time.ticks_us()
    while i < n:
        ap(2500 + (i & mask), raw, out, 1000, 3300, acc)
        i += 1
    return time.ticks_diff(time.ticks_us(), t0)

def floor(n):
    i = 0
    t0 = time.ticks_us()
    while i < n:
        unpack(buf, out)
        i += 1
    return time.ticks_diff(time.ticks_us(), t0)

def empty(n):
    i = 0
    t0 = time.ticks_us()
    while i < n:
        i += 1
    return time.ticks_diff(time.ticks_us(), t0)

N = %(n)d
run(4, 63)
# each loop after a collection, as tools/bench/instructions.py measures: a call whose frame passes
# 11 words (apply, update) takes it from the heap and frees it on return, and that search costs
# more the fuller the heap is (here the set-up's garbage: 18,000 against 2,600 instructions for
# an update() that returns at once), which is the heap's state, not the model's cost
gc.collect(); e = empty(N)
gc.collect(); fl = floor(N)
gc.collect(); r0 = run(N, 0)
gc.collect(); r1 = run(N, 63)
print('INSN', (fl - e) * 1000 // N, (r0 - e) * 1000 // N, (r1 - e) * 1000 // N)
"""


PADS = (0, 700, 2100, 4900, 9100)

FW_RAM = """
import gc
gc.collect(); f0 = gc.mem_free()
import tempcomp.fixedpoint
gc.collect(); f1 = gc.mem_free()
from tempcomp.augment import Augmented
gc.collect(); f2 = gc.mem_free()
a = Augmented(%s)
gc.collect(); f3 = gc.mem_free()
b = Augmented(%s)
gc.collect(); f4 = gc.mem_free()
print('RAM', f0 - f1, f1 - f2, f2 - f3, f3 - f4)
"""


def firmware_costs(models, n=200):
    """{name: (floor, constant reading, changing reading)} instructions per sample on the
    Cortex-M3 firmware, each loop after gc.collect() and each the least over PADS heap layouts
    (MicroPython's attribute-lookup caches and its heap-allocated call frames make one layout's
    count differ from another's, and the UART interrupts of the host mount add counts that
    depend on the host's timing), and
    {name: (lo, hi)} of the constant-reading count; (None, reason) when it is not built."""
    why = interp.missing("an385")
    if why:
        return None, None, why
    res, spread = {}, {}
    with interp.open_interp("an385") as it:
        out = it.run(FW_RAM % (json.dumps(dict(models)["base"]), json.dumps(dict(models)["every term"])))
        res["ram"] = tuple(int(v) for v in [ln for ln in out.splitlines() if ln.startswith("RAM ")][0].split()[1:])
        for name, m in models:
            runs = []
            for pad in PADS:
                out = it.run(FW_BENCH % {"model": json.dumps(m), "n": n, "pad": pad, "unpack": UNPACK_FLOOR}, timeout=600)
                line = [ln for ln in out.splitlines() if ln.startswith("INSN ")][0]
                runs.append(tuple(int(v) for v in line.split()[1:]))
            # the least of the layouts: the UART's interrupts (the host mount) only ever add
            res[name] = tuple(min(r[k] for r in runs) for k in range(3))
            spread[name] = (min(r[1] for r in runs), max(r[1] for r in runs))
    return res, spread, None


def shrink(report):
    """README's before/after table: on logs with one effect each from the test suite's generator
    (host_tests/helpers/augsynth.py, written apart from the diagnosis), the board's withheld RMS of
    the sim alone and of the augmented model (the device code replayed in the VM), axis x, and the
    host's ratio (the diagnosis' own); host_tests/augment/test_export_replay.py recomputes them."""
    sys.path.insert(0, os.path.join(REPO, "host_tests", "helpers"))
    try:
        import augsynth
    finally:
        sys.path.remove(os.path.join(REPO, "host_tests", "helpers"))
    for effect in augsynth.EFFECTS:
        tr, wh = augsynth.make(effect), augsynth.make(effect, withheld=True)
        res, _ = diagnose(tr, wh)
        exp = export.build(res, tr)
        full, _ = replay.replay(exp, wh)
        base, _ = replay.replay(exp, wh, base_only=True)
        h = exp["host"]["rms"]
        report("augment: %s log, board RMS of the sim alone, axis x (withheld)" % effect, base["rms"]["x"], "dps",
               key="shrink_%s_base" % effect)
        report("augment: %s log, board RMS of the augmented model, axis x" % effect, full["rms"]["x"], "dps",
               key="shrink_%s_aug" % effect)
        report("augment: %s log, board ratio augmented / sim alone, axis x" % effect,
               full["rms"]["x"] / base["rms"]["x"], "", key="shrink_%s_ratio" % effect)
        report("augment: %s log, the host's ratio (the diagnosis' withheld RMS), axis x" % effect,
               h["augmented"]["x"] / h["base_only"]["x"], "", key="shrink_%s_host" % effect)


def bench(report):
    shrink(report)
    t0 = time.time()
    names = ["base"] + list(TERMS) + ["every term"]
    models = [("base", model([]))] + [(n, model([n])) for n in TERMS] + [("every term", model(list(TERMS)))]
    fw, spread, why = firmware_costs(models)
    if fw is not None:
        fl = fw["base"][0]
        report("augment: the 6-byte unpack floor (Cortex-M3 firmware)", fl, "instructions", key="m3_floor")
        report("augment: base model per 3-axis sample (Cortex-M3 firmware, reading unchanged)", fw["base"][1],
               "instructions (%.1fx the unpack floor; %d..%d over %d heap layouts)"
               % (fw["base"][1] / fl, spread["base"][0], spread["base"][1], len(PADS)), key="m3_base")
        report("augment: same, temperature reading changing every sample", fw["base"][2],
               "instructions (%.1fx)" % (fw["base"][2] / fl), key="m3_base_t")
        for n in names[1:]:
            report("augment: + %s, extra per sample" % n, fw[n][1] - fw["base"][1],
                   "instructions (%.1fx the floor; total %d..%d)" % ((fw[n][1] - fw["base"][1]) / fl,
                                                                     spread[n][0], spread[n][1]),
                   key="m3_extra_" + n.replace(" ", "_").replace("(", "").replace(")", ""))
        report("augment: every term, reading changing every sample", fw["every term"][2],
               "instructions (%.1fx)" % (fw["every term"][2] / fl), key="m3_every_term_t")
        ram = fw["ram"]
        report("augment: heap for fixedpoint (.mpy) on the Cortex-M3 firmware", ram[0], "B", key="ram_fixedpoint")
        report("augment: heap for the module (.mpy) on the Cortex-M3 firmware", ram[1], "B", key="ram_module")
        report("augment: heap of a first Augmented (base; with first-use interning)", ram[2], "B", key="ram_first")
        report("augment: heap of a second Augmented (every term)", ram[3], "B", key="ram_second")
        report("augment: Cortex-M3 firmware run wall time", time.time() - t0, "s", key="m3_wall")
        _vm_precision(report, time.time())
        return
    report("augment: Cortex-M3 firmware not available (%s); VM time ratios instead" % why, "", "")
    out = mpvm.run(VM_BENCH % dict(unpack=UNPACK_FLOOR, models=json.dumps(models), n=3000, reps=3), heap="4m", timeout=900)
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
    _vm_precision(report, t0)


def _vm_precision(report, t0):
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
    report("augment: bytes allocated per sample, every term on (VM)", info["allocated_per_sample"], "B", key="alloc",
           ok=info["allocated_per_sample"] == 0)
    report("augment: clamped feature values in that run (0: all inside their bounds)", info.get("clamped", 0), "",
           key="clamped")
    report("augment: heap-locked samples, every term on", "ok" if info["heap_locked"] else "FAIL", "", key="locked",
           ok=bool(info["heap_locked"]))
    report("augment: worst error vs float64, every term, %d samples" % n, float(err.max()), "output LSB", key="worst")
    report("augment: RMS error vs float64, every term", float(np.sqrt(np.mean(err ** 2))), "output LSB", key="rms")
    report("augment: VM run wall time", time.time() - t0, "s", key="vm_wall")
