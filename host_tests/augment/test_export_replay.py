"""From a log to the board: the diagnosis' model exported (tools/simgap/export.py) and run by the
device code in the real MicroPython VM (tools/simgap/replay.py) over a withheld log. On logs
from our own generator (helpers/augsynth.py), one effect each, the device's shrink (augmented
replay RMS over base-only replay RMS) equals the host's (the diagnosis' host_check RMS ratio)."""
import json
import os
import subprocess
import sys

import augsynth
import numpy as np
import pytest
import seeds
from paths import REPO, skip_unless_ci

from tools.bench import record
from tools.simgap import export, replay
from tools.simgap.diagnose import diagnose
from tools.simgap.logio import write_log


def run_effect(effect, seed=0):
    tr, wh = augsynth.make(effect, seed=seed), augsynth.make(effect, withheld=True, seed=seed)
    res, _ = diagnose(tr, wh)
    exp = export.build(res, tr)
    full, _ = replay.replay(exp, wh)
    base, _ = replay.replay(exp, wh, base_only=True)
    return res, exp, full, base


def _device_equals_host(effect, seed):
    res, exp, full, base = run_effect(effect, seed)
    assert effect in {e["name"] for e in exp["on_device"]}, (res["verdict"], exp["not_on_device"])
    assert not exp["not_on_device"]
    h = exp["host"]["rms"]
    for a in "xyz":
        host = h["augmented"][a] / h["base_only"][a]
        dev = full["rms"][a] / base["rms"][a]
        assert abs(dev - host) <= 0.005 + 0.02 * host, (a, host, dev)
    # the generator put the effect on x: the board's own output shows it gone
    assert full["rms"]["x"] < 0.6 * base["rms"]["x"]
    for r in (full, base):
        assert r["allocated_per_sample"] == 0 and r["heap_locked"]
        assert r["rows"] == 3000 and r["unit"] == "dps"
    return h, full, base


@pytest.mark.parametrize("effect", augsynth.EFFECTS)
def test_device_shrink_equals_host_shrink(effect):
    # seed 0: the logs `python -m tools bench augment` measures (tools/bench/augment.py), whose
    # figures README shows and this test checks against the record (the test below checks the
    # same property on this run's logs)
    h, full, base = _device_equals_host(effect, 0)
    # README's before/after table (rendered from make bench's record, tools/bench/augment.py's
    # shrink) is what the code gives now: deterministic, so to the record's six digits
    rows = record.load()["areas"]["augment"]["rows"]
    for key, now in (("base", base["rms"]["x"]), ("aug", full["rms"]["x"]),
                     ("ratio", full["rms"]["x"] / base["rms"]["x"]), ("host", h["augmented"]["x"] / h["base_only"]["x"])):
        was = rows["shrink_%s_%s" % (effect, key)]["value"]
        assert was == pytest.approx(now, rel=1e-5), (
            "docs/bench.json's %s %s is %r, the code gives %r: run `python -m tools bench augment`" % (effect, key, was, now))


def test_device_shrink_equals_host_shrink_on_this_runs_logs():
    # one effect a run (all six cost 20 s): other logs, and in turn every effect, every run
    k = seeds.seed("export_replay/effect")
    _device_equals_host(augsynth.EFFECTS[k % len(augsynth.EFFECTS)], k)


def _no_effect(seed):
    tr = augsynth.make(augsynth.NONE, seed=seed)
    wh = augsynth.make(augsynth.NONE, seed=seed, withheld=True)
    res, _ = diagnose(tr, wh)
    # the generator's logs with no effect at all: a verdict there is a false positive of the
    # diagnosis, and that is a failure (never a skip)
    assert res["verdict"] == [], "the diagnosis named %s on a log without effects (seed %d)" % (res["verdict"], seed)
    return tr, wh, res


@pytest.mark.parametrize("seed", seeds.seeds("no_effect", 3))
def test_a_log_without_effects_gets_no_verdict(seed):
    _no_effect(seed)


def test_an_empty_verdict_exports_the_base_model():
    tr, wh, res = _no_effect(seeds.seed("empty_verdict"))
    exp = export.build(res, tr)
    assert exp["device"]["features"] == [] and exp["on_device"] == []
    assert exp["device"]["offset"] == exp["base"]["offset"]
    full, _ = replay.replay(exp, wh)
    base, _ = replay.replay(exp, wh, base_only=True)
    assert full["rms"] == base["rms"]


def test_the_commands_from_a_log_to_a_replay(tmp_path):
    paths = {}
    k = seeds.seed("export_replay/commands")  # the logs of this run
    for name, log in (("train", augsynth.make("hysteresis", seed=k)),
                      ("held", augsynth.make("hysteresis", withheld=True, seed=k))):
        cols = {"time_s": log.t, "temp_c": log.temp}
        cols.update({"out_%s" % a: log.out[:, i] for i, a in enumerate("xyz")})
        cols.update({"ref_%s" % a: log.ref[:, i] for i, a in enumerate("xyz")})
        paths[name] = str(tmp_path / ("%s.csv" % name))
        write_log(paths[name], cols, log.meta)
    model = str(tmp_path / "model.json")
    py = [sys.executable, "-m", "tools"]
    r = subprocess.run(py + ["gap", paths["train"], "--withheld", paths["held"], "--json",
                             str(tmp_path / "gap.json"), "--export", model],
                       cwd=REPO, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "exported" in r.stdout and "hysteresis" in r.stdout
    outs = {}
    for flag in ("", "--base-only"):
        out = str(tmp_path / ("r%s.json" % flag))
        r = subprocess.run(py + ["replay", model, paths["held"], "--json", out] + ([flag] if flag else []),
                           cwd=REPO, capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        with open(out) as f:
            outs[flag] = json.load(f)
        assert set(outs[flag]) >= {"rms", "unit", "rows", "allocated_per_sample"}
        assert outs[flag]["allocated_per_sample"] == 0
    assert outs[""]["rms"]["x"] < 0.2 * outs["--base-only"]["rms"]["x"]


def test_replay_refuses_what_is_not_a_model(tmp_path):
    bad = tmp_path / "m.json"
    bad.write_text('{"verdict": []}')
    log = tmp_path / "l.csv"
    log.write_text("time_s,temp_c,out_x,out_y,out_z,ref_x,ref_y,ref_z\n" + "\n".join(
        "%d,25,1,2,3,0,0,0" % i for i in range(12)))
    r = subprocess.run([sys.executable, "-m", "tools", "replay", str(bad), str(log), "--json",
                        str(tmp_path / "o.json")], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "not an exported model" in r.stderr


def test_an_axis_whose_input_never_moves_gets_a_nominal_sensitivity_and_the_right_offset():
    # z held at -60 dps all along: offset and sensitivity are one number there; the export takes
    # the unit ratio (here --sensitivity) and must leave the board reading -60, not 0
    k = seeds.seed("export_replay/still")  # the logs of this run
    tr = augsynth.make("hysteresis", still=2, seed=k)
    wh = augsynth.make("hysteresis", withheld=True, still=2, seed=k)
    res, _ = diagnose(tr, wh)
    exp = export.build(res, tr, sensitivity=float(augsynth.SENS[2]))
    assert any("axis z: sensitivity not identified" in n for n in exp["notes"])
    base, y = replay.replay(exp, wh, base_only=True)
    h = exp["host"]["rms"]["base_only"]["z"]
    assert abs(np.mean(y[:, 2]) + 60.0) < 0.5
    assert abs(base["rms"]["z"] * augsynth.SENS[2] - h) <= 0.05 * h + 0.1


@pytest.mark.parametrize("name", ["tofupilot_gyro", "tofupilot_accel"])
def test_real_logs_the_board_reproduces_the_hosts_figures(tmp_path, name):
    # float logs (mdps, mg: raw codes chosen by the export), a still gravity axis, sensitivity not
    # identified: on the real TofuPilot logs the board's withheld RMS equals the host's own figure
    from tools.simgap import convert as convert_logs
    from tools.simgap.logio import read_log

    data = convert_logs.default_data_dir()
    if not os.path.isdir(data):
        skip_unless_ci("real data not found at %s" % data)
    paths = convert_logs.convert(data, str(tmp_path))
    train, held = (read_log(p) for p in paths[name])
    res, _ = diagnose(train, held)
    exp = export.build(res, train)
    host = exp["host"]["rms"]
    for base_only, key in ((True, "base_only"), (False, "augmented")):
        r, _ = replay.replay(exp, held, base_only)
        assert r["allocated_per_sample"] == 0
        for a in "xyz":
            # same rows (no outliers in these withheld segments); the board's rounding only
            assert abs(r["rms"][a] * 1000 - host[key][a]) <= 0.01 * host[key][a] + 0.05, (key, a)
