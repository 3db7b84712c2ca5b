"""The boot form of the MPU's software offset(T): tempcomp.mpu6xxx_rt resumes the per-sample
state that tempcomp.mpu6xxx_tc.compiled() exported, without the fixed-point set-up.

The reference is the set-up path itself, compensate(BiasModel.from_ints(mpu_tc)), which the
precision tests compare with float64: the resumed state must give the same integers at every
temperature reading (bit-identical), and refuse a record that does not fit the part.
"""

import os
from array import array

import pytest
import seeds

from tempcomp.fixedpoint import EXTRAPOLATE
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_rt import LENGTH
from tempcomp.mpu6xxx_tc import BiasModel, compiled
from tempcomp.store import Store
from tools.sim.buses import SimI2C
from tools.sim.mpu6xxx_sim import MPU6xxxSim

T0 = 4000
MODELS = {
    "one point": [(T0, (12.0, -19.0, 2.5), (1004.0, -498.0, 2296.5))],
    "two points": [(T0 - 1500, (10.5, -20.25, 3.0), (1000.0, -501.5, 2300.0)),
                   (T0 + 900, (14.5, -17.0, 1.0), (1010.0, -493.0, 2290.0))],
    "three points": [(T0 - 2000, (10.5, -20.25, 3.0), (1000.0, -501.5, 2300.0)),
                     (T0, (12.0, -19.0, 2.5), (1004.0, -498.0, 2296.5)),
                     (T0 + 2000, (14.5, -17.0, 1.0), (1010.0, -493.0, 2290.0))],
    "five points": [(T0 - 3000 + 1400 * i, (3.0 * i - 40.0, 0.5 * i * i, -7.0 + i), (-2000.0 + 9.0 * i, 15.0 * i, 4000.0 - i * i))
                    for i in range(5)],
}


def part(seed=3):
    # the part's biases and noise differ from run to run (seed k of the run: equal k, equal parts)
    sim = MPU6xxxSim("MPU-6500", seed=seeds.seed("mpu6xxx_rt_part", seed), temp_c=30.0)
    return sim, SimI2C({0x68: sim})


def both(bus, ints, ranges, policy=0):
    """(imu compensated by the set-up path, imu resumed from the compiled record)."""
    a = MPU6xxx(bus)
    a.set_ranges(*ranges)
    a.compensate(BiasModel.from_ints(ints, policy))
    b = MPU6xxx(bus)
    b.compensate(compiled(b, ints), ints)
    return a, b


@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("ranges", [(250, 2), (2000, 16), (500, 8)])
def test_resumed_state_is_bit_identical_over_every_temperature(name, ranges):
    sim, bus = part()
    bus.writeto_mem(0x68, 0x13, bytes([0x01, 0x2C, 0xFF, 0x38, 0x00, 0x07]))  # gyro offsets +300 -200 +7
    ints = BiasModel(MODELS[name]).to_ints()
    a, b = both(bus, ints, ranges)
    assert type(b._ca).__name__ == "_State"  # the resumed form, not a Compensator
    for t in list(range(-32768, 32768, 97)) + [T0 - 2000, T0 + 2000, T0 - 2001, T0 + 2001]:
        for c in ("_ca", "_cg"):
            ca, cb = getattr(a, c), getattr(b, c)
            ca.update(t)
            cb.update(t)
            assert list(ca.burst3) == list(cb.burst3), (name, ranges, t, c)
    assert (a._ca.clamped, a._cg.clamped) == (b._ca.clamped, b._cg.clamped)
    assert a._ca.clamped > 0  # the sweep did leave the calibrated span


def test_read_compensated_identical_through_the_store(tmp_path):
    sim, bus = part(seed=9)
    sim.set_tc(gyro=[(0.05, 0.002), (-0.03, 0.001), (0.02, -0.0015)], accel=[(0.0004, 0.00001)] * 3)
    imu = MPU6xxx(bus)
    imu.calibrate(packets=200)
    pts = []
    for tc in (10.0, 30.0, 50.0):
        sim.temp_c = tc
        pts.append(imu.bias_point(packets=200))
    path = os.path.join(str(tmp_path), "cal")
    st = Store(path)
    imu.save(st)
    mi = BiasModel(pts).to_ints()
    st.save("mpu_tc", mi)
    st.save("mpu_tcc", compiled(imu, mi))
    # a fresh boot of two identical parts (same seed: the same samples), one path each
    st = Store(path)
    boards = []
    for _ in range(2):
        s2, bus2 = part(seed=9)
        s2.set_tc(gyro=[(0.05, 0.002), (-0.03, 0.001), (0.02, -0.0015)], accel=[(0.0004, 0.00001)] * 3)
        boards.append((s2, MPU6xxx(bus2)))
    (sa, a), (sb, b) = boards
    a.restore(st)
    a.compensate(BiasModel.from_ints(st.load("mpu_tc")))
    b.restore(st)
    b.compensate(st.load("mpu_tcc"), st.load("mpu_tc"))
    oa = array("i", [0] * 7)
    ob = array("i", [0] * 7)
    for tc in (-20.0, 5.0, 10.0, 22.2, 30.0, 47.5, 50.0, 80.0):
        sa.temp_c = sb.temp_c = tc
        for _ in range(5):
            sa.ns += 1000000
            sb.ns += 1000000
            a.read_compensated(oa)
            b.read_compensated(ob)
            assert list(oa[:6]) != [0] * 6
            assert list(oa) == list(ob), tc


def test_compiled_leaves_the_running_compensation_alone():
    sim, bus = part()
    model = BiasModel(MODELS["three points"], EXTRAPOLATE)
    imu = MPU6xxx(bus)
    imu.compensate(model)
    ca = imu._ca
    rec = compiled(imu, model.to_ints())
    assert imu._ca is ca and len(rec) == LENGTH


def test_record_that_does_not_fit_is_refused_and_nothing_changes():
    sim, bus = part()
    ints = BiasModel(MODELS["two points"]).to_ints()
    imu = MPU6xxx(bus)
    rec = compiled(imu, ints)
    other = BiasModel(MODELS["three points"]).to_ints()
    cases = [
        (rec[:-1], ints, "not a compiled offset"),
        ([2] + rec[1:], ints, "not a compiled offset"),
        (rec, other, "not built from this mpu_tc"),
        (rec[:10] + [rec[10], rec[11], rec[12], 99] + rec[14:], ints, "not a compiled offset"),
        (rec[:10 + 20] + [1 << 30] + rec[31:], ints, "not a compiled offset"),
    ]
    for bad, model, msg in cases:
        with pytest.raises(ValueError, match=msg):
            imu.compensate(bad, model)
        assert imu._ca is None and imu._cg is None
    imu.set_ranges(gyro_dps=1000)
    with pytest.raises(ValueError, match="built for \\+-250 dps, \\+-2 g; the part is set to \\+-1000 dps"):
        imu.compensate(rec, ints)
    imu.set_ranges(gyro_dps=250)
    imu.apply((1, 2, 3), (0, 0, 0))
    with pytest.raises(ValueError, match="other offset registers"):
        imu.compensate(rec, ints)
    assert imu._ca is None
    with pytest.raises(ValueError, match="call compensate"):
        imu.read_compensated([0] * 7)


def test_boot_from_the_const_export_reads_what_the_store_boot_reads(tmp_path, monkeypatch):
    # docs/ram.md's two blocks as written (paths moved into tmp_path): the store's const() export
    # as the boot's source, no store reader at boot; it must read what the store boot reads
    import sys

    from docblocks import REPO, blocks

    docs = [b.body for b in blocks(REPO / "docs" / "ram.md") if b.lang == "python" and "calib_const" in b.body]
    assert len(docs) == 2, docs
    sim, bus = part(seed=9)
    imu = MPU6xxx(bus)
    imu.calibrate(packets=200)
    pts = []
    for tc in (15.0, 40.0):
        sim.temp_c = tc
        pts.append(imu.bias_point(packets=200))
    path = str(tmp_path / "tempcomp.cal")
    st = Store(path)
    imu.save(st)
    mi = BiasModel(pts).to_ints()
    st.save("mpu_tc", mi)
    st.save("mpu_tcc", compiled(imu, mi))
    exec(docs[0].replace('"/tempcomp.cal"', repr(path)).replace('"/calib_const.py"', repr(str(tmp_path / "calib_const.py"))), {})
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "calib_const", raising=False)
    outs = []
    for how in ("store", "docs"):
        s2, bus2 = part(seed=9)
        s2.temp_c = 33.0
        s2.ns += 1000000
        buf = array("i", [0] * 7)
        if how == "store":
            b = MPU6xxx(bus2)
            b.restore(Store(path))
            b.compensate(Store(path).load("mpu_tcc"), Store(path).load("mpu_tc"))
            b.read_compensated(buf)
        else:
            exec(docs[1], {"i2c": bus2, "buf": buf})
        outs.append(list(buf))
    assert outs[0] == outs[1] and outs[0][:6] != [0] * 6


def test_random_models_compile_to_records_the_boot_accepts():
    # 200 models the set-up was not written around (spans from 40 raw counts to most of the int16
    # range, 1..6 points, every range): each compiled record passes resume()'s bound checks and
    # resumes bit-identical to the set-up path, beyond the span too
    from mpu_models import random_cases

    sim, bus = part(seed=4)
    for mi, fs, g, a, probe in random_cases(200, seed=seeds.seed("mpu6xxx_rt_models")):
        sim.regs[0x1B] = fs[0]
        sim.regs[0x1C] = fs[1]
        MPU6xxx(bus).apply(g, a)
        ref, got = both(bus, mi, MPU6xxx(bus).ranges())
        assert type(got._ca).__name__ == "_State"
        lo, hi = ref._ca._t_lo, ref._ca._t_hi
        for t in probe + [lo + (hi - lo) * i // 16 for i in range(17)]:
            for c in ("_ca", "_cg"):
                ca, cb = getattr(ref, c), getattr(got, c)
                ca.update(t)
                cb.update(t)
                assert list(ca.burst3) == list(cb.burst3), (mi, fs, t, c)
