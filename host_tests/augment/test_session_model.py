"""The guided session offers an exported augmented model instead of (or after) the temperature
points, checks it by building it, and saves it; the board then loads it from the store and
compensates as the exported JSON says."""
import json
import types
from array import array

import augsynth
import pytest
import seeds

from tempcomp import augment
from tempcomp.session import Aborted, Session
from tempcomp.store import KIND_AUGMENT, Store
from tools.sim.buses import SimI2C
from tools.sim.mpu6xxx_sim import MPU6xxxSim
from tools.simgap import export
from tools.simgap.diagnose import diagnose


def mpu_board():
    mpu = MPU6xxxSim("MPU-6500", seed=seeds.seed("session_model_part"), gyro_bias_dps=(1.0, 2.0, -3.0))
    return types.SimpleNamespace(i2c=lambda: SimI2C({0x68: mpu}))


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    k = seeds.seed("session_model/log")  # the logs of this run
    tr, wh = augsynth.make("drift", seed=k), augsynth.make("drift", withheld=True, seed=k)
    res, _ = diagnose(tr, wh)
    path = tmp_path_factory.mktemp("m") / "model.json"
    export.write(str(path), res, tr)
    return str(path)


@pytest.mark.parametrize("answer, points", [("i", 0), ("a", 1)])
def test_session_loads_the_model_instead_or_after(tmp_path, model_file, answer, points, capsys):
    path = str(tmp_path / "t.cal")
    sess = Session(mpu_board(), store_path=path, which=("mpu6xxx",), answers=["", "", answer], points=1,
                   packets=200, model=model_file)
    sess.run()
    r = sess.result
    assert len(r.get("points") or []) == points
    assert r["saved"][-1] == "gyro_aug"
    assert "drift" in r["model"]["effects"]
    rec = Store(path).record("gyro_aug", kind=KIND_AUGMENT)
    with open(model_file) as f:
        dev = json.load(f)["device"]
    a = augment.Augmented(augment.from_store(Store(path), "gyro_aug"))
    b = augment.Augmented(dev)
    raw, oa, ob = array("i", [300, -200, 5]), array("i", [0, 0, 0]), array("i", [0, 0, 0])
    for k in range(50):
        a.apply(2500 + k, raw, oa, 2000, 0, None)
        b.apply(2500 + k, raw, ob, 2000, 0, None)
        assert all(abs(x - y) <= 1 for x, y in zip(oa, ob))
    assert len(rec.values) > 40
    assert "augmented model: base + drift" in capsys.readouterr().out


def test_a_bad_model_file_is_named_and_can_be_skipped(tmp_path):
    bad = tmp_path / "model.json"
    bad.write_text('{"store": {"values": [2], "frac": [0]}}')
    path = str(tmp_path / "t.cal")
    sess = Session(mpu_board(), store_path=path, which=("mpu6xxx",), answers=["", "", "i", "s"], points=1,
                   packets=200, model=str(bad))
    sess.run()
    r = sess.result
    assert "model" not in r and r["saved"] == ["mpu6xxx"]
    with pytest.raises(Aborted):
        Session(mpu_board(), store_path=path, which=("mpu6xxx",), answers=["", "", "i", "q"], points=1,
                packets=200, model=str(bad)).run()
