"""Fleet fitting (tools/fit/fleet.py): many units in one run through the command line.

Simulated units with known coefficients: the per-unit records recover them, the units whose
chamber run was noisy (a loose fixture) are the ones flagged, a directory and a unit-column CSV
give the same fleet, a bad unit stops the run with one line naming its file and line (or is
skipped with --skip-bad), and every subcommand keeps the {"units", "summary"} contract.
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import seeds
from fleet_checks import check_flags
from paths import REPO

from tempcomp import record
from tempcomp.an12760 import AN12760
from tools.fit import __main__ as fitcli
from tools.fit import an12760 as F
from tools.fit import simulate as S
from tools.sim.analog_gyro_sim import AnalogGyroSim

CPG = 16384.0
NOISY = (3, 17)


@pytest.fixture(scope="module")
def fleet_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("fleet")
    tr = S.fleet_files(str(d / "units"), 24, np.random.default_rng(seeds.seed("fleet_units")), samples=20, cpg=CPG, outliers=NOISY)
    return d, tr


def _run(argv, capsys):
    rc = fitcli.main(argv)
    out, err = capsys.readouterr()
    return rc, out, err


def test_directory_fleet_recovers_every_unit_and_flags_the_noisy_ones(fleet_dir, capsys, tmp_path):
    d, tr = fleet_dir
    out = tmp_path / "fleet.json"
    rec = tmp_path / "records.json"
    summ = tmp_path / "summary.csv"
    rc, text, err = _run(["sixpos", str(d / "units"), "--counts-per-g", str(CPG), "--order", "2", "--json", str(out),
                          "--record", str(rec), "--summary", str(summ), "--progress"], capsys)
    assert rc == 0, err
    doc = json.loads(out.read_text())
    assert set(doc) == {"units", "summary"}
    ids = ["unit-%05d" % u for u in range(24)]
    assert list(doc["units"]) == ids
    for u, uid in enumerate(ids):
        res = doc["units"][uid]
        if u in NOISY:
            continue
        # offsets at 25 degC (order 2: the simulated law is quadratic): 20-sample means, 8 counts noise
        got = [ax["offset_mg"] for ax in res["axes"]]
        assert np.allclose(got, tr["off0"][u], atol=1.0), (uid, got, tr["off0"][u])
        # sensitivity from the +-1 g means: sigma = sqrt(2) * 8 / sqrt(20) / (2 * CPG) = 7.7e-5, and 66
        # axes are checked: 5 sigma (2e-4, 2.6 sigma, held for one seed's parts only)
        assert np.allclose([ax["sen_tol"] for ax in res["axes"]], tr["sen_tol"][u], atol=4e-4)
    check_flags(doc["summary"], ["unit-%05d" % u for u in NOISY])
    assert doc["summary"]["units"] == 24 and doc["summary"]["failed"] == {}
    # the records file holds the same records; each builds the device's compensator
    recs = json.loads(rec.read_text())
    assert list(recs) == ids
    for uid in ids:
        assert recs[uid] == doc["units"][uid]["record"]
        AN12760.from_record(recs[uid], CPG)
        assert record.unpack(recs[uid], record.KIND_AN12760)[4] == pytest.approx(
            doc["units"][uid]["axes"][0]["offset_mg"], rel=1e-6)
    rows = summ.read_text().splitlines()
    assert rows[0].startswith("unit,status,residual")
    # the CSV and the text say what the summary flagged (the noisy units, and now and then a good
    # unit for a coefficient in the fleet's tail: check_flags)
    flagged = sorted(doc["summary"]["outliers"])
    assert sorted(r.split(",")[0] for r in rows[1:] if ",outlier," in r) == flagged and len(rows) == 25
    assert "%d outlier(s)" % len(flagged) in text
    assert "100%" in err and "24/24 [" in err and "unit/s]" in err  # the progress bar's (tqdm) last state


def test_unit_column_csv_is_the_same_fleet(fleet_dir, capsys, tmp_path):
    d, _ = fleet_dir
    one = tmp_path / "line.csv"
    lines = ["unit,temp_c,orient,ax,ay,az"]
    for n in sorted(os.listdir(d / "units"))[:8]:
        body = (d / "units" / n).read_text().splitlines()[1:]
        lines += ["%s,%s" % (n[:-4], b) for b in body]
    one.write_text("\n".join(lines) + "\n")
    rc, _, err = _run(["sixpos", str(one), "--counts-per-g", str(CPG), "--json", str(tmp_path / "a.json")], capsys)
    assert rc == 0, err
    a = json.loads((tmp_path / "a.json").read_text())
    sub = tmp_path / "sub"
    sub.mkdir()
    for n in sorted(os.listdir(d / "units"))[:8]:
        (sub / n).write_text((d / "units" / n).read_text())
    rc, _, err = _run(["sixpos", str(sub), "--counts-per-g", str(CPG), "--json", str(tmp_path / "b.json")], capsys)
    assert rc == 0, err
    b = json.loads((tmp_path / "b.json").read_text())
    assert a["units"] == b["units"]


def test_a_bad_unit_stops_the_run_with_one_line_or_is_skipped(fleet_dir, capsys, tmp_path):
    d, _ = fleet_dir
    src = tmp_path / "units"
    src.mkdir()
    for n in sorted(os.listdir(d / "units"))[:6]:
        (src / n).write_text((d / "units" / n).read_text())
    bad = src / "unit-00002.csv"
    rows = bad.read_text().splitlines()
    rows[40] = rows[40].rsplit(",", 1)[0] + ",12x"
    bad.write_text("\n".join(rows) + "\n")
    out = tmp_path / "o.json"
    rc, text, err = _run(["sixpos", str(src), "--counts-per-g", str(CPG), "--json", str(out)], capsys)
    assert rc == 2 and not out.exists()
    assert err.count("\n") == 1 and "unit-00002.csv line 41" in err and "'12x'" in err, err
    rc, text, err = _run(["sixpos", str(src), "--counts-per-g", str(CPG), "--json", str(out), "--skip-bad"], capsys)
    assert rc == 0, err
    doc = json.loads(out.read_text())
    assert "unit-00002" not in doc["units"] and len(doc["units"]) == 5
    assert "unit-00002" in doc["summary"]["failed"]
    assert "FAILED  unit-00002" in text


def _an12760_rows(u, rng):
    rows = []
    off, tco, sen, tcs = rng.normal(0, 30), rng.normal(0, 0.3), rng.normal(0, 0.02), rng.normal(0, 2e-4)
    for t in (-40.0, 25.0, 85.0):
        for g in (-1.0, 1.0):
            for _ in range(4):
                y = F.simulate_mg(t, g, off, tco, sen, tcs) + rng.normal(0, 0.5)
                rows.append("%g,%g,%.4f" % (t, g, y))
    return "temp_c,ref_g,out_mg", rows


def _adxrs_rows(u, rng):
    sim = AnalogGyroSim(vref_mv=3300, divider=2.0, noise_mv=0.5, t_noise_mv=0.3, seed=seeds.seed("fleet_adxrs", u))
    q = 3300.0 * 2.0 / 65535
    rows = []
    for t in (-40.0, 25.0, 85.0):
        sim.temp_c = t
        for r in (0.0, 200.0, -200.0):
            sim.rate_dps = r
            for _ in range(4):
                rows.append("%g,%.2f,%g,%.2f" % (t, sim.temp.read_u16() * q, r, sim.rate.read_u16() * q))
    return "temp_c,vt_mv,rate_dps,out_mv", rows


def _sixpos_rows(u, rng):
    raw = S.chamber(S.truth(1, rng), [-40.0, 25.0, 85.0], S.SIX, 3, CPG, rng)
    labels = ["+x", "-x", "+y", "-y", "+z", "-z"]
    rows = ["%g,%s,%d,%d,%d" % ((t, labels[o]) + tuple(int(v) for v in raw[0, k, o, s]))
            for k, t in enumerate((-40.0, 25.0, 85.0)) for o in range(6) for s in range(3)]
    return "temp_c,orient,ax,ay,az", rows


@pytest.mark.parametrize("cmd,make,extra", [
    ("an12760", _an12760_rows, []),
    ("adxrs", _adxrs_rows, []),
    ("sixpos", _sixpos_rows, ["--counts-per-g", str(CPG)]),
])
def test_every_subcommand_keeps_the_fleet_contract(cmd, make, extra, capsys, tmp_path):
    """--json of a unit-column CSV is {"units": {id: the one-unit fit's fields}, "summary": {...}}."""
    rng = np.random.default_rng(seeds.seed("fleet_11"))
    lines = None
    per_unit = {}
    for u in range(6):
        head, rows = make(u, rng)
        uid = "SN%03d" % (100 + u)
        per_unit[uid] = (head, rows)
        lines = lines or ["unit," + head]
        lines += ["%s,%s" % (uid, r) for r in rows]
    fleet_csv = tmp_path / "fleet.csv"
    fleet_csv.write_text("\n".join(lines) + "\n")
    rc, _, err = _run([cmd, str(fleet_csv), "--json", str(tmp_path / "f.json")] + extra, capsys)
    assert rc == 0, err
    doc = json.loads((tmp_path / "f.json").read_text())
    assert set(doc) == {"units", "summary"} and list(doc["units"]) == list(per_unit)
    assert doc["summary"]["fit"] == cmd and len(doc["summary"]["table"]) == 6
    for uid, (head, rows) in list(per_unit.items())[:2]:
        one = tmp_path / (uid + ".csv")
        one.write_text(head + "\n" + "\n".join(rows) + "\n")
        rc, _, err = _run([cmd, str(one), "--json", str(tmp_path / "one.json")] + extra, capsys)
        assert rc == 0, err
        assert doc["units"][uid] == json.loads((tmp_path / "one.json").read_text())


def test_the_command_line_itself(fleet_dir, tmp_path):
    d, _ = fleet_dir
    out = tmp_path / "f.json"
    p = subprocess.run([sys.executable, "-m", "tools", "fit", "sixpos", str(d / "units"), "--counts-per-g",
                        str(CPG), "--json", str(out), "--progress"], cwd=REPO, capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    assert "24 unit(s) fitted" in p.stdout and "| 24/24 [" in p.stderr  # tqdm, into a pipe
    assert len(json.loads(out.read_text())["units"]) == 24
