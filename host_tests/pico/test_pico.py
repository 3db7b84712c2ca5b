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

from tempcomp import fixedpoint as fp
from tools import REPO
from tools.board import picoctl

sys.path[:0] = [os.path.join(REPO, "tools", "sim"), os.path.join(REPO, "tools", "vboard", "vm")]
import vboard_sensors as truth  # noqa: E402  (the parts' constants; runs on CPython)


@pytest.fixture(scope="module")
def pico():
    why = picoctl.missing()
    if why:
        pytest.skip("virtual Pico cannot run: " + why)
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


def test_every_sensor_through_the_real_peripherals(pico):
    out = pico.run(r"""
import tempcomp_board as b
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mlx90609 import MLX90609
i2c = b.i2c()
print('SCAN', i2c.scan())
imu = MPU6xxx(i2c)
print('PART', repr(imu.part))
raw = [0] * 7
acc = [0, 0, 0]; gyr = [0, 0, 0]; n = 64
for _ in range(n):
    imu.read_raw(raw)
    for k in range(3):
        acc[k] += raw[k]; gyr[k] += raw[4 + k]
print('MPU', ([a / n for a in acc], [g / n for g in gyr], imu.temp_c100(), imu.ranges()))
mlx = MLX90609(b.spi(), b.mlx_cs())
print('MLX', (mlx.rate_dps(), mlx.tempout_mv()))
r, t = b.adc('rate'), b.adc('temp')
print('ADC', (sum(r.read_u16() for _ in range(32)) / 32, sum(t.read_u16() for _ in range(32)) / 32))
""")
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


OFFS = [[-35.0, 0.009, -2e-7], [12.0, -0.003, 1e-7], [3.0, 0.0, 1e-7, -1e-11]]
SCS = [[131.0, 4e-4, -3e-8], [130.0, 2e-4], [132.5, -2e-4]]
T_CAL = (-4000, 9000)


def test_kernels_bit_identical_to_pure_python_and_cpython_under_heap_lock(pico):
    rng = random.Random(5)
    n = 64
    burst = bytes(rng.getrandbits(8) for _ in range(6 * n))
    temps = [-4000, 1234, 9000]
    want = []
    for t in temps:
        c = fp.Compensator(OFFS, SCS, T_CAL, out_scale=1000.0)
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
for mode in (None, False):
    print('NATIVE', fp.use_native(mode))
    c = fp.Compensator(%r, %r, %r, out_scale=1000.0)
    res = []
    for t in %r:
        c.update(t)
        one = [0] * (3 * n)
        many = [0] * (3 * n)
        arr = array('i', many)
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
        finally:
            micropython.heap_unlock()
        assert one == many == list(arr)
        res.append(many)
    print('RES', res)
""" % (burst, n, OFFS, SCS, T_CAL, temps))
    assert values(out, "NATIVE") == [True, False]
    native, pure = values(out, "RES")
    assert native == pure == want


def test_read_compensated_through_real_i2c_under_heap_lock(pico):
    out = pico.run(r"""
import micropython
from array import array
import tempcomp_board as b
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_tc import BiasModel
imu = MPU6xxx(b.i2c())
t0 = imu.temp_raw()
imu.compensate(BiasModel([(t0 - 2000, (10.5, -20.25, 3.0), (1000.0, -501.5, 2300.0)),
                          (t0, (12.0, -19.0, 2.5), (1004.0, -498.0, 2296.5)),
                          (t0 + 2000, (14.5, -17.0, 1.0), (1010.0, -493.0, 2290.0))]))
out = array('i', [0] * 7)
fn = imu.read_compensated
imu.read_compensated(out)
micropython.heap_lock()
try:
    i = 0
    while i < 50:
        fn(out)
        i += 1
finally:
    micropython.heap_unlock()
print('OUT', list(out))
""")
    (o,), = [values(out, "OUT")]
    assert abs(o[6] - 2500) <= 10, o  # this sample's own temperature, 0.01 degC


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
    rng = random.Random(23)
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
