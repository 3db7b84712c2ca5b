"""Bench hook for ``make bench``: host fitting throughput and the on-device per-sample figures.

``bench(report)`` calls ``report(name, value, unit)`` for each figure:

* the six-position fit of 10,000 simulated units (3 temperatures x 6 orientations x 3 axes x
  200 samples: 108 million int16 values), timed on one core, data generation excluded;
* per sample in the real MicroPython VM: allocation (bytes) and VM time of the AN12760
  3-axis path, the analog gyro's rate() and the cross-axis correction (constant, and with its
  temperature law updated on every sample);
* worst fixed-point error against float64 (output LSB) over random inputs.

Run alone: ``.venv/bin/python -m tools.bench.fit``.
"""

import os
import time

import numpy as np

from tools import REPO

_VM = r"""
import time
from array import array
import allocprobe
from tempcomp.an12760 import AN12760
from tempcomp.adxrs import AnalogGyro
from tempcomp.crossaxis import CrossAxis
from tools.sim.analog_gyro_sim import AnalogGyroSim, ReplayADC

acc = AN12760([(35.0, (1.2, -0.004, 3e-5), 0.03, (-6e-4, 2e-6, -1e-8))] * 3, 4096, (-40, 105),
              t_scale=1 / 340, t_offset=36.53, out_per_g=10000)
codes = array("h", [acc.code_of(-40 + 0.7 * i) for i in range(200)])
raw = array("h", [1000, -2000, 4000])
out = array("i", [0, 0, 0])
st = array("i", [0])
def acc_step():
    i = st[0]
    i = i + 1 if i < 199 else 0
    st[0] = i
    acc.update(codes[i])
    acc.apply_all(raw, out)
def acc_same_t():
    acc.apply_all(raw, out)
sim = AnalogGyroSim(vref_mv=3300, divider=2.0)
tc = []
rc = []
for i in range(97):
    sim.temp_c = -40 + i * 1.3
    sim.rate_dps = -250 + 5 * i
    tc.append(sim.temp.read_u16())
    rc.append(sim.rate.read_u16())
g = AnalogGyro(ReplayADC(rc), ReplayADC(tc), 3300, divider=2.0)
g.set_three_point((1915.0, 2521.7, 6.75), (2500.0, 2500.0, 6.0), (3040.0, 2601.5, 6.22))
ca = CrossAxis([[0.001, -0.004, 0.002], [0.004, -0.002, 0.001], [-0.002, -0.001, 0.0005]])
def cross():
    ca.apply(out, out)
cl = CrossAxis([[0.001, -0.004, 0.002], [0.004, -0.002, 0.001], [-0.002, -0.001, 0.0005]],
               law=[[1e-4, -1e-4, 2e-5, 1e-4, 0.0, -3e-5, 1e-4, 1.5e-4, -1e-4],
                    [1e-6, -5e-7, 0.0, 2e-7, 8e-7, 0.0, -1e-6, 0.0, 3e-7]],
               t_span_c=(-40, 105), t_scale=1 / 340, t_offset=36.53)
def cross_law_new_t():
    i = st[0]
    i = i + 1 if i < 199 else 0
    st[0] = i
    cl.update(codes[i])
    cl.apply(out, out)
def timed(name, fn, n):
    fn()
    t0 = time.ticks_us()
    i = 0
    while i < n:
        fn()
        i += 1
    print("TIME %s %f" % (name, time.ticks_diff(time.ticks_us(), t0) / n))
for name, fn in (("an12760_3axis_new_t", acc_step), ("an12760_3axis_same_t", acc_same_t),
                 ("adxrs_rate", g.rate), ("crossaxis", cross), ("crossaxis_law_new_t", cross_law_new_t)):
    allocprobe.report(name, fn, (), 200)
    timed(name, fn, 2000)
"""


def _fit_bench(report, units=10000, chunk=1000):
    from tools.fit import simulate as S
    from tools.fit import sixpos as P

    rng = np.random.default_rng(0)
    temps = np.array([-40.0, 25.0, 85.0])
    fit_s = gen_s = 0.0
    worst_z = 0.0
    for start in range(0, units, chunk):
        n = min(chunk, units - start)
        t0 = time.perf_counter()
        tr = S.truth(n, rng)
        raw = S.chamber(tr, temps, S.SIX, 200, 16384.0, rng, noise_counts=8.0)
        t1 = time.perf_counter()
        mean, se = P.reduce_samples(raw)
        out, _ = P.fit_means(mean, temps, 16384.0, S.SIX, se, order=2)
        t2 = time.perf_counter()
        gen_s += t1 - t0
        fit_s += t2 - t1
        z = (out["law_offset_mg"][:, 0, :] - tr["off0"]) / out["se_law_offset_mg"][:, 0, :]
        worst_z = max(worst_z, float(np.abs(z).max()))
    report("fit_sixpos_%d_units" % units, fit_s, "s")
    report("fit_sixpos_per_unit", fit_s / units * 1e6, "us")
    report("fit_sixpos_datagen_%d_units" % units, gen_s, "s")
    report("fit_sixpos_offset_worst_z", worst_z, "sigma")


def _precision(report):
    from tempcomp.an12760 import AN12760
    from tempcomp.crossaxis import CrossAxis
    from tools.fit import an12760 as F

    rng = np.random.default_rng(1)
    ax = (35.0, (1.2, -0.004, 3e-5), 0.03, (-6e-4, 2e-6, -1e-8))
    dev = AN12760([ax], 4096, (-40, 105), t_scale=1 / 340, t_offset=36.53, out_per_g=10000)
    worst = 0.0
    lo, hi = dev.comp.t_cal
    for code in rng.integers(lo, hi + 1, 300):
        dev.update(int(code))
        raws = rng.integers(-32768, 32768, 50)
        ref = F.correct_mg(raws * 1000 / 4096, code / 340 + 36.53, *ax) * 10
        got = np.array([dev.apply(int(r)) for r in raws])
        worst = max(worst, float(np.abs(got - ref).max()))
    report("an12760_worst_error", worst, "LSB")
    worst = 0.0
    for _ in range(100):
        E = rng.uniform(-0.06, 0.06, (3, 3))
        ca = CrossAxis(E)
        for v in rng.integers(-(2**18) + 1, 2**18, (50, 3)):
            o = [0, 0, 0]
            ca.apply([int(x) for x in v], o)
            worst = max(worst, float(np.abs(np.array(o) - (v + E @ v)).max()))
    report("crossaxis_worst_error", worst, "LSB")
    # with a cubic temperature law, MPU-6500 codes across and beyond -40..85 degC (held at the edges)
    worst = 0.0
    for _ in range(60):
        laws = [rng.uniform(-0.04, 0.04, 9), rng.uniform(-1.5e-4, 1.5e-4, 9), rng.uniform(-1e-6, 1e-6, 9),
                rng.uniform(-5e-9, 5e-9, 9)]
        ca = CrossAxis(laws[0], law=laws[1:], t_span_c=(-40, 85), t_scale=1 / 333.87, t_offset=21.0)
        lo, hi = ca.code_of(-40.0), ca.code_of(85.0)
        for code in rng.integers(lo - 3000, hi + 3000, 40):
            ca.update(int(code))
            d = min(max(int(code) / 333.87 + 21.0, -40.0), 85.0) - 25.0
            E = sum(laws[k] * d**k for k in range(4)).reshape(3, 3)
            for v in rng.integers(-(2**18) + 1, 2**18, (25, 3)):
                o = [0, 0, 0]
                ca.apply([int(x) for x in v], o)
                worst = max(worst, float(np.abs(np.array(o) - (v + E @ v)).max()))
    report("crossaxis_law_worst_error", worst, "LSB")


def _vm(report):
    from tools.firmware import mpvm

    out = mpvm.run(_VM, mounts=(os.path.join(REPO, "tools") + ":/tools",), paths=("/",))
    for name, (b, ok) in mpvm.alloc_lines(out).items():
        # ok: the heap-locked run did not raise MemoryError
        report("vm_%s_alloc" % name, b, "bytes/sample", ok=bool(ok) and b == 0)
    for line in out.splitlines():
        if line.startswith("TIME "):
            _, name, us = line.split()
            report("vm_%s_time" % name, float(us), "us/sample (wasm VM)")


def bench(report):
    _fit_bench(report)
    _precision(report)
    _vm(report)


if __name__ == "__main__":
    bench(lambda name, value, unit, key=None, ok=None: print("%-40s %12s %s" % (name, value, unit)))
