"""One step of `make demo`: fixed-point compensation of a simulated gyro through a temperature sweep.

A simulated MPU-6500-style gyro axis (131 LSB/dps at +-250 dps, temperature register
333.87 LSB/degC + 21 degC) has a zero-rate offset that is quadratic in temperature and a
sensitivity that is linear in it (the application notes' model). It is "calibrated" at three
temperatures, the three-point quadratics are set up with tempcomp.fixedpoint, and the sweep is
compensated inside the real MicroPython VM (32-bit small ints, the code that runs on a board).
The table shows raw vs compensated output against the true rate and against the float64
evaluation of the same calibration.
"""

import argparse
import os
import sys

import numpy as np

from tools import REPO

sys.path.insert(0, os.path.join(REPO, "lib"))

from tempcomp.fixedpoint import quadratic_through  # noqa: E402
from tools.firmware import mpvm  # noqa: E402

TEMP_LSB_PER_C = 333.87
TEMP_OFFSET_C = 21.0
RATE_DPS = 100.0
# the checks this step makes (exit status 1 when one fails): the core's bound against float64
# (README, "The fixed-point core": |error| <= 0.7 + |y| * 2**-24 output LSB on any set the set-up accepts)
# and compensation beating the raw output by 20x on this drift
BOUND_LSB = 0.7
GAIN = 20.0


def offset_lsb(temp_c):
    return -40.0 + 1.1 * (temp_c - 25.0) + 0.012 * (temp_c - 25.0) ** 2


def sens_lsb_per_dps(temp_c):
    return 131.0 * (1.0 + 0.0004 * (temp_c - 25.0))


def temp_code(temp_c):
    return int(round((temp_c - TEMP_OFFSET_C) * TEMP_LSB_PER_C))


def raw_output(temp_c, rate, rng):
    v = offset_lsb(temp_c) + sens_lsb_per_dps(temp_c) * rate + rng.normal(0, 1.5)
    return int(np.clip(np.round(v), -32768, 32767))


VM_CODE = r"""
from tempcomp.fixedpoint import Compensator
comp = Compensator([%(off)r], [%(sc)r], %(t_cal)r, t_ref=%(t_ref)d, out_scale=1000.0)
for t, raw in %(rows)r:
    comp.update(t)
    print("ROW %%d %%d %%d" %% (t, raw, comp.apply(raw)))
"""


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bound", type=float, default=BOUND_LSB,
                    help="worst fixed-point error vs float64 allowed, output LSB, plus |y| * 2**-24 "
                         "(default %(default)s)")
    ap.add_argument("--gain", type=float, default=GAIN,
                    help="how many times smaller the compensated error must be than the raw one (default %(default)s)")
    a = ap.parse_args(argv)
    rng = np.random.default_rng(2)
    cal_temps = (-10.0, 25.0, 70.0)
    # calibration: offset from a capture at rest, sensitivity from a known rate, at each temperature
    offs, scs = [], []
    for tc in cal_temps:
        at_rest = np.mean([raw_output(tc, 0.0, rng) for _ in range(400)])
        spun = np.mean([raw_output(tc, RATE_DPS, rng) for _ in range(400)])
        offs.append((temp_code(tc), float(at_rest)))
        scs.append((temp_code(tc), float(spun - at_rest) / RATE_DPS))
    t_ref = temp_code(25.0)
    off = quadratic_through(*offs, t_ref=t_ref)
    sc = quadratic_through(*scs, t_ref=t_ref)
    t_cal = (temp_code(cal_temps[0]), temp_code(cal_temps[-1]))

    sweep = np.arange(-10.0, 71.0, 10.0)
    rows = [(temp_code(tc), raw_output(tc, RATE_DPS, rng)) for tc in sweep]
    out = mpvm.run(VM_CODE % dict(off=list(off), sc=list(sc), t_cal=t_cal, t_ref=t_ref, rows=rows))
    comp = {}
    for line in out.splitlines():
        if line.startswith("ROW "):
            _, t, raw, y = line.split()
            comp[(int(t), int(raw))] = int(y)

    print("Simulated gyro axis, true rate %.1f dps; calibrated at %s degC; compensated in the"
          " MicroPython VM (milli-dps)." % (RATE_DPS, ", ".join("%g" % t for t in cal_temps)))
    print()
    hdr = ("temp degC", "t code", "raw LSB", "uncomp mdps", "err mdps", "comp mdps", "err mdps", "float64 ref", "vs ref LSB")
    print("%9s %7s %8s %12s %9s %10s %9s %12s %10s" % hdr)
    worst_raw = worst_comp = worst_ref = over = 0.0
    for tc, (t, raw) in zip(sweep, rows):
        u = 1000.0 * raw / 131.0  # what a driver without compensation reports
        y = comp[(t, raw)]
        u_ = float(t - t_ref)
        ref = 1000.0 * (raw - sum(c * u_**i for i, c in enumerate(off))) / sum(c * u_**i for i, c in enumerate(sc))
        truth = 1000.0 * RATE_DPS
        worst_raw = max(worst_raw, abs(u - truth))
        worst_comp = max(worst_comp, abs(y - truth))
        worst_ref = max(worst_ref, abs(y - ref))
        over = max(over, abs(y - ref) - abs(ref) * 2.0**-24)
        print("%9.1f %7d %8d %12.0f %+9.0f %10d %+9.0f %12.2f %+10.2f" % (tc, t, raw, u, u - truth, y, y - truth, ref, y - ref))
    print()
    print("worst error vs true rate: uncompensated %.0f mdps, compensated %.0f mdps (sensor noise"
          " 1.5 LSB = 11 mdps included)" % (worst_raw, worst_comp))
    print("worst fixed-point error vs the float64 evaluation of the same calibration: %.3f output LSB" % worst_ref)
    failed = []
    if not over <= a.bound:
        failed.append("fixed point vs float64 %.3f output LSB, more than %g + |y| * 2**-24" % (worst_ref, a.bound))
    if not worst_comp * a.gain < worst_raw:
        failed.append("compensated error %.0f mdps is not %gx below the raw %.0f mdps" % (worst_comp, a.gain, worst_raw))
    for f in failed:
        print("CHECK FAILED: " + f)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
