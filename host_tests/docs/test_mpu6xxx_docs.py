"""docs/mpu6xxx.md works as written: its REPL session against a simulated MPU-6500 standing in
for ``machine.I2C`` (on CPython with the shown output, and in the MicroPython VM), and its code
snippets against the same simulated part."""

import doctest
import os
import re
import sys

import pytest
import seeds
from paths import REPO, skip_unless_ci

from tempcomp.mpu6xxx_tc import BiasModel
from tools.firmware import mpvm

DOC = os.path.join(REPO, "docs", "mpu6xxx.md")

# what `machine` is for these tests: a simulated MPU-6500 lying still on its -x face (a part of
# this run: its biases, trim and noise from the run's seed)
FAKE_MACHINE = '''
from tools.sim.buses import SimI2C
from tools.sim.mpu6xxx_sim import MPU6xxxSim

sim = MPU6xxxSim("MPU-6500", seed=PART_SEED)
sim.place("-x")


class Pin:
    def __init__(self, *args, **kwargs):
        pass


def I2C(*args, **kwargs):
    return SimI2C({0x68: sim})
'''


@pytest.fixture
def fake_machine(tmp_path):
    (tmp_path / "machine.py").write_text(FAKE_MACHINE.replace("PART_SEED", str(seeds.seed("mpu6xxx_docs/part"))))
    sys.path.insert(0, str(tmp_path))
    sys.modules.pop("machine", None)
    yield tmp_path
    sys.path.remove(str(tmp_path))
    sys.modules.pop("machine", None)


def blocks():
    return re.findall(r"```(\w*)\n(.*?)```", open(DOC).read(), re.S)


def test_repl_session_gives_the_shown_output(fake_machine):
    repl = [b for lang, b in blocks() if lang == "python" and ">>> " in b]
    assert repl and "MPU-6500" in repl[0]
    for i, block in enumerate(repl):
        test = doctest.DocTestParser().get_doctest(block, {}, "mpu6xxx.md block %d" % i, DOC, 0)
        runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
        runner.run(test)
        assert runner.failures == 0, "docs/mpu6xxx.md block %d does not give the output it shows" % i
    import machine

    # the session really calibrated the part: bias gone on the simulated outputs, to half a step of
    # the accel offset register (bits 15..1 of 1/2048 g: 0.49 mg) + the 4-sigma error of calibrate()'s
    # 1000-sample mean (the part's noise, 5 mg at the MPU-6500's default: 0.63 mg), as test_mpu6xxx.py
    # bounds it (1 mg flat held for one part only: 1.02 mg at TEMPCOMP_SEED=25)
    m = machine.sim.mean_output()
    bound = 1.0 / 2048 + 4.0 * machine.sim.accel_noise / 1000 ** 0.5
    assert abs(m[0] / 16384.0 + 1.0) <= bound and abs(m[1]) / 16384.0 <= bound, (m, bound)


def test_repl_session_runs_in_the_vm(fake_machine):
    repl = [b for lang, b in blocks() if lang == "python" and ">>> " in b]
    src = "\n".join(ln[4:] for b in repl for ln in b.splitlines() if ln.startswith(">>> "))
    src += "\nprint(imu.part, imu.offsets() == (gyro, accel), imu.temp_c100(), len(record))\n"
    out = mpvm.run(
        src,
        mounts=(os.path.join(REPO, "tools", "sim") + ":/tools/sim", str(fake_machine) + ":/fake"),
        paths=("/", "/fake"),
    )
    assert out.split()[-4:] == ["MPU-6500", "True", "2500", "10"]


def test_snippets_run_against_the_simulated_part(fake_machine, tmp_path):
    import machine

    from tempcomp.mpu6xxx import MPU6xxx

    snippets = [b for lang, b in blocks() if lang == ""]
    assert len(snippets) == 5
    i2c = machine.I2C(0)
    imu = MPU6xxx(i2c)
    imu.calibrate(packets=200)
    t = machine.sim.temp_raw()
    # a one-point model (what the BiasModel snippet builds; it runs too when the store is there)
    model = BiasModel([(t, (0.0, 0.0, 0.0), tuple(float(v) for v in imu.factory))])
    ns = {"i2c": i2c, "imu": imu, "MPU6xxx": MPU6xxx, "model": model}
    path = str(tmp_path / "tempcomp.cal")
    for code in snippets:
        code = code.replace("/tempcomp.cal", path)
        if "store" in code.lower():
            from tempcomp.store import Store  # an import error fails: never a silent skip

            ns["store"] = Store(path)
        i2c.writeto_mem(0x68, 0x6B, b"\x01")  # awake, as follow() needs
        exec(code, ns)
        assert isinstance(ns["model"], BiasModel)
    assert ns["out"][6] == 2500


def test_the_temperature_block_figures_come_from_the_real_log():
    # docs/mpu6xxx.md's reason for temp_avg = 16, recomputed from the LSM6DSM log: one reading's
    # scatter, how often its 8-LSB step changes, and the same for the mean of 16 readings
    import numpy as np

    from tools.simgap import convert as convert_logs

    path = os.path.join(convert_logs.default_data_dir(), convert_logs.PAN_REL)
    if not os.path.isfile(path):
        skip_unless_ci("real data not found at %s" % path)
    d = np.genfromtxt(path, delimiter=",", skip_header=1)
    t = d[:, 7].astype(np.int64)
    t = np.where(t > 32767, t - 65536, t)
    edges = np.r_[0, np.nonzero(np.diff(d[:, 0]) > 1000)[0] + 1, len(t)]  # bursts 305 s apart
    assert len(edges) - 1 == 25
    moves = pairs = block_moves = blocks = 0
    sd1 = []
    sd16 = []
    for a, b in zip(edges[:-1], edges[1:]):
        x = t[a:b]
        moves += int(np.sum(np.diff(x // 8) != 0))
        pairs += len(x) - 1
        i = np.arange(len(x))
        sd1.append(np.std(x - np.polyval(np.polyfit(i, x, 1), i)))
        m = len(x) // 16
        mean16 = x[: 16 * m].reshape(m, 16).sum(axis=1) // 16  # read_compensated's floor of the mean
        j = np.arange(m)
        sd16.append(np.std(mean16 - np.polyval(np.polyfit(j, mean16, 1), j)))
        block_moves += int(np.sum(np.diff(mean16 // 8) != 0))
        blocks += m - 1
    doc = " ".join(open(DOC).read().split())
    for said in ("scatters 5.3 LSB", "on 61 % of consecutive samples", "scatters 1.4 LSB (3.8 times less)",
                 "changes on 27 % of blocks: an update on 1.7 % of samples"):
        assert said in doc, said
    assert round(float(np.mean(sd1)), 1) == 5.3
    assert round(100.0 * moves / pairs) == 61
    assert round(float(np.mean(sd16)), 1) == 1.4
    assert round(float(np.mean(sd1) / np.mean(sd16)), 1) == 3.8
    assert round(100.0 * block_moves / blocks) == 27
    assert round(100.0 * block_moves / blocks / 16, 1) == 1.7
