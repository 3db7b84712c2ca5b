"""tempcomp.session on CPython over the simulated buses: answers, skip, quit, no parts.

The expected offsets come from the simulated part's bias (tools/sim), not from the session.
"""

import os
import types

import pytest
import seeds

from tempcomp.session import Aborted, Session, restore
from tools.sim.analog_gyro_sim import AnalogGyroSim
from tools.sim.buses import SimI2C
from tools.sim.mlx90609_sim import MLX90609Sim, on_simspi
from tools.sim.mpu6xxx_sim import MPU6xxxSim

BIAS = (1.0, 2.0, -3.0)  # deg/s at 25 degC, no temperature dependence


def board(with_parts=True):
    mpu = MPU6xxxSim("MPU-6500", seed=seeds.seed("session_part"), gyro_bias_dps=BIAS)
    spi, cs = on_simspi(MLX90609Sim(full_scale_dps=150))
    a = AnalogGyroSim(divider=2.0)
    devices = {0x68: mpu} if with_parts else {}
    return types.SimpleNamespace(
        i2c=lambda: SimI2C(devices), spi=lambda: spi, mlx_cs=lambda: cs, ADC_VREF_MV=3300, ADC_DIVIDER=2.0,
        adc=lambda n: a.rate if n == "rate" else a.temp), mpu


def test_scripted_session_saves_and_restore_reapplies(tmp_path, capsys):
    b, sim = board()
    path = str(tmp_path / "t.cal")
    sess = Session(b, store_path=path, answers=[], points=1, packets=200)
    sess.run()
    r = sess.result
    assert r["saved"] == ["mlx90609", "mpu6xxx", "mpu_tc", "mpu_tcc", "adxrs"]
    # each record says what it holds and for which part (docs/store.md, kinds)
    from tempcomp import store
    st = store.Store(path)
    got = {n: (st.record(n).kind, st.record(n).part) for n in st.names()}
    assert got == {"mlx90609": (store.KIND_MLX_REZERO, "MLX90609"),
                   "mpu6xxx": (store.KIND_MPU_POLY, sim.part), "mpu_tc": (store.KIND_MPU_POLY, sim.part),
                   "mpu_tcc": (store.KIND_MPU_POLY, sim.part),
                   "adxrs": (store.KIND_ADI_3POINT, "")}, got
    want = tuple(round(-v * 32.8) for v in BIAS)
    assert all(abs(g - w) <= 1 for g, w in zip(sim.gyro_offsets(), want)), (sim.gyro_offsets(), want)
    sim.power_cycle()
    assert sim.gyro_offsets() == (0, 0, 0)
    s = restore(b, path)
    assert s.restored == ["mlx90609", "mpu6xxx", "mpu_tc", "adxrs"]
    assert s.model is None and type(s.mpu._cg).__name__ == "_State"  # resumed from mpu_tcc, no set-up
    assert all(abs(g - w) <= 1 for g, w in zip(sim.gyro_offsets(), want))
    assert "[####################] 100%" in capsys.readouterr().out


def test_skip_and_quit(tmp_path):
    b, sim = board()
    path = str(tmp_path / "t.cal")
    sess = Session(b, store_path=path, which=("mpu6xxx",), answers=["s", "s", "s"], points=1)
    sess.run()
    r = sess.result
    assert r["saved"] == [] and sim.gyro_offsets() == (0, 0, 0)
    with pytest.raises(Aborted):
        Session(b, store_path=path, which=("mpu6xxx",), answers=["q"]).run()
    assert not os.path.exists(path)


def test_a_person_quitting_gets_a_message_not_a_traceback(tmp_path, monkeypatch, capsys):
    # at the REPL (no scripted answers) "q" ends the session with its message; nothing raised
    b, sim = board()
    path = str(tmp_path / "t.cal")
    typed = []
    monkeypatch.setattr("builtins.input", lambda prompt="": typed.append(prompt) or "q")
    assert Session(b, store_path=path, which=("mpu6xxx",)).run() is None
    assert "session ended: quit at step 'still'; nothing saved" in capsys.readouterr().out
    assert typed and not os.path.exists(path) and sim.gyro_offsets() == (0, 0, 0)


def test_no_parts_is_a_clear_error(tmp_path):
    b, _ = board(with_parts=False)
    with pytest.raises(OSError, match="no sensor answered"):
        Session(b, store_path=str(tmp_path / "t.cal"), which=("mpu6xxx",), answers=[]).run()
    with pytest.raises(ValueError, match="points"):
        Session(b, points=0)
