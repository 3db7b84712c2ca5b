"""Executed instructions per call on real MicroPython firmware: Cortex-M3 (MPS2-AN385, soft float,
single-precision floats) and Cortex-M7 (MPS2-AN500, double-precision FPU) under qemu with
``-icount shift=0``, where the emulated clock advances 1 ns per executed instruction, so
``time.ticks_us()`` over n calls gives instructions per call exactly and repeatably.

Every figure is net of the empty loop measured in the same script (a ``while`` loop that only
counts); the empty loop and a call of an empty function are printed beside them, as are a naive
float implementation of the same 3-axis compensation (what peer drivers do: unpack with struct,
evaluate the temperature polynomials in float on every sample) and a careful float one
(polynomials evaluated once per temperature, per sample one subtract and one multiply per axis).
The library is measured as it chooses at import (native kernels where the firmware has the viper
emitter) and, where it offers ``fixedpoint.use_native(False)``, forced to pure Python as well.

The parts' register traffic is recorded from the simulated parts on the host and replayed on the
board by non-allocating stand-ins, so the figures are the drivers' cost, not the simulators'.
"""

import os
import sys
import time

from tools import REPO

BOARDS = (("an385", "Cortex-M3"), ("an500", "Cortex-M7"))

# the core benchmark's set-up (tools/bench/core.py): a +-250 dps gyro, milli-dps output
OFFS = [[-35.0, 0.009, -2e-7], [12.0, -0.003, 1e-7], [3.0, 0.0, 1e-7, -1e-11]]
SCS = [[131.0, 4e-4, -3e-8], [130.0, 2e-4], [132.5, -2e-4]]
T_CAL = (-4000, 9000)
BATCH = 32

HARNESS = r"""
import gc, time
def _loop(fn, args, n):
    i = 0
    if not args:
        t0 = time.ticks_us()
        while i < n:
            fn()
            i += 1
        t1 = time.ticks_us()
    elif len(args) == 1:
        a = args[0]
        t0 = time.ticks_us()
        while i < n:
            fn(a)
            i += 1
        t1 = time.ticks_us()
    elif len(args) == 2:
        a, b = args
        t0 = time.ticks_us()
        while i < n:
            fn(a, b)
            i += 1
        t1 = time.ticks_us()
    else:
        a, b, c = args
        t0 = time.ticks_us()
        while i < n:
            fn(a, b, c)
            i += 1
        t1 = time.ticks_us()
    return time.ticks_diff(t1, t0)
def _empty(n):
    i = 0
    t0 = time.ticks_us()
    while i < n:
        i += 1
    return time.ticks_diff(time.ticks_us(), t0)
def _nothing():
    pass
def insn(name, fn, args=(), n=1000, per=1):
    # 1 ns per instruction: us * 1000 / n = instructions per loop pass; best of 3 (a GC may hit one)
    best = None
    for _ in range(3):
        gc.collect()
        d = _loop(fn, args, n)
        if best is None or d < best:
            best = d
    print("INSN %s %.1f %d" % (name, best * 1000.0 / n, per))
def alloc(name, fn, args=(), n=20):
    # heap bytes a call leaves allocated (gc.mem_alloc() over n calls after a collection)
    gc.collect()
    i = 0
    a0 = gc.mem_alloc()
    while i < n:
        fn(*args)
        i += 1
    print("ALLOC %s %.1f" % (name, (gc.mem_alloc() - a0) / n))
def floor(n=2000):
    gc.collect()
    print("INSN empty_loop %.1f 1" % (min(_empty(n), _empty(n)) * 1000.0 / n))
    insn("empty_call", _nothing, (), n)
"""

CORE = r"""
import struct
from tempcomp import fixedpoint as fp
floor()
OFFS = %(offs)r
SCS = %(scs)r
T_CAL = %(t_cal)r
has_switch = hasattr(fp, "use_native")
kinds = [("", None)] + ([("_pure", False)] if has_switch else [])
buf = bytearray(b"\x80\x00\x12\x34\x7f\xff")
out = [0, 0, 0]
for suffix, mode in kinds:
    if has_switch:
        print("NATIVE%%s %%s" %% (suffix, fp.use_native(mode)))
    c = fp.Compensator(OFFS, SCS, T_CAL, out_scale=1000.0)
    c.update(1234)
    insn("apply_be16" + suffix, c.apply_be16, (buf, out))
    alloc("apply_be16" + suffix, c.apply_be16, (buf, out))
    if hasattr(c, "apply_be16_n"):
        bufn = bytearray(bytes(buf) * %(batch)d)
        outn = [0] * (3 * %(batch)d)
        insn("apply_be16_n" + suffix, c.apply_be16_n, (bufn, outn, %(batch)d), 100, %(batch)d)
    st = [0]
    def sweep(c=c, st=st):
        # a new temperature every call, so the polynomial and division stage really runs
        t = (st[0] + 37) & 0x1FFF
        st[0] = t
        c.update(t - 4000)
    insn("update" + suffix, sweep, (), 300)
    def sample_with_update(c=c, st=st, buf=buf, out=out):
        t = (st[0] + 37) & 0x1FFF
        st[0] = t
        c.update(t - 4000)
        c.apply_be16(buf, out)
    insn("sample_with_update" + suffix, sample_with_update, (), 300)
    del c
if has_switch:
    fp.use_native(None)

# the anchors: the same compensation in floats
T = [1234.0]
OFF = [0.0, 0.0, 0.0]
SCL = [0.0, 0.0, 0.0]
def driver_temp(t):
    # a typical driver, per temperature reading: each polynomial in powers of t, as written
    for k in range(3):
        off = 0.0
        p = 1.0
        for a in OFFS[k]:
            off += a * p
            p *= t
        sc = 0.0
        p = 1.0
        for a in SCS[k]:
            sc += a * p
            p *= t
        OFF[k] = off
        SCL[k] = 1000.0 / sc
def driver(buf, out):
    # ... and per sample: struct.unpack of the burst, (raw - offset) * scale per axis, floats out
    x, y, z = struct.unpack(">hhh", buf)
    out[0] = (x - OFF[0]) * SCL[0]
    out[1] = (y - OFF[1]) * SCL[1]
    out[2] = (z - OFF[2]) * SCL[2]
driver_temp(1234.0)
insn("float_driver", driver, (buf, out))
alloc("float_driver", driver, (buf, out))
insn("float_driver_update", driver_temp, (1234.0,), 300)
def naive(buf, out):
    # heavier: both polynomials on every sample, as drivers that read the temperature with every
    # sample do
    v = struct.unpack(">hhh", buf)
    t = T[0]
    for k in range(3):
        off = 0.0
        p = 1.0
        for a in OFFS[k]:
            off += a * p
            p *= t
        sc = 0.0
        p = 1.0
        for a in SCS[k]:
            sc += a * p
            p *= t
        out[k] = int((v[k] - off) / sc * 1000.0)
insn("float_naive", naive, (buf, out), 300)
off = [0.0, 0.0, 0.0]
gain = [0.0, 0.0, 0.0]
def careful_update(t):
    # once per temperature: Horner, and the reciprocal folded into one gain
    for k in range(3):
        o = 0.0
        for a in reversed(OFFS[k]):
            o = o * t + a
        s = 0.0
        for a in reversed(SCS[k]):
            s = s * t + a
        off[k] = o + 0.5 * s / 1000.0  # round half up instead of truncating
        gain[k] = 1000.0 / s
def careful(buf, out):
    # per sample: unpack by hand, one subtract and one multiply per axis
    v = buf[0] << 8 | buf[1]
    if v & 0x8000:
        v -= 0x10000
    out[0] = int((v - off[0]) * gain[0])
    v = buf[2] << 8 | buf[3]
    if v & 0x8000:
        v -= 0x10000
    out[1] = int((v - off[1]) * gain[1])
    v = buf[4] << 8 | buf[5]
    if v & 0x8000:
        v -= 0x10000
    out[2] = int((v - off[2]) * gain[2])
careful_update(1234.0)
insn("float_careful", careful, (buf, out))
insn("float_careful_update", careful_update, (1234.0,), 300)
"""

MPU = r"""
import micropython
from array import array
from replay_i2c import FrameI2C, ReplayI2C
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_tc import BiasModel
floor()
img = %(img)r
stream = %(stream)r
t0 = %(t0)d
pts = [(t0 - 2000, (10.5, -20.25, 3.0), (1000.0, -501.5, 2300.0)),
       (t0, (12.0, -19.0, 2.5), (1004.0, -498.0, 2296.5)),
       (t0 + 2000, (14.5, -17.0, 1.0), (1010.0, -493.0, 2290.0))]
model = BiasModel(pts)
out = array("i", [0] * 7)
raw = array("i", [0] * 7)
# TEMP_OUT as each driver reads it (tools/bench/mpu6xxx.py's scenarios), through a bus whose
# 14-byte read is one C call, as machine.I2C's is
for name, temps in (("", [t0 - 256 + 8 * i for i in range(64)]),
                    ("_noisy", [t0 + d for d in %(noise)r]),
                    ("_steady", [t0])):
    for avg in (16, 1):
        d = MPU6xxx(FrameI2C(img, stream, 16 * 12, temps))
        d.compensate(model)
        d.temp_avg = avg
        insn("read_compensated%%s%%s" %% (name, "" if avg == 16 else "_avg1"), d.read_compensated, (out,), 1024)
        if name == "_steady" and avg == 16:
            steady = d
insn("read_raw", d.read_raw, (raw,))
# read_compensated's frame passes 11 words, so each call takes it from the heap and frees it
# on return (py/objfun.c); the search grows with what the heap holds. Under heap_lock() the
# frame goes on the C stack (the library's hot paths are proven to run there)
keep = [bytearray(100) for _ in range(500)]
insn("read_compensated_steady_live", steady.read_compensated, (out,), 1024)
keep = None
gc.collect()
d0 = d1 = d2 = 0
fn = steady.read_compensated  # the bound method and the argument tuple, made before the lock
args = (out,)
micropython.heap_lock()
d0 = _loop(fn, args, 1024)
d1 = _loop(fn, args, 1024)
d2 = _loop(fn, args, 1024)
micropython.heap_unlock()
print("INSN read_compensated_steady_locked %%.1f 1" %% (min(d0, d1, d2) * 1000.0 / 1024))
def unpack14(b, o):
    i = 0
    while i < 7:
        v = b[2 * i] << 8 | b[2 * i + 1]
        if v & 0x8000:
            v -= 0x10000
        o[i] = v
        i += 1
insn("unpack14", unpack14, (bytearray(14), raw))
imu = MPU6xxx(ReplayI2C(img, stream, 16 * 12, t_base=t0, t_step=0, t_span=64))
insn("fifo_packet", imu._cal()._accumulate, (0, 16), 60, 16)
"""

MLX = r"""
from tempcomp.mlx90609 import MLX90609
floor()
class Pin:
    def value(self, v=None):
        return 1
class ReplaySPI:
    # answers recorded from the simulated part on the host: set-up once, then one rate() in a loop
    def __init__(self, first, loop):
        self.first = first
        self.loop = loop
        self.src = first
        self.pos = 0
    def write_readinto(self, out, into):
        s = self.src
        p = self.pos
        i = 0
        n = len(into)
        while i < n:
            into[i] = s[p]
            p += 1
            i += 1
        if p == len(s):
            p = 0
            self.src = self.loop
        self.pos = p
g = MLX90609(ReplaySPI(%(first)r, %(loop)r), Pin())
print("MLXRATE", g.rate(), g.rate())
insn("mlx_rate", g.rate)
del g
g = MLX90609(ReplaySPI(%(first)r, %(loop16)r), Pin())
g.rate()
g.temp_every = 16
g._count = 0
print("MLXRATE16", " ".join([str(g.rate()) for _ in range(16)]))
insn("mlx_rate_every16", g.rate, (), 1600)
insn("mlx_exchange", g._word, (0x80,))  # last: it leaves the replayed answers out of step
"""

ADXRS = r"""
from array import array
from tempcomp.adxrs import AnalogGyro
from tempcomp.an12760 import AN12760
floor()
class ReplayADC:
    def __init__(self, codes):
        self._buf = array("H", codes)
        self._i = 0
        self._n = len(self._buf)
    def read_u16(self):
        i = self._i
        v = self._buf[i]
        i += 1
        if i >= self._n:
            i = 0
        self._i = i
        return v
pts = %(pts)r
g = AnalogGyro(ReplayADC(%(rc)r), ReplayADC(%(tc)r), 3300, divider=2.0)
g.set_three_point(pts[0], pts[1], pts[2])
insn("adxrs_rate", g.rate)
g16 = AnalogGyro(ReplayADC(%(rc)r), ReplayADC(%(tc)r), 3300, divider=2.0, temp_every=16)
g16.set_three_point(pts[0], pts[1], pts[2])
insn("adxrs_rate_every16", g16.rate, (), 1600)
acc3 = AN12760([(35.0, (1.2, -0.004, 3e-5), 0.03, (-6e-4, 2e-6, -1e-8)),
                (-50.0, (-0.7, 0.002), -0.02, (4e-4,)), (5.0, 0.3, 0.01, 1e-4)],
               4096, (-40, 105), t_scale=1 / 340, t_offset=36.53, out_per_g=10000)
codes = array("h", [acc3.code_of(-40 + 0.7 * i) for i in range(200)])
buf = bytearray(6)
out = array("i", [0, 0, 0])
st = array("i", [0])
def an12760_sample():
    # one 3-axis accelerometer sample: a new temperature code, then the big-endian burst
    i = st[0]
    i = i + 1 if i < 199 else 0
    st[0] = i
    buf[0] = i
    acc3.update(codes[i])
    acc3.apply_be16(buf, out)
insn("an12760_sample", an12760_sample, (), 300)
insn("an12760_steady", acc3.apply_be16, (buf, out))
"""

# (key in the script's output, the row's label); the order of the table
ROWS = (
    ("empty_loop", "empty loop (per pass; subtracted from every row below)"),
    ("empty_call", "call of an empty function"),
    ("apply_be16", "3-axis compensated sample, Compensator.apply_be16"),
    ("apply_be16_pure", "  same, forced pure Python (fixedpoint.use_native(False))"),
    ("apply_be16_n", "  batch apply_be16_n, per 3-axis sample (%d per call)" % BATCH),
    ("apply_be16_n_pure", "  batch, forced pure Python, per sample"),
    ("update", "Compensator.update(t), a new temperature"),
    ("update_pure", "  same, forced pure Python"),
    ("sample_with_update", "update(t) + apply_be16, a new temperature every sample"),
    ("sample_with_update_pure", "  same, forced pure Python"),
    ("float_driver", "anchor: a typical driver's float 3-axis sample (struct, (raw - off) * scale)"),
    ("float_driver_update", "  its per-temperature polynomials"),
    ("float_naive", "anchor: naive float 3-axis sample (struct, polynomials per sample)"),
    ("float_careful", "anchor: careful float 3-axis sample (T steady)"),
    ("float_careful_update", "  careful float, its per-temperature update"),
    ("read_compensated", "MPU-6xxx read_compensated, a new T step every sample (temp_avg=16)"),
    ("read_compensated_avg1", "  same, temp_avg=1 (update + 6 axes on every sample)"),
    ("read_compensated_noisy", "  steady die, TEMP_OUT noise of a real log (temp_avg=16)"),
    ("read_compensated_noisy_avg1", "  same, temp_avg=1"),
    ("read_compensated_steady", "  temperature steady (temp_avg=16)"),
    ("read_compensated_steady_avg1", "  same, temp_avg=1"),
    ("read_compensated_steady_live", "  temperature steady, 50 KB more live data on the heap"),
    ("read_compensated_steady_locked", "  temperature steady, the loop under micropython.heap_lock()"),
    ("read_raw", "  MPU-6xxx read_raw (the same I2C read, no compensation)"),
    ("unpack14", "  14-byte unpack floor (7 words, no bus)"),
    ("fifo_packet", "MPU-6xxx bias capture, one FIFO packet"),
    ("mlx_rate", "MLX90609 rate() (TEMPOUT + rate conversions over SPI, update every sample)"),
    ("mlx_rate_every16", "  same, temp_every=16 (TEMPOUT read and update on 1 sample in 16)"),
    ("mlx_exchange", "  one 3-byte SPI exchange (SPIDevice + the replay bus; ~6 per conversion)"),
    ("adxrs_rate", "ADXRS rate() (VT + rate ADC reads)"),
    ("adxrs_rate_every16", "  same, temp_every=16"),
    ("an12760_sample", "AN12760 3-axis sample (new T code + apply_be16)"),
    ("an12760_steady", "  same, temperature steady (apply_be16 only)"),
)


class _Recorder:
    def __init__(self, spi):
        self.spi = spi
        self.rx = bytearray()

    def __getattr__(self, name):
        return getattr(self.spi, name)

    def write_readinto(self, out, into):
        self.spi.write_readinto(out, into)
        self.rx += bytes(into)


def _mlx_inputs():
    from tempcomp.mlx90609 import MLX90609
    from tools.sim import mlx90609_sim as ms
    sim = ms.MLX90609Sim(version=2, full_scale_dps=150)
    sim.set_state(25.0, 30.0)
    spi, cs = ms.on_simspi(sim)
    rec = _Recorder(spi)
    g = MLX90609(rec, cs)
    first = bytes(rec.rx)
    rec.rx = bytearray()
    g.rate()
    loop = bytes(rec.rx)
    rec.rx = bytearray()
    rates = [g.rate()]
    if bytes(rec.rx) != loop:
        raise SystemExit("bench: the simulated MLX90609 answered two rate() calls differently")
    rates.append(g.rate())
    g.temp_every = 16
    g._count = 0
    loops16 = []
    for _ in range(2):
        rec.rx = bytearray()
        rates16 = [g.rate() for _ in range(16)]
        loops16.append(bytes(rec.rx))
    if loops16[0] != loops16[1]:
        raise SystemExit("bench: the simulated MLX90609 answered two temp_every=16 cycles differently")
    # the same answers replayed on the board must give the host driver's rates
    expect = ["MLXRATE %d %d" % tuple(rates), "MLXRATE16 " + " ".join(str(r) for r in rates16)]
    return dict(first=first + loop, loop=loop, loop16=loops16[0]), expect


def _adxrs_inputs():
    from tempcomp.adxrs import AnalogGyro, point
    from tools.sim.analog_gyro_sim import AnalogGyroSim
    sim = AnalogGyroSim(vref_mv=3300, divider=2.0, noise_mv=0.3, t_noise_mv=0.2, bits=12, seed=3)
    g = AnalogGyro(sim.rate, sim.temp, 3300, divider=2.0)
    pts = []
    for t in (-40, 25, 85):  # three-point calibration as host_tests/device/adxrs_cal.py does it
        sim.temp_c, sim.rate_dps = t, 0.0
        vt, v0 = g.measure(64)
        sim.rate_dps = 200.0
        vt2, v1 = g.measure(64)
        pts.append(point((vt + vt2) / 2, v0, v1, 200.0))
    tc, rc = [], []
    for i in range(97):
        sim.temp_c, sim.rate_dps = -40 + i * 1.3, -250 + 5 * i
        tc.append(sim.temp.read_u16())
        rc.append(sim.rate.read_u16())
    return dict(pts=pts, tc=tc, rc=rc)


def scripts():
    """(name, device script, lines its output must hold) triples; each script runs after a soft
    reset, so each has the heap to itself."""
    from tools.bench.mpu6xxx import replay_inputs

    mlx, mlx_expect = _mlx_inputs()
    return (
        ("core", HARNESS + CORE % dict(offs=OFFS, scs=SCS, t_cal=T_CAL, batch=BATCH), ()),
        ("mpu6xxx", HARNESS + MPU % replay_inputs(), ()),
        ("mlx90609", HARNESS + MLX % mlx, mlx_expect),
        ("adxrs+an12760", HARNESS + ADXRS % _adxrs_inputs(), ()),
    )


def parse(out):
    """{key: instructions per call, net of that script's empty loop}, and the raw lines."""
    raw, extra = {}, {}
    for line in out.splitlines():
        p = line.split()
        if p and p[0] == "INSN":
            raw[p[1]] = (float(p[2]), int(p[3]))
        elif p and p[0].startswith("NATIVE"):
            extra[p[0]] = p[1]
        elif p and p[0] == "ALLOC":
            extra["ALLOC " + p[1]] = float(p[2])
    loop = raw.get("empty_loop", (0.0, 1))[0]
    net = {}
    for k, (v, per) in raw.items():
        net[k] = v if k == "empty_loop" else (v - loop) / per
    return net, extra


def measure(names=("an385", "an500"), areas=None):
    """({board: {row key: instructions}}, {board: notes}); areas: only those scripts (e.g. ("core",))."""
    from tools.firmware.interp import missing, open_interp
    results, notes = {}, {}
    for name in names:
        why = missing(name)
        if why:
            notes[name] = why
            continue
        got, extra = {}, {}
        with open_interp(name) as it:
            for area, code, expect in scripts():
                if areas is not None and area not in areas:
                    continue
                try:
                    out = it.run(code, timeout=900)
                except AssertionError as e:
                    notes.setdefault(name, "")
                    notes[name] += "%s failed: %s; " % (area, str(e).strip().splitlines()[-1])
                    continue
                lines = out.splitlines()
                wrong = [e for e in expect if e not in lines]
                if wrong:  # the replayed driver must compute what it computes on the host
                    notes.setdefault(name, "")
                    notes[name] += "%s: results differ from CPython (%s); " % (area, wrong[0])
                net, ex = parse(out)
                got.update(net)
                extra.update(ex)
        results[name] = got
        notes.setdefault(name, "")
        if "NATIVE" in extra:
            notes[name] += "library default kernels native: %s" % extra["NATIVE"]
    return results, notes


def table(results):
    names = [n for n, _ in BOARDS if n in results]
    lines = ["%-78s %s" % ("instructions per call", "  ".join("%12s" % dict(BOARDS)[n] for n in names))]
    for key, label in ROWS:
        if not any(key in results[n] for n in names):
            continue
        cells = []
        for n in names:
            v = results[n].get(key)
            cells.append("%12s" % ("-" if v is None else "{:,.0f}".format(v)))
        lines.append("%-78s %s" % (label, "  ".join(cells)))
    return lines


def bench(report):
    t0 = time.time()
    results, notes = measure()
    if not results:
        report("instructions: firmware not available", "; ".join(notes.values()), "")
        return
    for line in table(results):
        print("  " + line, flush=True)
    for name, label in BOARDS:
        for key, row in ROWS:
            if key in results.get(name, {}):
                report("instructions: %s, %s" % (label, row), results[name][key], "instructions per call",
                       key="%s_%s" % (name, key))
    for name, label in BOARDS:
        if name in results:
            r = results[name]
            if "apply_be16_pure" in r and "float_driver" in r:
                report("instructions: %s 3-axis sample, pure Python / typical driver's float sample" % label,
                       r["apply_be16_pure"] / r["float_driver"], "x")
            if "apply_be16" in r and "float_naive" in r:
                report("instructions: %s 3-axis sample / naive float sample" % label,
                       r["apply_be16"] / r["float_naive"], "x")
            if "apply_be16" in r and "float_careful" in r:
                report("instructions: %s 3-axis sample / careful float sample" % label,
                       r["apply_be16"] / r["float_careful"], "x")
        if notes.get(name):
            # a script that failed, or a replayed driver whose results differ from CPython's, fails the bench
            bad = "failed" in notes[name] or "differ" in notes[name]
            report("instructions: %s" % label, notes[name], "", key="%s_notes" % name, ok=False if bad else None)
    report("instructions: wall time (qemu, both boards)", time.time() - t0, "s")


# README's table: (key, its label there); the same rows as ROWS
README_ROWS = (
    ("empty_loop", "empty loop (per pass; subtracted from every row)"),
    ("empty_call", "call of an empty function"),
    ("apply_be16", "**3-axis compensated sample**, `Compensator.apply_be16`"),
    ("apply_be16_pure", "same, forced pure Python (`fixedpoint.use_native(False)`)"),
    ("apply_be16_n", "batch `apply_be16_n`, per 3-axis sample (%d per call)" % BATCH),
    ("apply_be16_n_pure", "batch, forced pure Python, per sample"),
    ("update", "`Compensator.update(t)`, a new temperature (scales varying with t)"),
    ("sample_with_update", "`update(t)` + `apply_be16`, a new temperature every sample"),
    ("float_driver", "anchor: a typical driver's float 3-axis sample (`struct`, `(raw - offset) * scale` per axis)"),
    ("float_driver_update", "its per-temperature polynomials"),
    ("float_naive", "anchor: naive float 3-axis sample (`struct`, both polynomials per sample)"),
    ("float_careful", "anchor: careful float 3-axis sample (polynomials once per temperature)"),
    ("float_careful_update", "careful float, its per-temperature update"),
    ("read_compensated", "MPU-6xxx `read_compensated`, a new temperature step every sample (`temp_avg=16`)"),
    ("read_compensated_avg1", "same, `temp_avg=1` (update + 6 axes on every sample)"),
    ("read_compensated_noisy", "steady die, TEMP_OUT noise of a real log (`temp_avg=16`)"),
    ("read_compensated_noisy_avg1", "same, `temp_avg=1`"),
    ("read_compensated_steady", "temperature steady (`temp_avg=16`)"),
    ("read_compensated_steady_avg1", "same, `temp_avg=1`"),
    ("read_compensated_steady_live", "temperature steady, 50 KB more live data on the heap"),
    ("read_compensated_steady_locked", "temperature steady, the loop under `micropython.heap_lock()`"),
    ("read_raw", "MPU-6xxx `read_raw` (the same I²C read, no compensation)"),
    ("unpack14", "the 14-byte unpack floor (7 big-endian words, no bus)"),
    ("fifo_packet", "MPU-6xxx bias capture, one FIFO packet"),
    ("mlx_rate", "MLX90609 `rate()` (TEMPOUT and rate conversions, update every sample)"),
    ("mlx_rate_every16", "same, `temp_every=16`"),
    ("mlx_exchange", "one 3-byte SPI exchange (SPIDevice + replay bus; about 6 per conversion)"),
    ("adxrs_rate", "ADXRS `rate()` (VT and rate ADC reads, update every sample)"),
    ("adxrs_rate_every16", "same, `temp_every=16`"),
    ("an12760_sample", "AN12760 3-axis sample (new temperature code + `apply_be16`)"),
    ("an12760_steady", "same, temperature steady"),
)


def markdown(results):
    """README's instruction table, from one measure()."""
    out = ["| instructions per call | Cortex-M3 | Cortex-M7 |", "|---|---:|---:|"]
    for key, label in README_ROWS:
        cells = []
        for name, _ in BOARDS:
            v = results.get(name, {}).get(key)
            c = "-" if v is None else "{:,.0f}".format(v)
            cells.append("**%s**" % c if label.startswith("**") else c)
        out.append("| %s | %s |" % (label, " | ".join(cells)))
    return "\n".join(out)


if __name__ == "__main__":
    # python -m tools.bench.instructions [--markdown]: the table alone, or README's version of it
    sys.path.insert(0, os.path.join(REPO, "lib"))
    if "--markdown" in sys.argv[1:]:
        res, why = measure()
        print(markdown(res))
        for name, note in why.items():
            print("%s: %s" % (name, note), file=sys.stderr)
    else:
        bench(lambda name, value, unit, key=None, ok=None: print("  %-72s %s %s" % (name, value, unit)))
