"""MLX90609 per-sample figures for `make bench` (the lead's tools/bench/__main__.py calls bench(report)).

Measured in the real MicroPython VM (32-bit, 1.27): bytes allocated per compensated sample
(driver read + compensate, against the simulated part behind buses.SimSPI), and the time of
unpack + compensate relative to the unpack floor (extracting the 11-bit code from the ADCR
answer bytes). On CPython: the worst error against AN2 equations 3-13 in float64.
"""

import os
import random

import numpy as np

from tempcomp.mlx90609 import compensator, decode_eeprom  # noqa: E402
from tools import REPO
from tools.firmware import mpvm
from tools.sim import mlx90609_sim as ms

_VM = r"""
import time
import allocprobe
import mlx90609_sim as ms
from tempcomp.mlx90609 import MLX90609

sim = ms.MLX90609Sim(version=2, full_scale_dps=150)
spi, cs = ms.on_simspi(sim)
g = MLX90609(spi, cs)
sim.schedule([(-140.0 + 7.7 * i, -60.0 + 4.6 * i) for i in range(37)])
allocprobe.report("rate", g.rate, (), 300)
comp = g._comp
ans = bytearray(3)
ans[1] = 0x2B
ans[2] = 0x45
N = 50000

def floor(n):
    b = ans
    i = 0
    s = 0
    while i < n:
        s += ((b[1] << 8 | b[2]) >> 1) & 0x7FF
        b[2] = (b[2] + 2) & 0xFF
        i += 1
    return s

def compensate(n):
    b = ans
    ap = comp.apply
    i = 0
    s = 0
    while i < n:
        s += ap(((b[1] << 8 | b[2]) >> 1) & 0x7FF)
        b[2] = (b[2] + 2) & 0xFF
        i += 1
    return s

def with_update(n):
    b = ans
    ap = comp.apply
    up = comp.update
    i = 0
    s = 0
    while i < n:
        up(1900 + (i & 1023))  # a new TEMPOUT (mV) every sample: the driver's temp_every = 1
        s += ap(((b[1] << 8 | b[2]) >> 1) & 0x7FF)
        b[2] = (b[2] + 2) & 0xFF
        i += 1
    return s

def driver(n):
    r = g.rate
    i = 0
    while i < n:
        r()
        i += 1

def best(fn, n):
    b = None
    for _ in range(5):
        t0 = time.ticks_us()
        fn(n)
        d = time.ticks_diff(time.ticks_us(), t0)
        if b is None or d < b:
            b = d
    return b

tf = best(floor, N)
tc = best(compensate, N)
tu = best(with_update, N // 10)
td = best(driver, N // 10)
print("TIME", tf, tc, tu * 10, td * 10, N)
"""


def _worst_error(out_scale=1000, tables=6, t_step=5):
    rnd = random.Random(609)
    worst = 0.0
    for k in range(tables):
        v = (1, 2, 3, 255)[k % 4]
        fs = (75, 150, 300)[k % 3]
        tc = (1850 + rnd.randint(-80, 80), 2500 + rnd.randint(-50, 50), 3100 + rnd.randint(-80, 80))
        img = ms.encode_eeprom(v, fs // 5, tc, [rnd.randint(0, 255) for _ in range(3)],
                               [rnd.randint(0, 255) for _ in range(3)])
        table = decode_eeprom(img)
        comp = compensator(table, "digital", out_scale)
        z = table.zro("digital")
        s = table.sf(table.s0("digital"))
        lo, hi = comp.t_in
        raws = np.arange(0, 2048)
        for t in range(lo, hi + 1, t_step):
            comp.update(t)
            got = np.array([comp.apply(int(r)) for r in raws], dtype=float)
            ref = out_scale * (raws - ms.an2_quadratic(table.tc, z, t)) / ms.an2_quadratic(table.tc, s, t)
            worst = max(worst, float(np.abs(got - ref).max()))
    return worst


def bench(report):
    out = mpvm.run(_VM, mounts=(os.path.join(REPO, "tools", "sim") + ":/simdir",), paths=("/simdir",))
    alloc = mpvm.alloc_lines(out)
    b, ok = alloc["rate"]
    report("mlx90609 bytes per compensated sample (driver read + compensate, VM)", b, "bytes", key="alloc", ok=b == 0)
    report("mlx90609 heap-locked read + compensate", "ok" if ok else "FAIL", "", key="locked", ok=bool(ok))
    line = [ln for ln in out.splitlines() if ln.startswith("TIME ")][0].split()
    tf, tc, tu, td, n = (int(x) for x in line[1:])
    report("mlx90609 unpack floor per sample (VM)", tf / n, "us")
    report("mlx90609 unpack + compensate per sample (VM)", tc / n, "us")
    report("mlx90609 compensate time ratio vs unpack floor", tc / tf, "x", key="ratio")
    report("mlx90609 same with a new TEMPOUT every sample (update + compensate)", tu / tf, "x", key="update_ratio")
    report("mlx90609 driver rate() incl. simulated SPI, 2 conversions (VM)", td / n, "us")
    w = _worst_error()
    report("mlx90609 worst error vs AN2 eq. 3-13 (output LSB = 1 milli-deg/s)", w, "LSB", key="worst")


if __name__ == "__main__":
    bench(lambda name, value, unit, key=None, ok=None: print("%-75s %10s %s" % (name, value, unit)))
