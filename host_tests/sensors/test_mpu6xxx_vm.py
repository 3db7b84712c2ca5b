"""tempcomp.mpu6xxx in the real MicroPython VM (32-bit), against the same simulator.

One VM run (host_tests/device/mpu6xxx_vmcheck.py) calibrates simulated parts behind SimI2C,
probes allocation per captured FIFO batch and per compensated sample (allocprobe, with a
non-allocating replay bus fed from the simulator), and prints integer results that CPython
must reproduce exactly.
"""

import os
import sys

import interps
import pytest
import seeds
from mpu_models import random_cases
from paths import REPO

from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_tc import BiasModel
from tools.sim.buses import SimI2C
from tools.sim.mpu6xxx_sim import FACES, MPU6xxxSim

# the VM check's simulated parts: VM_SEED .. VM_SEED + 4 (mpu6xxx_vmcheck.main), other parts every run
VM_SEED = seeds.seed("mpu6xxx_vm/parts") % 1000000


@pytest.fixture(scope="module")
def vm_out(interp):
    # on every interpreter (the interp fixture): the WebAssembly VM, Cortex-M3/M7 firmware, CircuitPython
    return interps.run(
        interp,
        "import mpu6xxx_vmcheck\nmpu6xxx_vmcheck.main(%d)" % VM_SEED,
        mounts=(os.path.join(REPO, "tools", "sim") + ":/tools/sim",),
        paths=("/",),
    )


def test_calibration_in_vm(vm_out):
    lines = [ln.split() for ln in vm_out.splitlines() if ln.startswith("CAL ")]
    assert len(lines) == 4
    for ln in lines:
        face = ln[2]
        regs = [int(v) for v in ln[3:9]]
        factory = [int(v) for v in ln[9:12]]
        mean = [float(v) for v in ln[12:18]]
        exp = FACES[face]
        for k in range(3):
            assert abs(mean[k] / 16384.0 - exp[k]) <= 0.001, ln  # within 1 mg
            # half a register step (2 LSB) + 4 sigma of a 300-sample mean of 1.31 LSB noise
            assert abs(mean[3 + k]) <= 2.0 + 4 * 1.31 / 300**0.5, ln
            assert regs[3 + k] & 1 == factory[k] & 1, ln  # reserved bit 0 kept
    assert {(ln[1], ln[2]) for ln in lines} == {(p, f) for p in ("MPU-6050", "MPU-6500") for f in ("+z", "-y")}


def test_zero_allocation_per_packet_and_sample(vm_out):
    from tools.firmware import mpvm

    res = mpvm.alloc_lines(vm_out)
    for name in ("mpu_fifo_poll_16_packets", "mpu_accumulate_16_packets", "mpu_read_compensated", "mpu_read_compensated_resumed",
                 "mpu_temp_c100"):
        b, locked_ok = res[name]
        assert b == 0 and locked_ok, (name, res[name])
    got = [ln for ln in vm_out.splitlines() if ln.startswith("GOT ")][0]
    # every probed FIFO poll really read 16 packets: (2 + 200 + 2 + 51) calls
    assert int(got.split()[1]) == 16 * 255


def test_vm_integers_match_cpython(vm_out, interp):
    # the same computation on CPython (arbitrary-precision ints, float64) must give identical
    # integers on every interpreter, the Cortex-M3's single-precision floats included: the set-up
    # fits the model and derives its fixed-point integers in exact rational arithmetic
    # (mpu6xxx_tc._exact_fit, fixedpoint._exact_mid), so no float rounding reaches them
    sys.path.insert(0, os.path.join(REPO, "host_tests", "device"))
    try:
        import mpu6xxx_vmcheck as chk
    finally:
        sys.path.pop(0)

    t0 = 4000
    model = BiasModel(chk.model_points(t0))
    sim = MPU6xxxSim("MPU-6500", seed=VM_SEED + 4)  # the VM's compensation_grid part
    sim.regs[0x1B] = 0x18
    sim.regs[0x1C] = 0x00
    imu = MPU6xxx(SimI2C({0x68: sim}))
    imu.compensate(model)
    n = 0
    rt = None
    for ln in vm_out.splitlines():
        f = ln.split()
        if f[0] == "COMP":
            t, raw = int(f[1]), int(f[2])
            imu._ca.update(t)
            imu._cg.update(t)
            exp = [imu._ca.apply(raw, k) for k in range(3)] + [imu._cg.apply(raw, k) for k in range(3)]
            assert [int(v) for v in f[3:]] == exp, ln
            n += 1
        elif f[0] == "TGT":
            g, a = model.targets(int(f[1]))
            assert [int(v) for v in f[2:]] == list(g) + list(a), ln
            n += 1
        elif f[0] == "RT":
            # the boot form resumed on the port from its own compiled() record: bit-identical to
            # that port's set-up path (f[2] == "1": a boot there gets from mpu_tcc what
            # compensate(BiasModel) gave it), and to CPython's set-up path from the same mpu_tc
            t = int(f[1])
            assert f[2] == "1", ln
            f = f[:2] + f[3:]
            if rt is None:
                rt = MPU6xxx(SimI2C({0x68: sim}))
                rt.compensate(BiasModel.from_ints(model.to_ints()))
            rt._ca.update(t)
            rt._cg.update(t)
            assert [int(v) for v in f[2:]] == list(rt._ca.burst3) + list(rt._cg.burst3), ln
            n += 1
        elif f[0] == "TEMP":
            assert int(f[2]) == imu.temp_c100(int(f[1])), ln
            n += 1
    assert n == 7 * 7 + 7 + 7 + 7


# the set-up on each interpreter for models it was not written around: every integer the
# software path keeps (the mpu_tcc record, then resumed by the boot form), the EXTRAPOLATE
# policy's per-temperature numbers beyond the span and the hardware path's register targets
SETUP = r"""
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_tc import BiasModel, compiled
from tools.sim.buses import SimI2C
from tools.sim.mpu6xxx_sim import MPU6xxxSim
sim = MPU6xxxSim("MPU-6500", seed=PART_SEED)
imu = MPU6xxx(SimI2C({0x68: sim}))
for i, (mi, fs, g, a, ts) in enumerate(CASES_):
    sim.regs[0x1B] = fs[0]
    sim.regs[0x1C] = fs[1]
    imu.apply(g, a)
    rec = compiled(imu, mi)
    print("TCC %d %s" % (i, " ".join([str(v) for v in rec])))
    imu.compensate(rec, mi)  # the boot form, which refuses a record outside its bounds
    for t in ts:
        imu._ca.update(t)
        imu._cg.update(t)
        print("RES %d %d %s" % (i, t, " ".join([str(v) for v in list(imu._ca.burst3) + list(imu._cg.burst3)])))
    model = BiasModel.from_ints(mi, 1)
    imu.compensate(model)
    for t in ts:
        imu._ca.update(t)
        imu._cg.update(t)
        tg = model.targets(t)
        print("EXT %d %d %s" % (i, t, " ".join([str(v) for v in list(imu._ca.burst3) + list(imu._cg.burst3) + list(tg[0]) + list(tg[1])])))
"""


def test_setup_integers_identical_on_every_interpreter(interp):
    cases = random_cases(24, seed=seeds.seed("mpu6xxx_vm_models"))
    part = seeds.seed("mpu6xxx_vm/setup_part")
    out = interps.run(interp, SETUP.replace("CASES_", repr(cases)).replace("PART_SEED", str(part)),
                      mounts=(os.path.join(REPO, "tools", "sim") + ":/tools/sim",), paths=("/",), timeout=600)
    from tempcomp.mpu6xxx_tc import compiled

    sim = MPU6xxxSim("MPU-6500", seed=part)
    imu = MPU6xxx(SimI2C({0x68: sim}))
    lines = iter(out.splitlines())
    n = 0
    for i, (mi, fs, g, a, ts) in enumerate(cases):
        sim.regs[0x1B] = fs[0]
        sim.regs[0x1C] = fs[1]
        imu.apply(g, a)
        assert next(lines) == "TCC %d %s" % (i, " ".join(str(v) for v in compiled(imu, mi))), (interp.name, i)
        imu.compensate(BiasModel.from_ints(mi))  # CPython's set-up path: what the resumed record gives
        for t in ts:
            imu._ca.update(t)
            imu._cg.update(t)
            exp = list(imu._ca.burst3) + list(imu._cg.burst3)
            assert next(lines) == "RES %d %d %s" % (i, t, " ".join(str(v) for v in exp)), (interp.name, i, t)
        model = BiasModel.from_ints(mi, 1)
        imu.compensate(model)
        for t in ts:
            imu._ca.update(t)
            imu._cg.update(t)
            tg = model.targets(t)
            exp = list(imu._ca.burst3) + list(imu._cg.burst3) + list(tg[0]) + list(tg[1])
            assert next(lines) == "EXT %d %d %s" % (i, t, " ".join(str(v) for v in exp)), (interp.name, i, t)
        n += 1
    assert n == len(cases)


def _worst_against_float64(cases):
    # read_compensated's integers (set-up on CPython: the same integers as on every interpreter,
    # above) against an independent float64 reference: numpy's least-squares fit of the same
    # points, the registers' datasheet scales, out = 1000 * (raw - offset(T)) / sensitivity
    import numpy as np

    sim = MPU6xxxSim("MPU-6500", seed=seeds.seed("mpu6xxx_vm/float_part"))
    imu = MPU6xxx(SimI2C({0x68: sim}))
    raws = np.arange(-32768, 32768, 257)
    worst = 0.0
    for policy in (0, 1):
        for mi, fs, g, a, probe in cases:
            sim.regs[0x1B] = fs[0]
            sim.regs[0x1C] = fs[1]
            imu.apply(g, a)
            gfs, afs = imu.ranges()[0] // 250, imu.ranges()[1] // 2
            cur = imu._read_offsets()
            model = BiasModel.from_ints(mi, policy)
            imu.compensate(model)
            rows = np.array(mi[1:], dtype=float).reshape(mi[0], 7)
            fits = [np.polyfit(rows[:, 0] - model.t_ref, rows[:, 1 + k] / 16.0, min(mi[0] - 1, 2)) for k in range(6)]
            lo, hi = imu._ca._t_lo, imu._ca._t_hi  # the span, or the extrapolated one
            for t in [int(v) for v in np.linspace(lo, hi, 9)] + probe:
                imu._ca.update(t)
                imu._cg.update(t)
                tt = min(max(t, lo), hi)
                for k in range(6):
                    v = np.polyval(fits[k], tt - model.t_ref)
                    if k < 3:
                        ref = 1000.0 * (raws - (cur[k] - v) * 4.0 / gfs) / (131.0 / gfs)
                        got = [imu._cg.apply(int(r), k) for r in raws]
                    else:
                        ref = 1000.0 * (raws - ((cur[k] & ~1) - v) * 8.0 / afs) / (16384.0 / afs)
                        got = [imu._ca.apply(int(r), k - 3) for r in raws]
                    worst = max(worst, float(np.abs(np.array(got) - ref).max()))
    return worst


def test_exact_setup_within_the_precision_bound():
    # the bound of test_mpu6xxx.py's float reference test, over models it was not written around
    worst = _worst_against_float64(random_cases(24, seed=seeds.seed("mpu6xxx_vm_models")))
    print("exact set-up, 24 random models x 2 policies: worst %.4f output LSB against float64" % worst)
    assert worst <= 0.6, worst


def test_float_setup_without_long_ints_stays_within_the_bound(monkeypatch):
    # a build without long ints (MICROPY_LONGINT_IMPL_NONE) overflows in the exact fit and the
    # exact coefficients: both fall back to float set-up, which must keep the precision bound
    from tempcomp import fixedpoint, mpu6xxx_tc

    def overflow(*_):
        raise OverflowError("small int overflow")

    monkeypatch.setattr(mpu6xxx_tc, "_exact_fit", overflow)
    monkeypatch.setattr(fixedpoint, "_exact_mid", overflow)
    m = BiasModel([(1000, (1.5, 2.0, -3.0), (100.0, -200.0, 300.0)), (3000, (2.0, 2.5, -2.0), (104.0, -190.0, 310.0))])
    assert m._q is None and type(m.offset_poly(0, 0, 1)[0]) is float  # the float path really ran
    worst = _worst_against_float64(random_cases(12, seed=seeds.seed("mpu6xxx_vm_models_float")))
    print("float set-up (no long ints), 12 random models x 2 policies: worst %.4f output LSB" % worst)
    assert worst <= 0.6, worst

