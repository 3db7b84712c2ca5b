"""The virtual Raspberry Pi Pico: the real MicroPython rp2 firmware on the emulated RP2040 (tools/pico),
tempcomp deployed as make deploy puts it there, the simulated parts on its real I2C, SPI and ADC.

Boot and exec; every sensor read through the real peripherals against the parts' true properties
(tools/vboard/vm/vboard_sensors.py, read here on the host); the hot paths under heap_lock; the
M0+'s native kernels bit-identical to its pure-Python path and to CPython; power cuts during a
store save. Skipped, with the reason, only where the firmware is not built (make setup builds it).
"""

import os
import random
import sys

import pytest
import seeds
from paths import skip_unless_ci

from tempcomp import fixedpoint as fp
from tools import REPO
from tools.board import picoctl

sys.path[:0] = [os.path.join(REPO, "tools", "sim"), os.path.join(REPO, "tools", "vboard", "vm")]
import vboard_sensors as truth  # noqa: E402  (the parts' constants; runs on CPython)


@pytest.fixture(scope="module")
def pico():
    why = picoctl.missing()
    if why:
        skip_unless_ci("virtual Pico cannot run: " + why)
    p = picoctl.PicoInterp()
    yield p
    p.close()


def values(out, tag):
    return [eval(line[len(tag) + 1:]) for line in out.splitlines() if line.startswith(tag + " ")]


def test_boots_the_rp2040_firmware_with_tempcomp_deployed(pico):
    out = pico.run(
        "import sys, os, gc\n"
        "print('IMPL', (sys.implementation._machine, sys.implementation._mpy >> 10 & 0x3F))\n"
        "print('FILES', sorted(os.listdir('/lib/tempcomp'))[:3], 'native_m0.mpy' in os.listdir('/lib/tempcomp'))\n"
        "from tempcomp import fixedpoint\n"
        "print('NATIVE', fixedpoint.use_native())\n")
    assert values(out, "IMPL") == [("Raspberry Pi Pico with RP2040", 4)]  # .mpy arch 4: armv6m
    assert "True" in out.split("FILES", 1)[1].splitlines()[0]
    assert values(out, "NATIVE") == [True]  # the armv6m kernels load on the M0+


SENSE = r"""
import tempcomp_board as b
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mlx90609 import MLX90609
imu = MPU6xxx(b.i2c())
raw = [0] * 7
acc = [0, 0, 0]; gyr = [0, 0, 0]; n = 64
for _ in range(n):
    imu.read_raw(raw)
    for k in range(3):
        acc[k] += raw[k]; gyr[k] += raw[4 + k]
print('MPU', ([a / n for a in acc], [g / n for g in gyr], imu.temp_c100(), imu.ranges()))
mlx = MLX90609(b.spi(), b.mlx_cs())
print('MLX', (sum(mlx.rate_dps() for _ in range(8)) / 8, mlx.tempout_mv()))
r, t = b.adc('rate'), b.adc('temp')
print('ADC', (sum(r.read_u16() for _ in range(64)) / 64, sum(t.read_u16() for _ in range(32)) / 32))
"""


def test_every_sensor_through_the_real_peripherals(pico):
    out = pico.run(r"""
import tempcomp_board as b
from tempcomp.mpu6xxx import MPU6xxx
i2c = b.i2c()
print('SCAN', i2c.scan())
print('PART', repr(MPU6xxx(i2c).part))
""" + SENSE)
    assert values(out, "SCAN") == [[0x68]]  # found by the rp2 port's bit-banged scan
    assert values(out, "PART") == [truth.MPU_PART]
    (acc, gyr, t100, ranges), = values(out, "MPU")
    g_dps, a_g = ranges
    # at rest, +z up, 25 degC: counts = (gravity + bias) * sensitivity, gyro = bias
    lsb_g = 32768 / a_g
    lsb_dps = 32768 / g_dps
    for k in range(3):
        assert abs(acc[k] / lsb_g - ((1.0 if k == 2 else 0.0) + truth.MPU_ACCEL_BIAS_G[k])) < 0.01, acc
        assert abs(gyr[k] / lsb_dps - truth.MPU_GYRO_BIAS_DPS[k]) < 0.05, gyr
    assert abs(t100 - 2500) <= 10, t100
    (rate, tempout), = values(out, "MLX")
    # the factory table's ZRO is off by this board's supply shift (8 mV): that much rate, not more
    assert 0.05 < abs(rate) < 1.5, rate
    (vr, vt), = values(out, "ADC")
    # 2.5 V through the 1:2 divider against 3.3 V, 12 bits (read_u16 widens them)
    code = round(truth.ADXRS_NULL_MV[0] / truth.ADXRS_DIVIDER / truth.ADXRS_VREF_MV * 4095)
    assert abs(vr / 16 - code) < 2 and abs(vt / 16 - code) < 2, (vr, vt, code)
    assert 2000 < tempout < 3000




def test_sensors_follow_the_world_as_it_turns_and_heats(pico):
    # the host's hands (tools/pico/control.mjs): the board on its -x face, turning, at 45 degC;
    # every reading through the real peripherals against the parts' models at that state
    rate = (10.0, -20.0, 30.0)
    temp = 45.0
    with pico.world() as w:
        try:
            w.place("-x")
            w.spin(rate)
            w.heat([(0, temp)])
            out = pico.run(SENSE)
            assert w.state()["temperature_c"] == temp
        finally:
            w.place("+z")
            w.heat([(0, 25.0)])
    (acc, gyr, t100, (g_dps, a_g)), = values(out, "MPU")
    d = temp - 25.0
    for k in range(3):
        b0 = truth.MPU_GYRO_BIAS_DPS[k]
        b1, b2 = truth.MPU_GYRO_TC[k]
        assert abs(gyr[k] / (32768 / g_dps) - (rate[k] + b0 + b1 * d + b2 * d * d)) < 0.05, (k, gyr)
        g = (-1.0 if k == 0 else 0.0) + truth.MPU_ACCEL_BIAS_G[k]  # -x up: gravity along -x
        assert abs(acc[k] / (32768 / a_g) - g) < 0.01, (k, acc)
    assert abs(t100 - 100 * temp) <= 10, t100
    mpu_sim, mlx_sim, adxrs_sim = truth.make_parts()
    (mlx_rate, tempout), = values(out, "MLX")
    assert abs(mlx_rate - rate[2]) < 1.5, mlx_rate  # the supply shift's error at most, as at rest
    assert abs(tempout - mlx_sim.tempout_mv(temp)) < 2.0, (tempout, mlx_sim.tempout_mv(temp))
    (vr, vt), = values(out, "ADC")
    adxrs_sim.temp_c, adxrs_sim.rate_dps = temp, rate[2]
    to12 = truth.ADXRS_DIVIDER * truth.ADXRS_VREF_MV / 4095  # mV per 12-bit code at the sensor
    assert abs(vr / 16 * to12 - adxrs_sim.rate_mv()) < 3 * to12, (vr, adxrs_sim.rate_mv())
    assert abs(vt / 16 * to12 - adxrs_sim.vt_mv()) < 2 * to12, (vt, adxrs_sim.vt_mv())


def test_world_control_is_the_hosts_alone(pico):
    # a Unix socket beside the board's pid file, rw for its user only; fixed verbs, nothing
    # evaluated; code on the board has no way to it (it is not on the board's buses)
    import stat

    sock = os.path.join(pico.home, "world.sock")
    st = os.lstat(sock)
    assert stat.S_ISSOCK(st.st_mode) and stat.S_IMODE(st.st_mode) == 0o600 and st.st_uid == os.getuid()
    with pico.world() as w:
        for bad, why in ((dict(cmd="eval", src="1"), "unknown cmd"), (dict(cmd="place", face="__import__('os')"), "face"),
                         (dict(cmd="spin", rate=[0, 0, 1e9]), "rate"), (dict(cmd="spin", rate=[0, 0, float("nan")]), "not valid JSON"), (dict(cmd="heat", points=[[0, 1e9]]), "degC")):
            with pytest.raises(ValueError, match=why):
                w.call(**bad)
        assert w.state()["face"] == "+z"


OFFS = [[-35.0, 0.009, -2e-7], [12.0, -0.003, 1e-7], [3.0, 0.0, 1e-7, -1e-11]]
SCS = [[131.0, 4e-4, -3e-8], [130.0, 2e-4], [132.5, -2e-4]]
T_CAL = (-4000, 9000)


def _exact(coeffs):
    # each coefficient as the exact (num, den) pair of its nearest float32: the rp2 firmware's
    # floats are single precision, so a decimal literal (0.009, -2e-7) is another number there
    # than on CPython, and a burst drawn per run met the difference (a 1-LSB output at t=9000)
    import numpy as np

    return [[float(np.float32(c)).as_integer_ratio() for c in row] for row in coeffs]


def test_kernels_bit_identical_to_pure_python_and_cpython_under_heap_lock(pico):
    # the same coefficients on both sides: CPython's integers are then the board's exactly
    offs, scs = _exact(OFFS), _exact(SCS)
    rng = random.Random(seeds.seed("pico_kernel_burst"))
    n = 64
    burst = bytes(rng.getrandbits(8) for _ in range(6 * n))
    temps = [-4000, 1234, 9000]
    want = []
    for t in temps:
        c = fp.Compensator(offs, scs, T_CAL, out_scale=1000.0)
        c.update(t)
        out = [0] * (3 * n)
        c.apply_be16_n(burst, out, n)
        want.append(out)
    out = pico.run(r"""
import micropython
from array import array
from tempcomp import fixedpoint as fp
burst = %r
n = %d
view = memoryview(b'xy' + burst)[2:]
for mode in (None, False):
    print('NATIVE', fp.use_native(mode))
    c = fp.Compensator(%r, %r, %r, out_scale=1000.0)
    if mode is None:
        print('ASM', bool(fp._kernels()._t))  # the asm_thumb batch kernel took the M0+
    res = []
    for t in %r:
        c.update(t)
        one = [0] * (3 * n)
        many = [0] * (3 * n)
        arr = array('i', many)
        viewed = [0] * (3 * n)
        three = [0, 0, 0]
        b6 = bytearray(6)
        micropython.heap_lock()
        try:
            i = 0
            while i < n:
                j = 0
                while j < 6:
                    b6[j] = burst[6 * i + j]
                    j += 1
                c.apply_be16(b6, three)
                one[3 * i] = three[0]; one[3 * i + 1] = three[1]; one[3 * i + 2] = three[2]
                i += 1
            c.apply_be16_n(burst, many, n)
            c.apply_be16_n(burst, arr, n)
            c.apply_be16_n(view, viewed, n)
        finally:
            micropython.heap_unlock()
        assert one == many == list(arr) == viewed
        res.append(many)
    print('RES', res)
""" % (burst, n, offs, scs, T_CAL, temps))
    assert values(out, "NATIVE") == [True, False]
    assert values(out, "ASM") == [True]
    native, pure = values(out, "RES")
    assert native == pure == want


POINTS_DT = (-2000, 0, 2000)
POINTS_G = ((10.5, -20.25, 3.0), (12.0, -19.0, 2.5), (14.5, -17.0, 1.0))
POINTS_A = ((1000.0, -501.5, 2300.0), (1004.0, -498.0, 2296.5), (1010.0, -493.0, 2290.0))


def test_read_compensated_through_real_i2c_against_float64(pico):
    # read_compensated on the firmware through the real I2C, the world turning and warming:
    # zero allocation under heap_lock, and each sample against a float64 evaluation on the host
    # of what it should be: the bias model's quadratic through its three points (numpy), held
    # at the span's edges (CLAMP), at the sample's own TEMP_OUT in 8-LSB steps (temp_avg=1),
    # as an offset-register change (RM-MPU-6500: 4 output LSB per gyro register LSB at +-250
    # dps, 8 per accel word LSB at +-2 g) taken from the burst's raw words, in mdps and mg at
    # the datasheet's sensitivities (131 LSB per deg/s, 16384 LSB per g)
    np = pytest.importorskip("numpy")
    script = r"""
import micropython
from array import array
import tempcomp_board as b
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_tc import BiasModel
imu = MPU6xxx(b.i2c())
imu.temp_avg = 1  # every sample compensated at its own reading: an update() on most of them
t0 = imu.temp_raw()
imu.compensate(BiasModel([(t0 + dt, g, a) for dt, g, a in zip(%r, %r, %r)]))
print('SETUP', (t0, imu.offsets(), imu.ranges()))
out = array('i', [0] * 7)
fn = imu.read_compensated
def locked(n):
    micropython.heap_lock()
    try:
        i = 0
        while i < n:
            fn(out)
            i += 1
    finally:
        micropython.heap_unlock()
locked(50)
print('LOCKED', list(out))
d = imu._d14  # the burst each call reads
import time
for _ in range(40):
    time.sleep_ms(50)
    fn(out)
    print('PAIR', ([((d[2 * k] << 8 | d[2 * k + 1]) ^ 0x8000) - 0x8000 for k in range(7)], list(out)))
""" % (POINTS_DT, POINTS_G, POINTS_A)
    with pico.world() as w:
        try:
            w.spin((15.0, -7.5, 40.0))
            w.heat([(0, 25.0), (60, 33.0)])  # warming through the samples
            out = pico.run(script)
        finally:
            w.place("+z")
            w.heat([(0, 25.0)])
    (t0, (gbase, abase), (g_dps, a_g)), = values(out, "SETUP")
    (locked,), = [values(out, "LOCKED")]
    assert abs(locked[5] - 40000) < 5000, locked  # mdps about z: the turntable, give or take bias
    ts = [t0 + dt for dt in POINTS_DT]
    polys = [np.polyfit(ts, [p[k] for p in POINTS_G], 2) for k in range(3)]
    polys += [np.polyfit(ts, [p[k] for p in POINTS_A], 2) for k in range(3)]
    k_g, k_a = 4 * 250.0 / g_dps, 8 * 2.0 / a_g
    pairs = values(out, "PAIR")
    assert len(pairs) == 40 and len({raw[3] for raw, _ in pairs}) > 1  # the temperature moved
    worst = 0.0
    for raw, got in pairs:
        t = raw[3] - raw[3] % 8  # temp_avg=1: this reading, in the 8-LSB steps
        t = min(max(t, ts[0]), ts[-1])  # CLAMP
        for k in range(3):
            reg = np.polyval(polys[3 + k], t)
            want = 1000.0 * (raw[k] - ((abase[k] & ~1) - reg) * k_a) / (16384.0 * 2 / a_g)
            worst = max(worst, abs(got[k] - want))
            reg = np.polyval(polys[k], t)
            want = 1000.0 * (raw[4 + k] - (gbase[k] - reg) * k_g) / (131.0 * 250 / g_dps)
            worst = max(worst, abs(got[3 + k] - want))
        assert got[6] == round(raw[3] / 333.87 * 100 + 2100) or abs(got[6] - (raw[3] / 333.87 * 100 + 2100)) <= 1
    assert worst <= 0.6, worst  # output LSB (1 mdps, 1 mg): the core's bound against float64


def test_augmented_model_under_heap_lock_native_as_pure_within_float64_bound(pico):
    # the augmented model with every term on (host_tests/augment's model and inputs), as the
    # library ships it today, on the M0+: heap-locked, the native kernels bit for bit with the
    # pure path on the same board, and within the stated precision of float64. Not CPython's
    # integers: the rp2 firmware's floats are single precision, and the model's set-up
    # (divisions by the LSB sizes, the filters' exp tables) is float arithmetic, so a few
    # outputs in a thousand come out 1 LSB from CPython's run (TEMPCOMP_SEED=448613, 104, 110;
    # the Cortex-M firmware test, test_augment_firmware, checks the same bound for that reason)
    np = pytest.importorskip("numpy")
    import json

    from augsynth import OUT_SCALE, every_term_model, inputs

    from tools.simgap import devmodel

    m = every_term_model()
    inp, feats = inputs(m, n=60, seed=seeds.seed("pico_augment_inputs"))
    rows = np.column_stack([inp["t"], inp["dt_ms"], inp["raw"], inp["supply"], inp["acc"]]).astype(int).tolist()
    flat = [v for r in rows for v in r]  # t, dt_ms, raw x3, supply, acc x3 per row
    out = pico.run("""
import micropython
from array import array
from tempcomp import augment
from tempcomp.augment import Augmented
print('NATIVE', augment.use_native())
M = %s
ap = Augmented(M).apply
rows = array('i', %r)
n = len(rows) // 9
res = array('i', bytes(12 * n))
three = [array('i', [0, 0, 0]) for _ in range(3)]  # raw, out, acc
def span(lo, hi):
    raw, o, acc = three
    while lo < hi:
        b = 9 * lo
        raw[0] = rows[b + 2]; raw[1] = rows[b + 3]; raw[2] = rows[b + 4]
        acc[0] = rows[b + 6]; acc[1] = rows[b + 7]; acc[2] = rows[b + 8]
        ap(rows[b], raw, o, rows[b + 1], rows[b + 5], acc)
        res[3 * lo] = o[0]; res[3 * lo + 1] = o[1]; res[3 * lo + 2] = o[2]
        lo += 1
span(0, 2)  # first-call caches
micropython.heap_lock()
try:
    span(2, n)
finally:
    micropython.heap_unlock()
print('RES', list(res))
augment.use_native(False)
ap = Augmented(M).apply
span(0, n)
print('PURE', list(res))
""" % (json.dumps(m), flat))
    assert values(out, "NATIVE") == [True], out
    (got,), = [values(out, "RES")]
    (pure,), = [values(out, "PURE")]
    assert got == pure  # the M0+'s native kernels, bit for bit with its pure path
    assert len(got) == 3 * len(rows)
    ref = devmodel.compensate(m, inp, feats) * OUT_SCALE
    assert np.max(np.abs(np.array(got, dtype=float).reshape(-1, 3) - ref)) <= 1.5


STORE_SETUP = ("from tempcomp import store\nst = store.Store('/cut.cal')\nst.save('gyro0', (1, 2, 3))\n"
               "st.save('mlx', tuple(range(24)))\nprint(st.load('gyro0'))\n")
STORE_SAVE = "from tempcomp import store\nst = store.Store('/cut.cal')\nst.save('gyro0', (4, 5, 6))\n"
STORE_CHECK = "from tempcomp import store\nst = store.Store('/cut.cal')\nprint(st.load('gyro0'), st.load('mlx'))\n"


def test_power_cuts_during_a_store_save_restore_old_or_new(pico):
    # a sample of cuts (make bench sweeps >= 200): inside each flash operation of the save at a
    # seeded random point, and at seeded random cycles over the whole save
    ref = picoctl.cut_sweep(pico.flash, STORE_SETUP, STORE_SAVE, STORE_CHECK, [])["reference"]
    ops, cycles = ref["ops"], ref["cycles"]
    assert ops and ref["check"].startswith("(4, 5, 6)")
    rng = random.Random(seeds.seed("pico_power_cuts"))
    cuts = [{"op": k, "frac": rng.random()} for k in range(len(ops))]
    cuts += [{"cycle": rng.randrange(ops[0]["start"], cycles)} for _ in range(3)]
    res = picoctl.cut_sweep(pico.flash, STORE_SETUP, STORE_SAVE, STORE_CHECK, cuts)
    old, new = "(1, 2, 3) %r" % (tuple(range(24)),), "(4, 5, 6) %r" % (tuple(range(24)),)
    seen = set()
    for r in res["cuts"]:
        assert r["powered_off"] and not r["check_err"], r
        assert r["check"].strip() in (old, new), r
        seen.add(r["check"].strip())
        if "op" in r["cut"]:
            assert r["torn"] is not None and r["torn"]["done"] < r["torn"]["len"], r
    assert seen == {old, new}  # cuts before and after the commit point both happened


def test_a_new_module_level_name_under_heap_lock_is_what_raised_memoryerror(pico):
    # The MemoryError a bench loop met under heap_lock() on the Pico (tools/bench/pico.py, the
    # read_compensated loop): not the library but the script's own names. At module level a name
    # is a key of the globals table (py/map.c: open addressing, grown only when every slot is
    # taken, to the next of 2, 4, ... 12, 17, 23, 29, 37 slots), so storing a NEW name under the
    # lock (the loop's time difference, with 23 globals) must grow it and allocate. An existing
    # name or a function's locals never do.
    out = pico.run(r"""
import micropython
code = compile('''
micropython.heap_lock()
try:
    try:
        old = 2
        res[0] = 'old ok'
        new = 1
        res[1] = 'new ok'
    except MemoryError:
        res[1] = 'MemoryError'
finally:
    micropython.heap_unlock()
''', 'probe', 'exec')
for n in range(4, 40):
    g = {'micropython': micropython, 'res': [None, None], 'old': 1}
    i = 0
    while len(g) < n:
        g['v%d' % i] = i
        i += 1
    exec(code, g)
    print('TRIAL', (n, g['res'][0], g['res'][1]))
def inner():
    micropython.heap_lock()
    try:
        a = 1; b = 2; c = 3; d = 4; e = 5; f = 6; g = 7; h = 8
        return 'locals ok'
    finally:
        micropython.heap_unlock()
print('FN', repr(inner()))
""")
    trials = values(out, "TRIAL")
    assert len(trials) == 36
    assert all(old == "old ok" for _, old, _ in trials)
    full = {n for n, _, new in trials if new == "MemoryError"}
    assert full == {4, 6, 8, 10, 12, 17, 23, 29, 37}, full  # py/map.c's table sizes
    assert all(new == "new ok" for n, _, new in trials if n not in full)
    assert values(out, "FN") == ["locals ok"]
