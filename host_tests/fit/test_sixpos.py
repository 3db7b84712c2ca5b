"""Six-position / ellipsoid multi-temperature fits: recovery within statistical error, CSV -> device."""

import csv
import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest
import seeds
from paths import REPO
from scipy import stats

from tempcomp import record
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
    rng = np.random.default_rng(seeds.seed("sixpos", 21))
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
    # cross-axis terms (symmetric + rotation) at every temperature, each within the normal
    # deviate that all 4 x 1200 of them stay under with probability 1 - 1e-6 (Bonferroni): a flat
    # 5 sigma over 4,800 estimates fails a correct fit in about 0.3 % of runs (max |z| 5.02 at
    # TEMPCOMP_SEED=915289, a CI run; median max 3.86 over seeds 1-200)
    se_N = out["se_cross"]
    pairs = [(0, 1), (0, 2), (1, 2), (2, 0)]
    z_all = stats.norm.isf(1e-6 / (2 * len(pairs) * se_N[:, :, 0, 1].size))
    for i, j in pairs:
        d = out["cross"][:, :, i, j] - tr["N"][:, None, i, j]
        assert np.all(np.abs(d) < z_all * se_N[:, :, i, j])
        m, s = _z(out["cross"][:, :, i, j], tr["N"][:, None, i, j], se_N[:, :, i, j])
        assert abs(m) < 0.12 and 0.8 < s < 1.2
    # misalignment: the antisymmetric part is the simulated rotation
    assert np.max(np.abs(out["misalign_rad"] - tr["rot"][:, None, :])) < 5 * np.max(se_N)
    # residuals per axis and temperature near the noise of a 50-sample mean (mg)
    assert np.all(out["rms_mg"] < 5 * 6.0 / np.sqrt(50) / CPG * 1000)


def _observable(tr):
    """What an ellipsoid can see at Troom: sen_tol and cross-axis terms of the symmetric polar
    factor of the true M = diag(1 + sen_tol)(I + N) (M = M_sym R: R is not observable)."""
    M = (1 + tr["sen_tol"])[:, :, None] * (np.eye(3) + tr["N"])
    w, V = np.linalg.eigh(M @ np.swapaxes(M, 1, 2))
    Ms = np.einsum("uab,ub,ucb->uac", V, np.sqrt(w), V)
    s = np.einsum("uaa->ua", Ms)
    return s - 1, Ms / s[:, :, None] - np.eye(3)


def _ellipsoid_case(seed, dirs=None, noise=3.0, extra=()):
    rng = np.random.default_rng(seed)
    tr = S.truth(50, rng, rot=0.0)
    if dirs is None:
        dirs = rng.normal(size=(12, 3))
    dirs = np.vstack([dirs] + [list(extra)] if len(extra) else [dirs])
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    raw = S.chamber(tr, TEMPS, dirs, 30, CPG, rng, noise_counts=noise)
    mean, _ = P.reduce_samples(raw)
    out, warnings = P.fit_means(mean, TEMPS, CPG, None, order=2, ellipsoid=True)
    sen, cross = _observable(tr)
    errs = (np.max(np.abs(out["law_offset_mg"][:, 0, :] - tr["off0"])), np.max(np.abs(out["sen_tol"] - sen)),
            np.max(np.abs(out["cross"][:, 1] - cross)))
    return out, warnings, errs, dirs


def _within_bounds(errs):
    # 50 units: offset within 1 mg, sensitivity within 5e-4, cross-axis terms within 1e-3
    return errs[0] < 1.0 and errs[1] < 5e-4 and errs[2] < 1e-3


def _adi_nxp_counts():
    """The counts docs/adi_nxp.md states for 120 random sets of 12 at 3 counts of noise."""
    text = " ".join(open(os.path.join(REPO, "docs", "adi_nxp.md"), encoding="utf-8").read().split())
    m = re.search(r"Over (\d+) random sets of 12 at 3 counts of noise, (\d+) were not flagged and all of those met "
                  r"the test's bounds .*?; of the (\d+) flagged \((\d+) with a warning, (\d+) refused\), (\d+) missed "
                  r"them \((\d+) of the warned, (\d+) of the refused", text)
    assert m, "docs/adi_nxp.md no longer states the counts in the form this test reads"
    keys = ("sets", "passed", "flagged", "warned", "refused", "missed", "missed_warned", "missed_refused")
    return dict(zip(keys, (int(g) for g in m.groups())))


@pytest.mark.parametrize("noise", [3.0, 0.0])
def test_ellipsoid_random_orientations_pass_or_are_flagged(noise, monkeypatch):
    """12 random orientations per seed, 120 seeds: a fit that is not flagged meets the bounds;
    one that misses them was warned about (naming orientations to add) or refused. A refused set
    is fitted again with the refusal lifted, to count whether it would have missed (the counts
    docs/adi_nxp.md gives are these, at 3 counts of noise)."""
    got = dict(sets=120, passed=0, flagged=0, warned=0, refused=0, missed=0, missed_warned=0, missed_refused=0)
    for seed in range(120):
        try:
            out, warnings, errs, _ = _ellipsoid_case(seed, noise=noise)
        except FitError as e:
            assert "ellipsoid fit refused: orientation coverage" in str(e) and "up" in str(e)
            with monkeypatch.context() as m:
                m.setattr(P, "COVERAGE_REFUSE", float("inf"))
                _, _, errs, _ = _ellipsoid_case(seed, noise=noise)
            got["refused"] += 1
            got["missed_refused"] += not _within_bounds(errs)
            continue
        assert out["misalign_rad"] is None
        cov = [w for w in warnings if w.startswith("orientation coverage")]
        if cov:
            assert "add orientations with" in cov[0], cov
            got["warned"] += 1
            got["missed_warned"] += not _within_bounds(errs)
        else:
            assert _within_bounds(errs), (seed, errs)
            got["passed"] += 1
    got["flagged"] = got["warned"] + got["refused"]
    got["missed"] = got["missed_warned"] + got["missed_refused"]
    print("noise %.0f: %s" % (noise, got))
    # not a blanket warning: about two in five random sets of 12 are good enough (random
    # attitudes do crowd one side)
    assert got["passed"] >= 40 and got["flagged"] >= 10
    if noise == 3.0:
        assert got == _adi_nxp_counts()


def _refused_seed(name):
    """A seed of this run whose 12 random orientations (_ellipsoid_case's) crowd one side of the sphere
    enough that the check refuses them (amplification above COVERAGE_REFUSE, with a margin so the
    directions the fit finds from noisy data are above it too). About 1 random set in 25 is (40 of
    seeds 0..986), so 600 draws all miss with probability about 2e-11. Over 200 such sets (seeds
    0..~5000) every one was refused and met the bounds with the orientations its refusal named."""
    for s in seeds.seeds(name, 600):
        rng = np.random.default_rng(s)
        S.truth(50, rng, rot=0.0)
        dirs = rng.normal(size=(12, 3))
        if P.amplification(dirs / np.linalg.norm(dirs, axis=1, keepdims=True)).max() > 1.25 * P.COVERAGE_REFUSE:
            return s
    raise AssertionError("no refused set in 600 random sets of 12: the generator changed")


def test_ellipsoid_suggested_orientations_fix_the_fit():
    # a set of random orientations crowding one hemisphere (refused: such sets miss the bounds,
    # 22 of 22 in sixpos.py's count), then the same set with the orientations the refusal names
    seed = _refused_seed("sixpos/refused")
    with pytest.raises(FitError) as e:
        _ellipsoid_case(seed)
    msg = str(e.value)
    labels = msg.split("add orientations with ")[1].split(" up")[0].split(", ")
    assert 1 <= len(labels) <= 6
    extra = []
    for lab in labels:
        v = np.zeros(3)
        for sign, ax in zip(lab[::2], lab[1::2]):
            v["xyz".index(ax)] = 1.0 if sign == "+" else -1.0
        extra.append(v)
    # the same 12 random orientations plus the suggested ones: no warning, within the bounds
    rng = np.random.default_rng(seed)
    S.truth(50, rng, rot=0.0)
    dirs = rng.normal(size=(12, 3))
    _, warnings, errs, _ = _ellipsoid_case(seed, dirs=dirs, extra=extra)
    assert not [w for w in warnings if w.startswith("orientation coverage")], warnings
    # the fix leaves the set accepted (amplification <= COVERAGE_WARN), not evenly spread: at
    # scale amplification 1.92 (seed 4270 of _ellipsoid_case, +x+z, +x, -x added) the noise part
    # of the sensitivity error measured sd 1.7e-4 (3 counts over 30 samples, 8192 counts/g) on a
    # noise-free floor of 2.0e-4, so the worst of 150 estimates may reach floor + 3 sd = 7.5e-4;
    # _within_bounds' 5e-4 is what most sets meet (400 refused sets fixed: worst 5.05e-4 at 4270,
    # the only one above 5e-4; 99th percentile 4.3e-4)
    assert errs[0] < 1.0 and errs[1] < 7.5e-4 and errs[2] < 1e-3, (seed, errs)


def test_ellipsoid_amplification_reference_values():
    # evenly spread: the 12 icosahedron vertices (offset 0.5 = sqrt(3/12), by symmetry J^T J's
    # offset block is 12/3 I); the six faces: the quadric's cross terms are unobservable
    phi = (1 + 5 ** 0.5) / 2
    ico = np.array([[0, a, b * phi] for a in (1, -1) for b in (1, -1)] + [[a, b * phi, 0] for a in (1, -1) for b in (1, -1)]
                   + [[a * phi, 0, b] for a in (1, -1) for b in (1, -1)], float)
    ico /= np.linalg.norm(ico, axis=1, keepdims=True)
    amp = P.amplification(ico)
    assert np.allclose(amp[:3], 0.5)
    assert amp.max() < 0.75
    assert np.isinf(P.amplification(S.SIX)).all()


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
    rng = np.random.default_rng(seeds.seed("sixpos", 5))
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
    rng = np.random.default_rng(seeds.seed("sixpos", 1))
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
    rng = np.random.default_rng(seeds.seed("sixpos", 2))
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
    rng = np.random.default_rng(seeds.seed("sixpos", 9))
    worst = 0.0
    for _ in range(100):
        E = rng.uniform(-0.06, 0.06, (3, 3))
        ca = CrossAxis(E)
        for v in list(rng.integers(-(2**18) + 1, 2**18, (30, 3))) + [np.array([2**18 - 1, -(2**18) + 1, 2**18 - 1])]:
            out = [0, 0, 0]
            ca.apply([int(x) for x in v], out)
            err = float(np.max(np.abs(np.array(out) - (v + E @ v))))
            worst = max(worst, err)
            # 0.5 rounding + sum |v| x 0.5 unit of 2**-22 (docs/adi_nxp.md, tempcomp/crossaxis.py)
            assert err <= 0.5 + float(np.sum(np.abs(v))) * 2.0**-23, (v, err)
    print("cross-axis worst error %.4f LSB" % worst)
    with pytest.raises(ValueError, match="outside"):
        CrossAxis([[0, 0.07, 0], [0, 0, 0], [0, 0, 0]])


# MPU-6500 temperature code (PS-MPU-9250A-01 3.4.2: 333.87 LSB/degC, 0 at 21 degC)
T_SCALE = 1 / 333.87
T_OFFSET = 21.0


def _drift_unit(seed, drift=1e-4):
    rng = np.random.default_rng(seed)
    tr = S.truth(1, rng, cross=0.008, rot=0.005)
    # every cross-axis term drifts by +-1e-4 per degC (signs vary): 6.5e-3 at 65 degC from Troom
    sign = np.sign(rng.normal(size=(3, 3)))
    D = np.triu(sign, 1) * drift
    tr["N1"] = (D + D.T)[None]
    return tr, rng


def _device_error_mg(acc, ca, tr, rng, temps, dirs):
    """Worst |device output - true g| (mg) over temps and orientations, noise-free readings."""
    worst = []
    for t in temps:
        clean = S.chamber(tr, [t], dirs, 1, CPG, rng, noise_counts=0.0)[0, 0, :, 0, :]
        code = acc.code_of(t)
        acc.update(code)
        ca.update(code)
        e = 0.0
        for o in range(len(dirs)):
            v = [0, 0, 0]
            acc.apply_all([int(x) for x in clean[o]], v)
            ca.apply(v, v)
            e = max(e, float(np.max(np.abs(np.array(v) / 10.0 - 1000 * dirs[o]))))
        worst.append(e)
    return np.array(worst)


def test_cross_axis_drift_is_followed_on_the_device():
    tr, rng = _drift_unit(seeds.seed("sixpos_drift", 31))
    temps = np.array([-40.0, -10.0, 25.0, 55.0, 85.0])
    raw = S.chamber(tr, temps, S.SIX, 50, CPG, rng, noise_counts=4.0)
    mean, se = P.reduce_samples(raw)
    out, _ = P.fit_means(mean, temps, CPG, S.SIX, se, order=2)
    res = P.summarise(out, 0, CPG, 25.0, [])
    ints = P.record_ints(res)
    kw = dict(t_scale=T_SCALE, t_offset=T_OFFSET)
    acc = AN12760.from_record(ints, CPG, out_per_g=10000, **kw)
    law = CrossAxis.from_record(res["cross_record"], **kw)
    flat = CrossAxis(res["cross_correction"])  # the matrix at t_room only, as before the law
    # fresh directions the fit never saw, besides the six faces
    dirs = np.vstack([S.SIX, rng.normal(size=(20, 3))])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    check = [-40.0, 85.0]
    e_flat = _device_error_mg(acc, flat, tr, rng, check, dirs)
    e_law = _device_error_mg(acc, law, tr, rng, check, dirs)
    print("worst error at -40/85 degC: constant matrix %s mg, with the law %s mg" % (e_flat, e_law))
    # the drift is 6.5e-3 at both ends: a constant matrix leaves 6-7 mg (twice the drift on a
    # diagonal direction)
    assert np.all(e_flat > 5.0)
    # with the law: the 0.1 mg output step, the fit's noise (4 counts / sqrt(50) at 8192/g,
    # 0.07 mg) and the per-axis step's own rounding
    assert np.all(e_law < 0.5)
    # and everywhere in between
    assert np.all(_device_error_mg(acc, law, tr, rng, np.linspace(-40, 85, 11), dirs) < 0.5)


def test_cross_axis_law_fitted_over_many_units():
    # recovery of the drift per term, against the simulated truth (not the fit's own algebra)
    rng = np.random.default_rng(seeds.seed("sixpos", 4))
    tr = S.truth(200, rng, cross=0.008, rot=0.005, cross_tc=1e-4)
    temps = np.array([-40.0, 0.0, 25.0, 60.0, 85.0])
    raw = S.chamber(tr, temps, S.SIX, 40, CPG, rng, noise_counts=4.0)
    mean, se = P.reduce_samples(raw)
    out, _ = P.fit_means(mean, temps, CPG, S.SIX, se, order=1)
    N_true = tr["N"][:, None] + tr["N1"][:, None] * (np.array([-40.0, 85.0]) - 25.0)[None, :, None, None]
    E_true = np.linalg.inv(np.eye(3) + N_true) - np.eye(3)
    law = out["cross_correction_law"]
    assert law.shape == (200, 3, 3, 3)  # a linear N(T) gives a quadratic E(T)
    for k, t in enumerate((-40.0, 85.0)):
        E_fit = sum(law[:, i] * (t - 25.0) ** i for i in range(3))
        # a 1 g input would be off by this much (mg): noise of 5 x 40 samples of 4 counts
        err = np.max(np.abs(E_fit - E_true[:, k])) * 1000
        assert err < 0.3, (t, err)


# A constant-matrix record as the fit wrote it before the temperature law (9 values), kept
# as literal ints: stored records of that layout must keep loading and giving the same output.
# (m, e) pairs: value = m * 2**e, so -4194304 * 2**-30 = -2**-8
OLD_CROSS_RECORD = [3, 1, 9, 0, 0, -4194304, -30, 4194304, -31, 4194304, -30, 0, 0, 4194304, -32,
                    -4194304, -31, -4194304, -32, 0, 0]


def test_old_cross_record_still_loads():
    ca = CrossAxis.from_record(OLD_CROSS_RECORD, t_scale=T_SCALE, t_offset=T_OFFSET)
    E = np.array([[0, -2**-8, 2**-9], [2**-8, 0, 2**-10], [-2**-9, -2**-10, 0]])
    assert np.allclose(np.array(ca.e).reshape(3, 3), E, rtol=0, atol=0)
    v = [100000, -50000, 20000]
    out = [0, 0, 0]
    ca.update(ca.code_of(-40.0))  # no law: temperature changes nothing
    ca.apply(v, out)
    assert out == [int(round(x)) for x in np.array(v) + E @ np.array(v)]
    assert ca.to_record() == OLD_CROSS_RECORD


def test_cross_record_round_trip_and_bad_records():
    e0 = [[0.0, -0.004, 0.002], [0.004, 0.0, 0.001], [-0.002, -0.001, 0.0]]
    e1 = [[0.0, 1e-4, -1e-4], [1e-4, 0.0, 2e-5], [-1e-4, 2e-5, 0.0]]
    ca = CrossAxis(e0, law=[e1], t_span_c=(-40, 85), t_scale=T_SCALE, t_offset=T_OFFSET)
    rec = ca.to_record()
    assert len(rec) == 3 + 2 * (9 + 4 + 9)
    back = CrossAxis.from_record(rec, t_scale=T_SCALE, t_offset=T_OFFSET)
    for t in (-60.0, -40.0, 10.0, 85.0, 100.0):
        assert np.allclose(back.matrix(t), ca.matrix(t), rtol=1e-6, atol=1e-12)
    flat = list(np.ravel(e0)) + [25.0, -40.0, 85.0, 2.0] + list(np.ravel(e1))  # says degree 2, holds 1
    with pytest.raises(ValueError, match="22 values do not hold a degree 2.0 law"):
        CrossAxis.from_record(record.pack(record.KIND_CROSS, flat), t_scale=T_SCALE)
    with pytest.raises(ValueError, match="neither 9"):
        CrossAxis.from_record(record.pack(record.KIND_CROSS, [0.0] * 11))
    with pytest.raises(ValueError, match="outside \\+-1/16"):
        CrossAxis(e0, law=[[[0, 1e-3, 0], [0, 0, 0], [0, 0, 0]]], t_span_c=(-40, 85))


def test_cross_axis_law_fixed_point_vs_float():
    """Worst error of update+apply against float64 (I + E(T)) v, T from the code, over the whole
    input range |v| < 2**18 and temperature codes across and beyond the span (held at the edges)."""
    rng = np.random.default_rng(seeds.seed("sixpos", 12))
    worst = worst14 = 0.0
    for _ in range(40):
        laws = [rng.uniform(-0.04, 0.04, 9), rng.uniform(-1.5e-4, 1.5e-4, 9), rng.uniform(-1e-6, 1e-6, 9),
                rng.uniform(-5e-9, 5e-9, 9)]
        deg = int(rng.integers(1, 4))
        ca = CrossAxis(laws[0], law=laws[1:deg + 1], t_span_c=(-40, 85), t_scale=T_SCALE, t_offset=T_OFFSET)
        lo, hi = ca.code_of(-40.0), ca.code_of(85.0)
        codes = list(rng.integers(lo - 3000, hi + 3000, 25)) + [lo, hi]
        for code in codes:
            ca.update(int(code))
            d = min(max(int(code) * T_SCALE + T_OFFSET, -40.0), 85.0) - 25.0
            E = sum(laws[k] * d ** k for k in range(deg + 1)).reshape(3, 3)
            vs = list(rng.integers(-(2**18) + 1, 2**18, (20, 3))) + [np.array([2**18 - 1, -(2**18) + 1, 2**18 - 1])]
            for v in vs:
                for w in (v, v >> 4):
                    out = [0, 0, 0]
                    ca.apply([int(x) for x in w], out)
                    err = float(np.max(np.abs(np.array(out) - (w + E @ w))))
                    # 0.5 rounding + sum |v| x 4 units of 2**-22 (Horner's rounding of the law;
                    # 3.3 measured over 200 seeds): 1.25 LSB at full scale, 0.55 below 2**14
                    assert err <= 0.5 + float(np.sum(np.abs(w))) * 2.0**-20, (w, err)
                    if w is v:
                        worst = max(worst, err)
                    else:
                        worst14 = max(worst14, err)
    print("cross-axis law worst error %.4f LSB (|v| < 2**18), %.4f LSB (|v| < 2**14)" % (worst, worst14))


def test_mpu6500_register_sim_cross_axis_drift_end_to_end(tmp_path):
    """The register-level MPU-6500 model with a drifting cross-axis matrix (within the datasheet's
    +-2 %), read through the driver: six faces at five temperatures -> fit -> records -> the
    device path, checked at -40 and 85 degC on faces and tilted attitudes the fit never saw."""
    from tempcomp.mpu6xxx import MPU6xxx
    from tools.sim.buses import SimI2C
    from tools.sim.mpu6xxx_sim import FACES, MPU6xxxSim

    n0 = [[0.0, 0.008, -0.006], [0.005, 0.0, 0.004], [-0.007, 0.009, 0.0]]
    tc = [[0.0, 1e-4, -1e-4], [1e-4, 0.0, 1e-4], [-1e-4, -1e-4, 0.0]]
    sim = MPU6xxxSim("MPU-6500", seed=seeds.seed("sixpos_sim", 5), accel_noise_g=0.001)
    sim.set_cross(n0, tc)
    sim.set_tc(accel=[(0.0004, 1e-5), (-0.0003, 0.0), (0.0002, -2e-5)])
    imu = MPU6xxx(SimI2C({0x68: sim}))
    buf = [0] * 7

    def settle():
        # the data registers hold the last sample (1 kHz, each read ~0.4 ms of bus time)
        for _ in range(8):
            imu.read_raw(buf)

    def mean_raw(n):
        settle()
        s = np.zeros(3)
        for _ in range(n):
            imu.read_raw(buf)
            s += buf[:3]
        return s / n

    path = tmp_path / "mpu.csv"
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["temp_c", "orient", "ax", "ay", "az"])
        for t in (-40.0, -10.0, 25.0, 55.0, 85.0):
            sim.temp_c = t
            settle()
            tr = imu.temp_c100() / 100.0  # the part's own reading
            for face in FACES:
                sim.place(face)
                settle()
                for _ in range(100):
                    imu.read_raw(buf)
                    w.writerow([tr, face] + buf[:3])
    res = P.fit_csv(str(path), 16384, order=2)
    ints = P.record_ints(res)
    kw = dict(t_scale=T_SCALE, t_offset=T_OFFSET)
    acc = AN12760.from_record(ints, 16384, out_per_g=10000, **kw)
    law = CrossAxis.from_record(res["cross_record"], **kw)
    flat = CrossAxis(res["cross_correction"])
    rng = np.random.default_rng(seeds.seed("sixpos", 3))
    dirs = np.vstack([np.array(list(FACES.values())), rng.normal(size=(8, 3))])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    for t in (-40.0, 85.0):
        sim.temp_c = t
        settle()
        code = imu.temp_raw()
        acc.update(code)
        law.update(code)
        e_law = e_flat = 0.0
        for g in dirs:
            sim.set_motion(accel_g=tuple(g))
            raw = [int(round(x)) for x in mean_raw(64)]
            v = [0, 0, 0]
            acc.apply_all(raw, v)
            a = [0, 0, 0]
            law.apply(v, a)
            b = [0, 0, 0]
            flat.apply(v, b)
            e_law = max(e_law, float(np.max(np.abs(np.array(a) / 10.0 - 1000 * g))))
            e_flat = max(e_flat, float(np.max(np.abs(np.array(b) / 10.0 - 1000 * g))))
        print("MPU-6500 sim at %.0f degC: constant matrix %.2f mg, with the law %.2f mg" % (t, e_flat, e_law))
        # 6.5e-3 of drift on two terms of a row: up to 9 mg on a tilted attitude
        assert e_flat > 5.0
        # noise: 1 mg per sample, 64-sample means (0.13 mg), the fit's 100-sample means, the
        # 0.1 mg output step and the int rounding of the mean raw counts (0.03 mg)
        assert e_law < 0.8


def test_mpu_sim_cross_axis_stays_within_the_datasheet():
    from tools.sim.mpu6xxx_sim import MPU6xxxSim

    sim = MPU6xxxSim("MPU-6500", seed=seeds.seed("sixpos/cross_sim"))
    with pytest.raises(ValueError, match=r"N\[0\]\[1\] = 0.0262 at 85 degC is outside the datasheet's \+-2 %"):
        sim.set_cross([[0, 0.013, 0], [0, 0, 0], [0, 0, 0]], [[0, 2.2e-4, 0], [0, 0, 0], [0, 0, 0]])
    with pytest.raises(ValueError, match="diagonal"):
        sim.set_cross([[0.01, 0, 0], [0, 0, 0], [0, 0, 0]])
    assert sim.cross is None


def test_cli_ellipsoid_refuses_poor_coverage(tmp_path):
    # twelve orientations that crowd one hemisphere: exit status 2, one line naming them
    rng = np.random.default_rng(_refused_seed("sixpos/cli_refused"))
    tr = S.truth(50, rng, rot=0.0)
    dirs = rng.normal(size=(12, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    raw = S.chamber({k: v[:1] for k, v in tr.items()}, TEMPS, dirs, 10, CPG, rng, noise_counts=3.0)
    path = tmp_path / "ell.csv"
    _csv(path, raw, ["o%d" % i for i in range(12)], TEMPS)
    p = subprocess.run([sys.executable, "-m", "tools.fit", "sixpos", str(path), "--ellipsoid", "--json",
                        str(tmp_path / "o.json"), "--counts-per-g", "8192", "--order", "2"], cwd=REPO,
                       capture_output=True, text=True)
    assert p.returncode == 2, p.stderr
    err = p.stderr.strip()
    assert len(err.splitlines()) == 1 and "ellipsoid fit refused: orientation coverage" in err, err
    assert "add orientations with" in err and " up" in err
    assert not (tmp_path / "o.json").exists()
