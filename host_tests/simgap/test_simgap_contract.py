"""The command line and the JSON contract of `python -m tools.simgap`."""
import json
import subprocess
import sys

import numpy as np
import pytest
from paths import REPO
from seeds import seed
from simgap_synth import make, play

from tools.simgap.effects import CATALOGUE
from tools.simgap.logio import write_log


def _write(path, log):
    cols = {"time_s": log.t, "temp_c": log.temp}
    for i, a in enumerate("xyz"):
        cols[f"out_{a}"] = log.out[:, i]
    for i, a in enumerate("xyz"):
        cols[f"ref_{a}"] = log.ref[:, i]
    write_log(path, cols, {"sensor": "gyro", "ref_unit": "dps", "out_unit": "LSB"})


def _run(*args):
    return subprocess.run([sys.executable, "-m", "tools.simgap", *map(str, args)], cwd=REPO,
                          capture_output=True, text=True, timeout=120)


@pytest.fixture(scope="module")
def hyst_result(tmp_path_factory):
    d = tmp_path_factory.mktemp("gap")
    def eff(t, T, r):
        return 3 * (play(T, 6.0) - T)

    _write(d / "train.csv", make(eff, n=3000, seed=seed("simgap_contract/hyst")))
    _write(d / "held.csv", make(eff, n=2000, seed=seed("simgap_contract/hyst", 1)))
    p = _run(d / "train.csv", "--withheld", d / "held.csv", "--json", d / "out.json",
             "--plot", d / "out.png")
    assert p.returncode == 0, p.stderr
    return json.loads((d / "out.json").read_text()), p.stdout, d


def test_json_contract_fields_and_types(hyst_result):
    res, _, _ = hyst_result
    assert isinstance(res["verdict"], list) and all(v in CATALOGUE for v in res["verdict"])
    assert set(res["noise_floor"]) == {"x", "y", "z"}
    assert set(res["final"]["withheld_rms"]) == {"x", "y", "z"}
    names = [e["name"] for e in res["effects"]]
    assert len(names) == len(set(names)) and set(names) <= set(CATALOGUE)
    for e in res["effects"]:
        assert set(e["axes"]) <= {"x", "y", "z"} and e["axes"]
        assert set(e["axes"]) <= set(e["withheld_rms_before"]) == set(e["withheld_rms_after"])
        assert isinstance(e["shrink"], float) and isinstance(e["significant"], bool)
        assert e["significant"] == (e["name"] in res["verdict"])
    for c in res["where"]:
        assert set(c) >= {"axis", "dimension", "from", "to", "share", "z_eff"}
        assert c["dimension"] in {"temperature", "branch", "input", "time", "run"}
        assert 0 < c["share"] <= 1 and c["excess"] > 0
    zs = [abs(c["z_eff"]) for c in res["where"]]
    assert zs == sorted(zs, reverse=True)
    for c in res["not_identifiable"]:
        assert len(c["effects"]) == 2 and isinstance(c["needs"], str) and c["needs"]


def test_hysteresis_diagnosed_and_shrunk(hyst_result):
    res, out, d = hyst_result
    assert res["verdict"][0] == "hysteresis"
    e = next(e for e in res["effects"] if e["name"] == "hysteresis")
    assert e["axes"] == ["x"]            # only x carries the effect
    before, after = e["withheld_rms_before"]["x"], e["withheld_rms_after"]["x"]
    assert e["shrink"] == pytest.approx(1 - after / before)
    assert res["final"]["withheld_rms"]["x"] < 1.15 * res["noise_floor"]["x"]
    assert "verdict (strongest first): hysteresis" in out
    assert (d / "out.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# Issue 22: when cells were ranked by share, an input cell of about half the rows (mean near 0)
# outranked the branches (mean 7 LSB) at TEMPCOMP_SEED=1, 2, 3, 5, 8, 11, ... (17/50); ranked by
# the cell mean's z, 0 misses over TEMPCOMP_SEED=1-50 (2026-11-28).
def test_where_points_at_the_branches(hyst_result):
    res, _, _ = hyst_result
    top = res["where"][0]
    # A hysteresis offset lives on the heating/cooling branches of axis x.
    assert top["axis"] == "x" and top["dimension"] == "branch"
    assert top["from"] in ("heating", "cooling")


# (Ranked by share, at TEMPCOMP_SEED=18 the 40..100 dps input cell, 1400 rows of mean 0.7 LSB,
# share 0.84, outranked the 31-37 degC band, 352 rows of mean 11 LSB, 0.78: 3/50 seeds missed;
# ranked by the cell mean's z, 0/50 over TEMPCOMP_SEED=1-50.)
def test_where_localises_a_temperature_band(tmp_path):
    from tools.simgap.diagnose import diagnose
    log = make(lambda t, T, r: np.where((T > 31) & (T < 36), 20.0, 0.0), n=3000, seed=seed("simgap_contract/band"))
    res, _ = diagnose(log)
    top = res["where"][0]
    assert (top["axis"], top["dimension"]) == ("x", "temperature")
    assert top["from"] <= 33.5 <= top["to"]
    assert not [c for c in res["where"] if c["axis"] != "x"]   # y, z are at the floor


def _model_json(path, slope):
    axes = {a: {"offset": [50.0, slope, -0.02], "sensitivity": [16.0, 16e-4]} for a in "xyz"}
    path.write_text(json.dumps({"t0_c": 25.0, "axes": axes}))


# None: this run's data. 415318: the run whose data a first version of the lag/loop rule
# (select.Greedy._told_apart, then comparing any confusable pair) failed - hysteresis first.
@pytest.mark.parametrize("run", [None, 415318])
def test_given_model_true_then_wrong(tmp_path, run):
    _write(tmp_path / "t.csv", make(None, n=3000, seed=seed("simgap_contract/given_model", run=run)))
    _model_json(tmp_path / "good.json", 4.0)     # the coefficients simgap_synth.make uses
    p = _run(tmp_path / "t.csv", "--model", tmp_path / "good.json", "--json", tmp_path / "g.json")
    assert p.returncode == 0, p.stderr
    good = json.loads((tmp_path / "g.json").read_text())
    assert good["verdict"] == [] and good["sim"] == "given model"
    _model_json(tmp_path / "bad.json", 4.5)      # offset slope 0.5 LSB/degC off
    p = _run(tmp_path / "t.csv", "--model", tmp_path / "bad.json", "--json", tmp_path / "b.json")
    bad = json.loads((tmp_path / "b.json").read_text())
    assert bad["verdict"][:1] == ["offset_temperature"]


def test_malformed_csv_exit_code_and_message(tmp_path):
    _write(tmp_path / "t.csv", make(None, n=50, seed=seed("simgap_contract/malformed")))
    lines = (tmp_path / "t.csv").read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("time_s")) + 10
    parts = lines[k].split(",")
    parts[2] = "1.2.3"
    lines[k] = ",".join(parts)
    (tmp_path / "t.csv").write_text("\n".join(lines))
    p = _run(tmp_path / "t.csv", "--json", tmp_path / "o.json")
    assert p.returncode == 2
    assert f"line {k + 1}, column 3 (out_x): not a number: '1.2.3'" in p.stderr
    assert not (tmp_path / "o.json").exists()


def test_bad_model_file_is_reported(tmp_path):
    _write(tmp_path / "t.csv", make(None, n=50, seed=seed("simgap_contract/bad_model")))
    (tmp_path / "m.json").write_text('{"axes": {"x": {"offset": [1, 2]}}}')
    p = _run(tmp_path / "t.csv", "--model", tmp_path / "m.json", "--json", tmp_path / "o.json")
    assert p.returncode == 2 and "bad model" in p.stderr
