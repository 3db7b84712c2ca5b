"""MPU-6xxx figures for `make bench`: capture and per-sample cost, allocation, precision.

``bench(report)`` measures in one run: in the MicroPython VM, time per captured FIFO packet
and per compensated sample (ratios to an unpack floor measured in the same run, as
tools/bench/__main__.py does) and bytes allocated for each; on CPython against the simulated part, the
bus traffic and simulated duration of a default calibration, the bias left after it, and the
worst error of the software offset(T) path against float64.
"""

import os
import random
import sys
import time

from tempcomp.mpu6xxx import MPU6xxx  # noqa: E402
from tempcomp.mpu6xxx_tc import BiasModel  # noqa: E402
from tools import REPO
from tools.firmware import mpvm  # noqa: E402
from tools.sim.buses import SimI2C  # noqa: E402
from tools.sim.mpu6xxx_sim import FACES, MPU6xxxSim  # noqa: E402

VM_BENCH = r"""
import time
from array import array
import allocprobe
from replay_i2c import FrameI2C, ReplayI2C
from mpu6xxx_vmcheck import model_points
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_tc import BiasModel

img = bytearray(%(img)r)
stream = bytearray(%(stream)r)
t0 = %(t0)d
imu = MPU6xxx(ReplayI2C(img, stream, 16 * 12, t_base=t0 - 256, t_step=8, t_span=64))
model = BiasModel(model_points(t0))
imu.compensate(model)
out = array("i", [0] * 7)
raw = array("i", [0] * 7)
pk = bytearray(12)
b14 = bytearray(14)
# the temperature readings each driver sees (TEMP_OUT raw codes, one per sample, in a ring)
SCEN = {
    "ramp": [t0 - 256 + 8 * i for i in range(64)],  # a new 8-LSB step on every sample
    "noisy": [t0 + d for d in %(noise)r],  # a steady die read with the noise of a real log
    "steady": [t0],
}
drv = {}
for name in SCEN:
    for avg in (16, 1):
        d = MPU6xxx(FrameI2C(img, stream, 16 * 12, SCEN[name]))
        d.compensate(model)
        d.temp_avg = avg
        drv[name + str(avg)] = d

def unpack(b, o, n):
    # the floor: n big-endian words into signed ints
    i = 0
    while i < n:
        v = b[2 * i] << 8 | b[2 * i + 1]
        if v & 0x8000:
            v -= 0x10000
        o[i] = v
        i += 1

dev = drv["steady16"]._dev
def busread(b):
    dev.read_into(0x3B, b)

def loop(fn, args, n):
    i = 0
    t = time.ticks_ms()
    if len(args) == 1:
        a = args[0]
        while i < n:
            fn(a)
            i += 1
    elif len(args) == 2:
        a, b = args
        while i < n:
            fn(a, b)
            i += 1
    else:
        a, b, c = args
        while i < n:
            fn(a, b, c)
            i += 1
    return time.ticks_diff(time.ticks_ms(), t)

allocprobe.report("acc16", imu._cal()._accumulate, (0, 16), 200)
allocprobe.report("comp", imu.read_compensated, (out,), 200)
for k in drv:
    allocprobe.report("comp_" + k, drv[k].read_compensated, (out,), 200)
best = {}
def keep(k, v):
    best[k] = min(best.get(k, 1e9), v)
N = %(n)d
for rep in range(%(reps)d):
    keep("unpack12", loop(unpack, (pk, raw, 6), N))
    keep("unpack14", loop(unpack, (b14, raw, 7), N))
    keep("acc16", loop(imu._cal()._accumulate, (0, 16), N // 16))
    keep("bus", loop(busread, (b14,), N))
    keep("raw", loop(drv["steady16"].read_raw, (raw,), N))
    for k in drv:
        keep(k, loop(drv[k].read_compensated, (out,), N))
for k in best:
    print("TIME %%s %%d" %% (k, best[k]))
"""

def replay_inputs():
    """What the replay buses serve (the VM bench here, the firmware's in tools/bench/instructions.py):
    a simulated MPU-6500 at rest on +z, its register image with one data sample, 16 FIFO packets
    of accel and gyro words, and its TEMP_OUT reading; built here on the host, so every
    interpreter replays the same bytes."""
    sim = MPU6xxxSim("MPU-6500", seed=5)
    sim.place("+z")
    sim.regs[0x6B] = 0x01
    stream = bytearray()
    for _ in range(16):
        s = sim._sample()
        stream += s[0:6]
        stream += s[8:14]
    img = bytearray(sim.regs)
    img[0x3B:0x49] = sim._sample()
    return dict(img=bytes(img), stream=bytes(stream), t0=sim.temp_raw(), noise=NOISE)


# TEMP_OUT noise of a real die sensor: sigma 5.3 LSB about its trend (the LSM6DSM log behind
# docs/mpu6xxx.md's temp_avg), drawn once here so that every run replays the same readings
_RNG = random.Random(11)
NOISE = [int(round(_RNG.gauss(0.0, 5.3))) for _ in range(256)]

SCENARIOS = (
    ("steady", "temperature steady"),
    ("noisy", "steady die, TEMP_OUT noise of a real log (sigma 5.3 LSB)"),
    ("ramp", "a new 8-LSB temperature step on every sample"),
)


def vm_figures(report):
    code = VM_BENCH % dict(replay_inputs(), n=20000, reps=5)
    out = mpvm.run(
        code,
        # mpu6xxx_vmcheck (model_points) imports the simulator
        mounts=(os.path.join(REPO, "tools", "sim") + ":/tools/sim",),
        paths=("/",),
        heap="2m",
        timeout=900,
    )
    alloc = mpvm.alloc_lines(out)
    t = {}
    for line in out.splitlines():
        if line.startswith("TIME "):
            _, k, v = line.split()
            t[k] = float(v)
    comp = [k for k in alloc if k.startswith("comp")]
    report("mpu6xxx: bytes allocated per captured FIFO packet (VM)", alloc["acc16"][0] / 16, "B", key="alloc_packet",
           ok=alloc["acc16"][0] == 0)
    worst = max(alloc[k][0] for k in comp)
    report("mpu6xxx: bytes allocated per compensated sample, worst of %d drivers (VM)" % len(comp), worst, "B",
           key="alloc_sample", ok=worst == 0)
    locked = alloc["acc16"][1] and all(alloc[k][1] for k in comp)
    report("mpu6xxx: heap-locked capture and compensation", "ok" if locked else "FAIL", "", key="locked",
           ok=bool(locked))
    # acc16 ran N/16 calls of 16 packets: N packets, as many as the floor unpacked
    report("mpu6xxx: time per captured packet (sum, min/max) / 12-byte unpack floor", t["acc16"] / t["unpack12"], "x",
           key="packet_ratio")
    # the data registers come through a bus whose read is one C call (FrameI2C), as
    # machine.I2C's is on a board; the floor unpacks the same 14 bytes with no bus at all
    report("mpu6xxx: the 14-byte bus read alone / 14-byte unpack floor", t["bus"] / t["unpack14"], "x",
           key="bus_ratio")
    report("mpu6xxx: read_raw / 14-byte unpack floor", t["raw"] / t["unpack14"], "x", key="raw_ratio")
    for key, what in SCENARIOS:
        for avg in (16, 1):
            k = key + str(avg)
            report("mpu6xxx: read_compensated, temp_avg=%d, %s / 14-byte unpack floor" % (avg, what),
                   t[k] / t["unpack14"], "x", key="comp_%s%d_ratio" % (key, avg))
            report("mpu6xxx:   same / read_raw", t[k] / t["raw"], "x", key="comp_%s%d_vs_raw" % (key, avg))


def sim_figures(report):
    sim = MPU6xxxSim("MPU-6500", seed=1)
    bus = SimI2C({0x68: sim})
    imu = MPU6xxx(bus)
    bus.transactions = 0
    ns0 = sim.ns
    w0 = time.time()
    imu.calibrate()
    wall = time.time() - w0
    report("mpu6xxx: bus transactions per captured packet (default calibrate, 400 kHz)", bus.transactions / 1050.0, "",
           key="bus_per_packet")
    report("mpu6xxx: simulated duration of a default calibration (1000 packets + 50 settling)", (sim.ns - ns0) / 1e6,
           "ms", key="cal_sim_ms")
    report("mpu6xxx: CPython wall time of that calibration against the simulator", wall * 1000, "ms", key="cal_wall_ms")
    worst_g = worst_a = 0.0
    for i, face in enumerate(FACES):
        sim = MPU6xxxSim("MPU-6500", seed=50 + i)
        sim.place(face)
        imu = MPU6xxx(SimI2C({0x68: sim}))
        imu.calibrate()
        m = sim.mean_output()
        worst_g = max(worst_g, max(abs(v) for v in m[3:]))
        worst_a = max(worst_a, max(abs(m[k] / 16384.0 - FACES[face][k]) for k in range(3)))
    report("mpu6xxx: bias left, datasheet noise, 6 faces: gyro (half a step = 2)", worst_g, "LSB at 250 dps",
           key="bias_gyro")
    report("mpu6xxx: bias left, datasheet noise, 6 faces: accel (half a step = 0.49)", worst_a * 1000, "mg",
           key="bias_accel")
    # software offset(T): integer path vs float64 over all raw codes, across and beyond t_cal
    t0 = 4000
    from mpu6xxx_vmcheck import model_points  # host_tests/vm, plain Python

    model = BiasModel(model_points(t0))
    sim = MPU6xxxSim("MPU-6500", seed=43)
    imu = MPU6xxx(SimI2C({0x68: sim}))
    worst = 0.0
    for gdps, ag in ((250, 2), (2000, 16)):
        imu.set_ranges(gyro_dps=gdps, accel_g=ag)
        imu.compensate(model)
        cur = imu.offsets()
        for t in range(t0 - 2600, t0 + 2601, 650):
            imu._ca.update(t)
            imu._cg.update(t)
            tg = max(t0 - 2000, min(t0 + 2000, t))
            for k in range(3):
                off_g = (cur[0][k] - model.value(k, tg)) * 4.0 / (gdps // 250)
                off_a = ((cur[1][k] & ~1) - model.value(3 + k, tg)) * 8.0 / (ag // 2)
                sg = 131.0 / (gdps // 250)
                sa = 16384.0 / (ag // 2)
                for raw in range(-32768, 32768, 7):
                    worst = max(
                        worst,
                        abs(imu._cg.apply(raw, k) - 1000.0 * (raw - off_g) / sg),
                        abs(imu._ca.apply(raw, k) - 1000.0 * (raw - off_a) / sa),
                    )
    report("mpu6xxx: software offset(T) worst error vs float64 (mdps / mg)", worst, "output LSB", key="tc_worst")
    report("mpu6xxx: temperature fixed point worst error", _temp_error(), "0.01 degC", key="temp_worst")


def _temp_error():
    worst = 0.0
    for part, sens, zero in (("MPU-6050", 340.0, 36.53), ("MPU-6500", 333.87, 21.0), ("ICM-20602", 326.8, 25.0)):
        imu = MPU6xxx(SimI2C({0x68: MPU6xxxSim(part)}))
        for raw in range(-32768, 32768):
            worst = max(worst, abs(imu.temp_c100(raw) - (raw / sens + zero) * 100.0))
    return worst


def bench(report):
    sys.path.insert(0, os.path.join(REPO, "host_tests", "device"))
    try:
        vm_figures(report)
        sim_figures(report)
    finally:
        sys.path.remove(os.path.join(REPO, "host_tests", "device"))


if __name__ == "__main__":
    def _report(name, value, unit, key=None, ok=None):
        print("  %-78s %s %s" % (name, "%.4g" % value if isinstance(value, float) else value, unit))

    bench(_report)
