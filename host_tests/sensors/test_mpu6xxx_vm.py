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
from paths import REPO

from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_tc import BiasModel
from tools.sim.buses import SimI2C
from tools.sim.mpu6xxx_sim import FACES, MPU6xxxSim


@pytest.fixture(scope="module")
def vm_out(interp):
    # on every interpreter (the interp fixture): the WebAssembly VM, Cortex-M3/M7 firmware, CircuitPython
    return interps.run(
        interp,
        "import mpu6xxx_vmcheck\nmpu6xxx_vmcheck.main()",
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
    # the same computation on CPython (arbitrary-precision ints) must give identical integers; on the
    # Cortex-M3 the set-up's float coefficients are single precision, and a compensated value may
    # land on the other side of a rounding step: there one output LSB, on few values
    single = interp.name == "an385"
    off_by_one = []
    rt_differs = []
    sys.path.insert(0, os.path.join(REPO, "host_tests", "device"))
    try:
        import mpu6xxx_vmcheck as chk
    finally:
        sys.path.pop(0)

    t0 = 4000
    model = BiasModel(chk.model_points(t0))
    sim = MPU6xxxSim("MPU-6500", seed=5)
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
            got = [int(v) for v in f[3:]]
            if single:
                assert all(abs(a - b) <= 1 for a, b in zip(got, exp)), (ln, exp)
                off_by_one += [ln for a, b in zip(got, exp) if a != b]
            else:
                assert got == exp, ln
            n += 1
        elif f[0] == "TGT":
            g, a = model.targets(int(f[1]))
            assert [int(v) for v in f[2:]] == list(g) + list(a), ln
            n += 1
        elif f[0] == "RT":
            # the boot form resumed on the VM from its own compiled() record. On the port itself
            # it is bit-identical to that port's set-up path (every interpreter): a boot there gets
            # from mpu_tcc what compensate(BiasModel) gave it. Against CPython's set-up path: the
            # same numbers, except where the port's floats are single precision (below)
            t = int(f[1])
            assert f[2] == "1", ln
            f = f[:2] + f[3:]
            if rt is None:
                rt = MPU6xxx(SimI2C({0x68: sim}))
                rt.compensate(BiasModel.from_ints(model.to_ints()))
            rt._ca.update(t)
            rt._cg.update(t)
            exp = list(rt._ca._p3) + list(rt._cg._p3)
            if single and [int(v) for v in f[2:]] != exp:
                rt_differs.append("%s (CPython: %s)" % (ln, " ".join(str(v) for v in exp)))
            else:
                assert [int(v) for v in f[2:]] == exp, ln
            n += 1
        elif f[0] == "TEMP":
            assert int(f[2]) == imu.temp_c100(int(f[1])), ln
            n += 1
    assert n == 7 * 7 + 7 + 7 + 7
    # few: a systematic error would move most of the 294 values
    assert len(off_by_one) <= 3, off_by_one
    if rt_differs:
        pytest.xfail("single-precision set-up on the Cortex-M3: the boot form's integer coefficients differ "
                     "from CPython's (%d of 7 temperatures), e.g. %s" % (len(rt_differs), rt_differs[0]))
