"""`make bench` figures of the augmented model (lib/tempcomp/augment.py): per-sample cost of the
base model and of each term the gap diagnosis can add, as executed instructions on the
MicroPython 1.27 firmware for a Cortex-M3 (qemu -icount: exact, whatever the host's load; the
VM's time ratios to the unpack floor when the firmware is not built), each beside its anchors
measured in the same script: the plain compensator's sample (Compensator.apply_be16) and a
careful float implementation of the same model; the native kernels against the pure-Python path;
bytes allocated under heap_lock() on the firmware; and the worst error against float64
(tools/simgap/devmodel.py) with every term on, in the VM."""

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
BATCH = 32


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

def run(a, n, mask):
    # mask 63: the temperature reading changes every sample; 0: it stays (read less often)
    i = 0
    t = 2500
    t0 = time.ticks_ms()
    while i < n:
        a.apply(t + (i & mask), raw, out, 1000, 3300, acc)
        i += 1
    return time.ticks_diff(time.ticks_ms(), t0)

augs = [(name, Augmented(m)) for name, m in MODELS]
best = {}
for rep in range(%(reps)d):
    v = floor(%(n)d * 20) / 20
    best['floor'] = min(best.get('floor', 1e9), v)
    for name, a in augs:
        for mask, tag in ((0, ''), (63, '+t')):
            v = run(a, %(n)d, mask)
            best[name + tag] = min(best.get(name + tag, 1e9), v)
for k in best:
    print('TIME', best[k], k)
"""


# The float anchor: the same model in floats as careful code would run it on the board (the
# temperature polynomials, the cross matrix and the filters' steps only when their input changes),
# per sample the features, the terms and two steps of the cross-axis solve; floats allocate.
FLOAT_MODEL = r"""
import math
class FloatModel:
    def __init__(self, m):
        self.m = m
        tl = m['t_lsb']
        to = m.get('t_off', 0.0)
        self.tl = tl
        self.to = to
        self.t0a = round((m['t0'] - to) / tl) * tl + to
        self.rl = m.get('raw_lsb', 1.0)
        self.os = m['out_scale']
        self.kinds = [f['kind'] for f in m.get('features', [])]
        self.f = m.get('features', [])
        self.v = [0.0] * len(self.f)
        self.s = [0.0] * len(self.f)  # filter states
        self.al = [0.0] * len(self.f)
        self.up = 0.0
        self.dt = None
        self.t = None
        self.first = True
        self.s0 = [m['sensitivity'][i][0] for i in range(3)]
        self.ot = (m.get('offset_terms') or [[], [], []])
        self.gt = (m.get('gain_terms') or [[], [], []])
        self.cr = (m.get('cross') or [[], [], []])
        self.any_cross = any(self.cr)
        self.o = [0.0, 0.0, 0.0]
        self.g = [0.0, 0.0, 0.0]
        self.rho = [1.0, 1.0, 1.0]
        self.K = [[], [], []]
        self.y0 = [0.0, 0.0, 0.0]
        self.e = [1.0, 1.0, 1.0]
        self.y = [0.0, 0.0, 0.0]
    def update(self, t):
        # once per reading: the polynomials, the gain, rho and the cross matrix
        m = self.m
        T = t * self.tl + self.to
        d = T - m['t0']
        self.T = T
        self.dT = T - self.t0a
        for i in range(3):
            o = 0.0
            for c in reversed(m['offset'][i]):
                o = o * d + c
            s = 0.0
            for c in reversed(m['sensitivity'][i]):
                s = s * d + c
            self.o[i] = o + 0.5 * s / self.os  # round half up by truncation below
            self.g[i] = self.os / s
            self.rho[i] = self.s0[i] / s
            self.K[i] = [(int(k), self.rho[i] * (k0 + k1 * self.dT)) for k, k0, k1 in self.cr[i]]
        self.t = t
    def apply(self, t, raw, out, dt_ms, supply, acc):
        if t != self.t:
            self.update(t)
        T = self.T
        if self.kinds:
            m = self.m
            self.up += dt_ms * 0.001
            if dt_ms != self.dt:
                self.dt = dt_ms
                for j in range(len(self.f)):
                    if 'tau' in self.f[j]:
                        self.al[j] = 1.0 - math.exp(-dt_ms * 0.001 / self.f[j]['tau'])
            v = self.v
            for j in range(len(self.kinds)):
                k = self.kinds[j]
                f = self.f[j]
                if k == 'dT':
                    x = self.dT
                elif k == 'lag':
                    s = T if self.first else self.s[j] + self.al[j] * (T - self.s[j])
                    self.s[j] = s
                    x = T - s
                elif k == 'play':
                    h = f['width'] * 0.5
                    p = T if self.first else self.s[j]
                    if T - h > p:
                        p = T - h
                    elif T + h < p:
                        p = T + h
                    self.s[j] = p
                    x = p - T
                elif k == 'drift_exp':
                    s = 1.0 if self.first else self.s[j] - self.al[j] * self.s[j]
                    self.s[j] = s
                    x = s
                elif k == 'drift_hyp':
                    x = 1.0 / (1.0 + self.up / f['tau'])
                elif k == 'uptime':
                    x = self.up
                elif k == 'supply':
                    x = supply * m['supply_lsb'] - m['supply0']
                elif k == 'acc':
                    x = acc[f['axis']] * m['acc_lsb']
                else:
                    x = v[f['a']] * v[f['b']]
                v[j] = x
            self.first = False
            for i in range(3):
                d = 0.0
                for fi, c in self.ot[i]:
                    d += c * v[fi]
                e = 0.0
                for fi, c in self.gt[i]:
                    e += c * v[fi]
                self.y0[i] = (raw[i] * self.rl - self.o[i] - d) * self.g[i]
                self.e[i] = 1.0 + self.rho[i] * e
        else:
            for i in range(3):
                self.y0[i] = (raw[i] * self.rl - self.o[i]) * self.g[i]
                self.e[i] = 1.0
        y0 = self.y0
        e = self.e
        y = self.y
        y[0] = y0[0] / e[0]
        y[1] = y0[1] / e[1]
        y[2] = y0[2] / e[2]
        if self.any_cross:
            for _ in range(2):
                n0 = y0[0]
                for k, c in self.K[0]:
                    n0 -= c * y[k]
                n1 = y0[1]
                for k, c in self.K[1]:
                    n1 -= c * y[k]
                n2 = y0[2]
                for k, c in self.K[2]:
                    n2 -= c * y[k]
                y[0] = n0 / e[0]
                y[1] = n1 / e[1]
                y[2] = n2 / e[2]
        out[0] = int(y[0])
        out[1] = int(y[1])
        out[2] = int(y[2])
"""

FW_BENCH = r"""
import gc, time, micropython
from array import array
from tempcomp import augment
pad = bytearray(%(pad)d)  # moves the objects: the attribute caches then hit differently
M = %(model)s
NAME = %(name)r
N = %(n)d
B = %(batch)d
raw = array('i', [1200, -800, 300]); out = array('i', [0, 0, 0]); acc = array('i', [100, -300, 950])
outl = [0, 0, 0]
buf = bytearray(b"\x80\x00\x12\x34\x7f\xff")
bufn = bytearray(bytes(buf) * B)
outn = array('i', [0] * (3 * B))
%(float_model)s
def empty(n):
    i = 0
    t0 = time.ticks_us()
    while i < n:
        i += 1
    return time.ticks_diff(time.ticks_us(), t0)
def empty_t(n):
    i = 0
    t0 = time.ticks_us()
    while i < n:
        t = 2500 + (i & 63)
        i += 1
    return time.ticks_diff(time.ticks_us(), t0)
def run(a, n, raw=raw, out=out, acc=acc):
    # the documented call, everything a local: a direct method call passes the arguments
    # without copying them (a bound method made beforehand copies more than 4 through the heap)
    i = 0
    t0 = time.ticks_us()
    while i < n:
        a.apply(2500, raw, out, 1000, 3300, acc)
        i += 1
    return time.ticks_diff(time.ticks_us(), t0)
def run_t(a, n, raw=raw, out=out, acc=acc):
    i = 0
    t0 = time.ticks_us()
    while i < n:
        a.apply(2500 + (i & 63), raw, out, 1000, 3300, acc)
        i += 1
    return time.ticks_diff(time.ticks_us(), t0)
def run_b(a, n, buf=bufn, out=outn, acc=acc):
    i = 0
    t0 = time.ticks_us()
    while i < n:
        a.apply_be16_n(2500, buf, out, B, 1000, 3300, acc)
        i += 1
    return time.ticks_diff(time.ticks_us(), t0)
def run_c(ap, n, buf=buf, out=outl):
    i = 0
    t0 = time.ticks_us()
    while i < n:
        ap(buf, out)
        i += 1
    return time.ticks_diff(time.ticks_us(), t0)
def run_cn(ap, n, buf=bufn, out=outn):
    i = 0
    t0 = time.ticks_us()
    while i < n:
        ap(buf, out, B)
        i += 1
    return time.ticks_diff(time.ticks_us(), t0)
def locked(a):
    # zero allocation: a sample and a burst under heap_lock()
    micropython.heap_lock()
    try:
        run(a, 3)
        run_t(a, 3)
        run_b(a, 2)
        ok = 'ok'
    except MemoryError:
        ok = 'FAIL'
    micropython.heap_unlock()
    return ok
res = {}
def put(k, d, n, e):
    res[k] = (d - e) * 1000 // n
gc.collect(); e = empty(N)
gc.collect(); et = empty_t(N)
for mode in %(modes)r:
    augment.use_native(mode)
    a = augment.Augmented(M)
    tag = '' if mode is None else '_pure'
    n = N if mode is None else max(4, N // 20)
    run_t(a, 2)
    run_b(a, 1)
    a.apply(2500, raw, out, 1000, 3300, acc)
    gc.collect(); put('c' + tag, run(a, n), n, e * n // N)
    gc.collect(); put('t' + tag, run_t(a, n), n, et * n // N)
    if mode is None:
        nb = max(2, N // B)
        gc.collect(); put('b', run_b(a, nb), nb * B, e * nb // N)
        res['lock'] = locked(a)
    if NAME == 'base' and mode is None:
        ap = a.comp.apply_be16
        gc.collect(); put('plain', run_c(ap, N), N, e)
        gc.collect(); put('plain_arr', run_c(ap, N, buf, out), N, e)
        apn = a.comp.apply_be16_n
        nb = max(2, N // B)
        gc.collect(); put('plain_b', run_cn(apn, nb), nb * B, e * nb // N)
    a = None
augment.use_native(None)
if %(anchor)d:
    f = FloatModel(M)
    f.apply(2500, raw, out, 1000, 3300, acc)
    n = max(4, N // 10)
    gc.collect(); put('float', run(f, n), n, e * n // N)
    gc.collect(); put('float_t', run_t(f, n), n, et * n // N)
print('INSN', json.dumps(res))
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
    """{name: {key: instructions per sample}} on the Cortex-M3 firmware, each loop after
    gc.collect() and net of an empty loop, the least over PADS heap layouts (MicroPython's
    attribute-lookup caches make one layout's count differ from another's, and the UART
    interrupts of the host mount only ever add): c / t the model with the reading unchanged /
    changing every sample, b per sample of a burst of BATCH, *_pure the same forced to pure
    Python, float / float_t the float anchor, plain / plain_arr / plain_b the plain compensator's
    apply_be16 into a list / an array and its burst; lock 'ok' when a sample and a burst ran
    under heap_lock(). Plus {name: (lo, hi)} of the constant-reading count over the layouts;
    (None, None, reason) when the firmware is not built."""
    why = interp.missing("an385")
    if why:
        return None, None, why
    res, spread = {}, {}
    with interp.open_interp("an385") as it:
        out = it.run(FW_RAM % (json.dumps(dict(models)["base"]), json.dumps(dict(models)["every term"])))
        res["ram"] = tuple(int(v) for v in [ln for ln in out.splitlines() if ln.startswith("RAM ")][0].split()[1:])
        for name, m in models:
            runs = []
            anchor = name in ("base", "every term")
            modes = [None, False] if anchor else [None]
            for pad in PADS:
                out = it.run("import json\n" + FW_BENCH % {
                    "model": json.dumps(m), "name": name, "n": n, "pad": pad, "batch": BATCH, "modes": modes,
                    "anchor": int(anchor and pad == 0), "float_model": FLOAT_MODEL if anchor and pad == 0 else ""},
                    timeout=900)
                line = [ln for ln in out.splitlines() if ln.startswith("INSN ")][0]
                runs.append(json.loads(line[5:]))
            best = {}
            for r in runs:
                for k, v in r.items():
                    best[k] = v if k == "lock" and best.get(k, "ok") == "ok" else (min(best[k], v) if k in best else v)
            res[name] = best
            spread[name] = (min(r["c"] for r in runs), max(r["c"] for r in runs))
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
        b, ev = fw["base"], fw["every term"]
        pl = b["plain"]
        report("augment: plain Compensator.apply_be16 per 3-axis sample, into a list (Cortex-M3 firmware)", pl,
               "instructions", key="m3_plain")
        report("augment: same, into an array('i')", b["plain_arr"], "instructions", key="m3_plain_arr")
        report("augment: plain apply_be16_n, per sample of a burst of %d" % BATCH, b["plain_b"], "instructions",
               key="m3_plain_b")
        report("augment: base model through the augmented path, reading unchanged (target <= 1.5x the plain sample)",
               b["c"], "instructions (%.2fx the plain sample; %d..%d over %d heap layouts)"
               % (b["c"] / pl, spread["base"][0], spread["base"][1], len(PADS)), key="m3_base", ok=b["c"] <= 1.5 * pl)
        report("augment: same, reading changing every sample", b["t"], "instructions", key="m3_base_t")
        report("augment: same, per sample of a burst of %d" % BATCH, b["b"], "instructions", key="m3_base_b")
        report("augment: base model, float anchor (careful float code), reading unchanged", b["float"], "instructions",
               key="m3_base_float")
        report("augment: base model, float anchor, reading changing", b["float_t"], "instructions",
               key="m3_base_float_t")
        worst = 0
        for n in names[1:-1]:
            k = n.replace(" ", "_").replace("(", "").replace(")", "")
            x = fw[n]["c"] - b["c"]
            worst = max(worst, x)
            report("augment: + %s, extra per sample" % n, x, "instructions", key="m3_extra_" + k)
            report("augment: + %s, extra per sample, reading changing" % n, fw[n]["t"] - b["t"], "instructions",
                   key="m3_extra_%s_t" % k)
            report("augment: + %s, extra per sample of a burst" % n, fw[n]["b"] - b["b"], "instructions",
                   key="m3_extra_%s_b" % k)
        report("augment: largest single term's extra (target <= 1,500)", worst, "instructions", key="m3_extra_worst",
               ok=worst <= 1500)
        report("augment: every term, reading unchanged", ev["c"], "instructions", key="m3_every")
        report("augment: every term, reading changing every sample (target <= 8,000)", ev["t"], "instructions",
               key="m3_every_t", ok=ev["t"] <= 8000)
        report("augment: every term, per sample of a burst of %d (target <= 2,000)" % BATCH, ev["b"], "instructions",
               key="m3_every_b", ok=ev["b"] <= 2000)
        report("augment: every term, float anchor, reading unchanged", ev["float"], "instructions",
               key="m3_every_float")
        report("augment: every term, float anchor, reading changing", ev["float_t"], "instructions",
               key="m3_every_float_t")
        report("augment: pure-Python path forced (use_native(False)), base, reading unchanged", b["c_pure"],
               "instructions", key="m3_base_pure")
        report("augment: pure-Python path forced, every term, reading unchanged", ev["c_pure"], "instructions",
               key="m3_every_pure")
        report("augment: pure-Python path forced, base, reading changing", b["t_pure"], "instructions",
               key="m3_base_pure_t")
        report("augment: pure-Python path forced, every term, reading changing", ev["t_pure"], "instructions",
               key="m3_every_pure_t")
        locks = sorted({fw[n]["lock"] for n in names})
        report("augment: samples and bursts under heap_lock() on the Cortex-M3 firmware, every model",
               "ok" if locks == ["ok"] else "FAIL", "", key="m3_locked", ok=locks == ["ok"])
        ram = fw["ram"]
        report("augment: heap for fixedpoint (.mpy) on the Cortex-M3 firmware", ram[0], "B", key="ram_fixedpoint")
        report("augment: heap for the module (.mpy) on the Cortex-M3 firmware", ram[1], "B", key="ram_module")
        report("augment: heap of a first Augmented (base; with the native kernels' import)", ram[2], "B",
               key="ram_first")
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
