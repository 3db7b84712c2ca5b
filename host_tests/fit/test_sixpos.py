"""Six-position / ellipsoid multi-temperature fits: recovery within statistical error, CSV -> device."""

import csv
import json
import subprocess
import sys

import numpy as np
import pytest
from paths import REPO

from tempcomp.an12760 import AN12760
from tempcomp.crossaxis import CrossAxis
from tools.fit import simulate as S
from tools.fit import sixpos as P
from tools.fit.common import FitError

CPG = 8192.0  # +-4 g
TEMPS = np.array([-40.0, 25.0, 85.0])


def _z(est, true, se):
    z = ((est - true) / se).ravel()
    return z.mean(), z.std()


def test_sixpos_recovers_truth_within_statistical_error():
    rng = np.random.default_rng(21)
    U = 400
    tr = S.truth(U, rng)
    raw = S.chamber(tr, TEMPS, S.SIX, 50, CPG, rng, noise_counts=6.0)
    mean, se = P.reduce_samples(raw)
    out, warnings = P.fit_means(mean, TEMPS, CPG, S.SIX, se, order=2)
    assert any("passes through every point" in w for w in warnings)
    # z-scores of estimate - truth over 1200 axes: unbiased (|mean| small), std ~ 1 when the
    # reported standard errors are right
    for est, true, se_ in [
        (out["law_offset_mg"][:, 0, :], tr["off0"], out["se_law_offset_mg"][:, 0, :]),
        (out["tco"][:, 0, :], tr["tco1"], out["se_law_offset_mg"][:, 1, :]),
        (out["tco"][:, 1, :], tr["tco2"], out["se_law_offset_mg"][:, 2, :]),
        (out["sen_tol"], tr["sen_tol"], out["se_law_scale_rel"][:, 0, :]),
    ]:
        m, s = _z(est, true, se_)
        assert abs(m) < 0.12 and 0.85 < s < 1.15, (m, s)
    # cross-axis terms (symmetric + rotation) at every temperature, within 5 sigma
    se_N = out["se_cross"]
    for i, j in [(0, 1), (0, 2), (1, 2), (2, 0)]:
        d = out["cross"][:, :, i, j] - tr["N"][:, None, i, j]
        assert np.all(np.abs(d) < 5 * se_N[:, :, i, j])
        m, s = _z(out["cross"][:, :, i, j], tr["N"][:, None, i, j], se_N[:, :, i, j])
        assert abs(m) < 0.12 and 0.8 < s < 1.2
    # misalignment: the antisymmetric part is the simulated rotation
    assert np.max(np.abs(out["misalign_rad"] - tr["rot"][:, None, :])) < 5 * np.max(se_N)
    # residuals per axis and temperature near the noise of a 50-sample mean (mg)
    assert np.all(out["rms_mg"] < 5 * 6.0 / np.sqrt(50) / CPG * 1000)


def test_ellipsoid_twelve_unknown_orientations():
    rng = np.random.default_rng(8)
    U = 50
    tr = S.truth(U, rng, rot=0.0)  # a rotation is not observable without known orientations
    dirs = rng.normal(size=(12, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    raw = S.chamber(tr, TEMPS, dirs, 30, CPG, rng, noise_counts=3.0)
    mean, _ = P.reduce_samples(raw)
    out, _ = P.fit_means(mean, TEMPS, CPG, None, order=2, ellipsoid=True)
    assert out["misalign_rad"] is None
    assert np.max(np.abs(out["law_offset_mg"][:, 0, :] - tr["off0"])) < 1.0  # mg
    assert np.max(np.abs(out["sen_tol"] - tr["sen_tol"])) < 5e-4
    assert np.max(np.abs(out["cross"][:, 1] - tr["N"])) < 1e-3


def _csv(path, raw, dirs_labels, temps, drop=None):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["temp_c", "orient", "ax", "ay", "az"])
        for k, t in enumerate(temps):
            for o, lab in enumerate(dirs_labels):
                if drop == (k, lab):
                    continue
                for s in raw[0, k, o]:
                    w.writerow([t, lab] + [int(v) for v in s])


LAB = ["+x", "-x", "+y", "-y", "+z", "-z"]


def test_cli_csv_to_device(tmp_path):
    rng = np.random.default_rng(5)
    tr = S.truth(1, rng, cross=0.008, rot=0.005)
    raw = S.chamber(tr, TEMPS, S.SIX, 20, CPG, rng, noise_counts=4.0)
    path = tmp_path / "acc.csv"
    _csv(path, raw, LAB, TEMPS)
    out = tmp_path / "acc.json"
    p = subprocess.run([sys.executable, "-m", "tools.fit", "sixpos", str(path), "--json", str(out),
                        "--counts-per-g", "8192", "--order", "2"], cwd=REPO, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    res = json.loads(out.read_text())
    assert len(res["temperatures"]) == 3 and res["misalignment_observable"]
    assert len(res["temperatures"][0]["residual_rms_mg"]) == 3
    acc = AN12760.from_record(res["record"], CPG, out_per_g=1000)
    ca = CrossAxis.from_record(res["cross_record"])
    # the device, from the two records, turns a fresh noise-free reading back into g (mg)
    for t in (-40.0, 0.0, 60.0, 85.0):
        clean = S.chamber(tr, [t], S.SIX, 1, CPG, rng, noise_counts=0.0)[0, 0, :, 0, :]
        acc.update(acc.code_of(t))
        for o in range(6):
            v = [0, 0, 0]
            acc.apply_all([int(x) for x in clean[o]], v)
            ca.apply(v, v)
            assert np.max(np.abs(np.array(v) - 1000 * S.SIX[o])) <= 2.5, (t, o, v)


@pytest.mark.parametrize("case,msg", [
    ("missing", "missing orientation: 85.00 degC has no rows for orientation '-z'"),
    ("one_temp", "only one temperature"),
    ("nan", "column ay is nan"),
    ("saturated", "saturated axis"),
    ("unsorted", "not sorted"),
    ("duplicate", "duplicate temperature"),
    ("label", "orientation 'up'"),
])
def test_cli_bad_input(tmp_path, case, msg):
    rng = np.random.default_rng(1)
    tr = S.truth(1, rng)
    temps = TEMPS
    raw = S.chamber(tr, TEMPS, S.SIX, 3, CPG, rng)
    labels = list(LAB)
    drop = None
    if case == "missing":
        drop = (2, "-z")
    elif case == "one_temp":
        temps = np.array([25.0, 25.0, 25.0])
    elif case == "unsorted":
        temps = np.array([25.0, -40.0, 85.0])
    elif case == "duplicate":
        temps = np.array([-40.0, 25.0, -40.0])
    elif case == "saturated":
        raw[0, 1, 2, 1, 0] = 32767
    elif case == "label":
        labels[4] = "up"
    path = tmp_path / "bad.csv"
    _csv(path, raw, labels, temps, drop)
    if case == "nan":
        lines = path.read_text().splitlines()
        parts = lines[7].split(",")
        parts[3] = "nan"
        lines[7] = ",".join(parts)
        path.write_text("\n".join(lines) + "\n")
    p = subprocess.run([sys.executable, "-m", "tools.fit", "sixpos", str(path), "--json", str(tmp_path / "o.json"),
                        "--counts-per-g", "8192"], cwd=REPO, capture_output=True, text=True)
    assert p.returncode == 2 and msg in p.stderr, p.stderr


def test_batch_bad_input():
    rng = np.random.default_rng(2)
    tr = S.truth(3, rng)
    raw = S.chamber(tr, TEMPS, S.SIX, 4, CPG, rng)
    with pytest.raises(FitError, match="saturated axis: unit 1"):
        r = raw.copy()
        r[1, 0, 0, 0, 2] = -32768
        P.reduce_samples(r)
    with pytest.raises(FitError, match="NaN/inf in the data: unit 2"):
        r = raw.astype(float)
        r[2, 1, 3, 0, 1] = np.nan
        P.reduce_samples(r)
    mean, se = P.reduce_samples(raw)
    with pytest.raises(FitError, match="missing orientation"):
        P.fit_means(mean[:, :, :5], TEMPS, CPG, S.SIX[:5], None)
    with pytest.raises(FitError, match="missing orientation"):
        P.fit_means(mean[:, :, [0, 1, 2, 4]], TEMPS, CPG, S.SIX[[0, 1, 2, 4]], None)
    with pytest.raises(FitError, match="not sorted: unit 0"):
        P.fit_means(mean, TEMPS[::-1].copy(), CPG, S.SIX, se)
    with pytest.raises(FitError, match="duplicate temperature"):
        P.fit_means(mean, np.array([-40.0, 25.0, 25.2]), CPG, S.SIX, se)
    with pytest.raises(FitError, match="only one temperature"):
        P.fit_means(mean[:, :1], TEMPS[:1], CPG, S.SIX, se[:, :1])
    with pytest.raises(FitError, match="order 3 temperature law needs at least 4"):
        P.fit_means(mean, TEMPS, CPG, S.SIX, se, order=3)
    with pytest.raises(FitError, match="at least 9 orientations"):
        P.fit_means(mean, TEMPS, CPG, None, ellipsoid=True)


def test_cross_axis_fixed_point_vs_float():
    rng = np.random.default_rng(9)
    worst = 0.0
    for _ in range(100):
        E = rng.uniform(-0.06, 0.06, (3, 3))
        ca = CrossAxis(E)
        for v in list(rng.integers(-(2**18) + 1, 2**18, (30, 3))) + [np.array([2**18 - 1, -(2**18) + 1, 2**18 - 1])]:
            out = [0, 0, 0]
            ca.apply([int(x) for x in v], out)
            worst = max(worst, float(np.max(np.abs(np.array(out) - (v + E @ v)))))
    print("cross-axis worst error %.4f LSB" % worst)
    assert worst < 0.9
    with pytest.raises(ValueError, match="outside"):
        CrossAxis([[0, 0.07, 0], [0, 0, 0], [0, 0, 0]])
