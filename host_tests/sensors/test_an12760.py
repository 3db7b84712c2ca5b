"""NXP AN12760: Table 10 in float and in the fixed-point device path, the fit, the CLI, bad input."""

import json
import subprocess
import sys

import numpy as np
import pytest
import seeds
from paths import REPO

from tempcomp import record
from tempcomp.an12760 import AN12760, decode_record
from tempcomp.fixedpoint import EXTRAPOLATE
from tools.fit import an12760 as F

# AN12760 Rev. 1, Table 10 (Temp, Tilt, RawAcc, AccTCO, AccTCOTCS), injected errors of Table 9
TABLE10 = [
    (-40, -90, -1178.1, -1093.1, -1000.0),
    (-40, 0, -85.0, 0.0, 0.0),
    (-40, 90, 1008.1, 1093.1, 1000.0),
    (25, -90, -1046.4, -1026.4, -1000.0),
    (25, 0, -20.0, 0.0, 0.0),
    (25, 90, 1006.4, 1026.4, 1000.0),
    (105, -90, -884.3, -944.3, -1000.0),
    (105, 0, 60.0, 0.0, 0.0),
    (105, 90, 1004.3, 944.3, 1000.0),
]
TABLE9 = dict(offset_mg=-20.0, tco=1.0, sen_tol=0.0264, tcs=-0.001)  # TCS -0.100 %/degC
T = np.array([r[0] for r in TABLE10], float)
G = np.sin(np.radians([r[1] for r in TABLE10]))  # tilt angle -> input in g
COL = {name: np.array([r[i] for r in TABLE10]) for i, name in ((2, "raw"), (3, "tco"), (4, "tcotcs"))}
CPG = 16384  # counts per g of the device-path test (16-bit, +-2 g): 0.061 mg per count


def test_table10_float_host():
    raw = F.simulate_mg(T, G, **TABLE9)
    assert np.all(np.abs(raw - COL["raw"]) <= 0.05)  # the table's 0.1 mg rounding
    acc = F.acc_tco(raw, T, TABLE9["offset_mg"], TABLE9["tco"])
    assert np.all(np.abs(acc - COL["tco"]) <= 0.05)
    out = F.correct_mg(raw, T, **TABLE9)
    assert np.array_equal(np.round(out, 1), COL["tcotcs"])
    assert np.max(np.abs(out - COL["tcotcs"])) < 1e-9


def _device(sen_tol, tcs, off=-20.0, tco=1.0, **kw):
    return AN12760([(off, (tco,), sen_tol, (tcs,))], CPG, (-40, 105), out_per_g=10000, **kw)


@pytest.mark.parametrize("mapping", [dict(), dict(t_scale=1 / 333.87, t_offset=21.0), dict(t_scale=0.01)])
def test_table10_fixed_point_device(mapping):
    """0.1 mg output units; raw counts simulated from Table 9; temperature as the part's code."""
    raw_counts = [int(round(v * CPG / 1000.0)) for v in F.simulate_mg(T, G, **TABLE9)]
    dev_raw = _device(0.0, 0.0, off=0.0, tco=0.0, **mapping)
    dev_tco = _device(0.0, 0.0, **mapping)
    dev = _device(0.0264, -0.001, **mapping)
    for i, (temp, _tilt, raw, acctco, out) in enumerate(TABLE10):
        code = dev.code_of(temp)
        for d in (dev_raw, dev_tco, dev):
            d.update(code)
        assert abs(dev_raw.apply(raw_counts[i]) - raw * 10) <= 1  # RawAcc to 0.1 mg
        assert abs(dev_tco.apply(raw_counts[i]) - acctco * 10) <= 1  # AccTCO to 0.1 mg
        assert dev.apply(raw_counts[i]) == int(out * 10)  # exactly -1000.0 / 0.0 / +1000.0 mg


def test_fit_table10_recovers_table9():
    res = F.fit(T, G, COL["raw"])
    assert round(res["offset_mg"], 1) == -20.0
    assert round(res["tco_mg_per_c"], 2) == 1.00
    assert round(res["sen_tol"] * 100, 2) == 2.64
    assert round(res["tcs_per_c"] * 100, 3) == -0.100
    assert res["t_room_c"] == 25.0 and res["warnings"] == []


def _write(path, rows, header="temp_c,ref_g,out_mg"):
    with open(path, "w") as f:
        f.write(header + "\n")
        for r in rows:
            f.write(",".join(str(v) for v in r) + "\n")


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "tools.fit", *args], cwd=REPO, capture_output=True, text=True)


def test_cli_table10(tmp_path):
    csv = tmp_path / "t10.csv"
    _write(csv, [(t, round(g, 6), r) for t, g, r in zip(T, G, COL["raw"])])
    out = tmp_path / "out.json"
    p = _cli("an12760", str(csv), "--json", str(out))
    assert p.returncode == 0, p.stderr
    res = json.loads(out.read_text())
    assert round(res["offset_mg"], 1) == -20.0 and round(res["tco_mg_per_c"], 2) == 1.0
    assert round(res["sen_tol"], 4) == 0.0264 and round(res["tcs_per_c"], 5) == -0.001
    assert res["t_room_c"] == 25 and "tco" not in res
    # the record loads on the device and corrects the table's raw values
    axes, t_room, span = decode_record(res["record"])
    assert t_room == 25.0 and span == (-40.0, 105.0)
    dev = AN12760.from_record(res["record"], CPG, out_per_g=1000)
    for temp, _tilt, raw, _a, want in TABLE10:
        dev.update(dev.code_of(temp))
        assert abs(dev.apply(int(round(raw * CPG / 1000))) - want) <= 1


def test_cli_order3_t_room(tmp_path):
    temps = [-40, -10, 25, 60, 105]
    tco, tcs = [0.8, 0.004, -2e-5], [-5e-4, 3e-6, 1e-8]
    rows = [(t, g, F.simulate_mg(t, g, 12.0, tco, 0.01, tcs, t_room=20.0)) for t in temps for g in (-1, 0, 1)]
    csv = tmp_path / "c.csv"
    _write(csv, rows)
    out = tmp_path / "o.json"
    p = _cli("an12760", str(csv), "--json", str(out), "--order", "3", "--t-room", "20")
    assert p.returncode == 0, p.stderr
    res = json.loads(out.read_text())
    assert res["t_room_c"] == 20.0
    assert np.allclose(res["tco"], tco, rtol=1e-6, atol=1e-12) and np.allclose(res["tcs"], tcs, rtol=1e-5, atol=1e-14)
    assert abs(res["offset_mg"] - 12.0) < 1e-8 and abs(res["sen_tol"] - 0.01) < 1e-10
    assert res["tco_mg_per_c"] == res["tco"][0] and res["tcs_per_c"] == res["tcs"][0]
    # cubic compensation on the device: every point back to its input within 1 mg
    dev = AN12760.from_record(res["record"], CPG, t_scale=1 / 340, t_offset=36.53)
    for t, g, y in rows:
        dev.update(dev.code_of(t))
        assert abs(dev.apply(int(round(y * CPG / 1000))) - 1000 * g) <= 1


@pytest.mark.parametrize("rows,args,msg", [
    ([(25, -1, -1000), (25, 1, 1000), (25, 0, 0)], [], "only one temperature"),
    ([(-40, -1, -1000), (-40, 1, 1000), (25, -1, -999), (25, 1, 1001), (85, -1, -998), (85, 1, 1002)],
     ["--order", "3"], "needs at least 4 temperatures"),
    ([(-40, -1, -1000), (-40, 1, 1000), (25, -1, -999), (25, 1, "nan"), (85, -1, -998), (85, 1, 1002)], [],
     "line 5: column out_mg is nan"),
    ([(-40, -1, -1000), (-40, 1, 1000), (25, 1, 1001), (85, -1, -998), (85, 1, 1002)], [], "missing orientation"),
    ([(-40, 0, 1), (-40, 0, 2), (25, 0, 1), (85, 0, 1)], [], "missing orientation"),
    ([(-40, -1, -1000), (-40, 1, 1000), (25, -1, -999), (25, 1, 2000), (85, -1, -998), (85, 1, 1002)],
     ["--full-scale-mg", "2000"], "saturated axis: line 5"),
    ([(25, -1, -1000), (25, 1, 1000), (-40, -1, -999), (-40, 1, 1001), (85, -1, -998), (85, 1, 1002)], [],
     "not sorted"),
    ([(-40, -1, -1000), (-40, 1, 1000), (25, -1, -999), (25, 1, 1001), (-40, -1, -998), (-40, 1, 1002)], [],
     "duplicate temperature"),
])
def test_cli_bad_input(tmp_path, rows, args, msg):
    csv = tmp_path / "bad.csv"
    _write(csv, rows)
    p = _cli("an12760", str(csv), "--json", str(tmp_path / "o.json"), *args)
    assert p.returncode == 2 and msg in p.stderr, p.stderr
    assert not (tmp_path / "o.json").exists()


def test_bad_csv_header(tmp_path):
    csv = tmp_path / "h.csv"
    _write(csv, [(1, 2, 3)], header="temp,ref_g,out_mg")
    p = _cli("an12760", str(csv), "--json", str(tmp_path / "o.json"))
    assert p.returncode == 2 and "missing column(s) temp_c" in p.stderr


def test_warnings_close_temperatures():
    t = np.repeat([20.0, 23.0, 30.0], 2)
    g = np.tile([-1.0, 1.0], 3)
    res = F.fit(t, g, F.simulate_mg(t, g, 0, 1, 0, 0))
    assert any("apart" in w for w in res["warnings"]) and any("span only" in w for w in res["warnings"])


def test_fixed_point_worst_error_vs_float():
    """Whole raw range x whole calibrated temperature range, cubic laws: worst error in LSB."""
    rng = np.random.default_rng(seeds.seed("an12760"))
    axes = [(35.0, (1.2, -0.004, 3e-5), 0.03, (-6e-4, 2e-6, -1e-8)),
            (-50.0, (-0.7, 0.002, 0.0), -0.02, (4e-4, 0.0, 0.0))]
    dev = AN12760(axes, 4096, (-40, 105), t_scale=1 / 340, t_offset=36.53, out_per_g=10000,
                  policy=EXTRAPOLATE, t_in_c=(-60, 125))
    worst = 0.0
    lo, hi = dev.comp.t_in
    for code in list(rng.integers(lo, hi + 1, 150)) + [lo, hi]:
        dev.update(int(code))
        temp = code / 340 + 36.53
        for k, (off, tco, sen, tcs) in enumerate(axes):
            raws = np.concatenate([rng.integers(-32768, 32768, 40), [-32768, 32767, 0]])
            ref = F.correct_mg(raws * 1000 / 4096, temp, off, tco, sen, tcs) * 10
            got = np.array([dev.apply(int(r), k) for r in raws])
            worst = max(worst, float(np.max(np.abs(got - ref))))
    print("AN12760 worst error %.4f LSB" % worst)
    assert worst <= 0.5625, worst  # final rounding 0.5 + the core's truncation bound 1/16


def test_record_roundtrip_and_corruption():
    dev = _device(0.0264, -0.001)
    ints = dev.to_record()
    assert all(isinstance(v, int) and abs(v) < 2**30 for v in ints)
    axes, t_room, span = decode_record(ints)
    assert axes[0][0] == -20.0 and axes[0][2] == pytest.approx(0.0264, rel=1e-7)
    with pytest.raises(ValueError, match="kind"):
        decode_record([record.KIND_ADXRS] + ints[1:])
    with pytest.raises(ValueError, match="length"):
        decode_record(ints[:-1])
    with pytest.raises(ValueError, match="corrupt"):
        decode_record(ints[:5] + [1 << 24] + ints[6:])


def test_bad_device_arguments():
    with pytest.raises(ValueError, match="sen_tol"):
        AN12760([(0, 0, -1.0, 0)], 1024, (-40, 85))
    with pytest.raises(ValueError, match="at most 3rd order"):
        AN12760([(0, (1, 2, 3, 4), 0, 0)], 1024, (-40, 85))
    with pytest.raises(ValueError, match="t_span_c"):
        AN12760([(0, 0, 0, 0)], 1024, (85, -40))
