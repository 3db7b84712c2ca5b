"""ADI three-point gyro calibration: quadratic vs Lagrange, fixed-point rate, sim end-to-end, host fit."""

import csv
import json
import subprocess
import sys

import numpy as np
import pytest
import seeds
from paths import REPO

from tempcomp.adxrs import AnalogGyro, point
from tempcomp.fixedpoint import quadratic_through
from tools.fit import adxrs as FA
from tools.fit.common import FitError
from tools.sim.analog_gyro_sim import AnalogGyroSim, ReplayADC


def lagrange(pts, x):
    """Independent float64 evaluation of the interpolating quadratic (Lagrange form)."""
    (x0, y0), (x1, y1), (x2, y2) = pts
    x = np.asarray(x, dtype=np.float64)
    return (y0 * (x - x1) * (x - x2) / ((x0 - x1) * (x0 - x2))
            + y1 * (x - x0) * (x - x2) / ((x1 - x0) * (x1 - x2))
            + y2 * (x - x0) * (x - x1) / ((x2 - x0) * (x2 - x1)))


def test_quadratic_through_matches_lagrange():
    rng = np.random.default_rng(seeds.seed("adxrs_3"))
    for _ in range(200):
        xs = np.sort(rng.uniform(1000, 4000, 3))
        if np.min(np.diff(xs)) < 50:
            continue
        pts = list(zip(xs, rng.uniform(2000, 3000, 3)))
        ref = float(xs[1])
        c = quadratic_through(pts[0], pts[1], pts[2], ref)
        x = np.linspace(xs[0], xs[2], 301)
        q = c[0] + c[1] * (x - ref) + c[2] * (x - ref) ** 2
        assert np.max(np.abs(q - lagrange(pts, x))) < 1e-9 * 3000
        for px, py in pts:  # through the points themselves
            assert abs(c[0] + c[1] * (px - ref) + c[2] * (px - ref) ** 2 - py) < 1e-9


class _Const:
    def __init__(self, v):
        self.v = v

    def read_u16(self):
        return self.v


def test_fixed_point_three_point_vs_lagrange():
    """V0/S points at exact ADC codes; rate over the whole VT span and rate range, in mdps."""
    q = 3300.0 / 65535  # mV per code, direct wiring
    vt_codes = (36000, 46000, 55000)
    v0_codes = (40000.0, 40650.5, 42010.25)
    s_codes = (121.5, 119.0, 116.25)  # codes per dps (~6 mV/dps)
    g = AnalogGyro(_Const(0), _Const(0), 3300, out_per_dps=1000)
    g.set_three_point(*[(vt * q, v0 * q, s * q) for vt, v0, s in zip(vt_codes, v0_codes, s_codes)])
    # the three points: null reads 0, null + 100 dps * S reads 100000 mdps, within the rounding
    for vt, v0, s in zip(vt_codes, v0_codes, s_codes):
        for rate in (0.0, 100.0, -250.0):
            raw = v0 + s * rate
            rr = int(round(raw))
            want = (rr - v0) / s * 1000
            assert abs(g.rate_from(vt, rr) - want) <= 0.5625
    rng = np.random.default_rng(seeds.seed("adxrs_4"))
    P0 = list(zip(vt_codes, v0_codes))
    PS = list(zip(vt_codes, s_codes))
    worst = 0.0
    for t in list(rng.integers(36000, 55001, 300)) + [36000, 55000]:
        v0 = lagrange(P0, t)
        s = lagrange(PS, t)
        for r in list(rng.integers(int(v0 - 260 * s), int(v0 + 260 * s), 20)):
            want = (r - v0) / s * 1000
            worst = max(worst, abs(g.rate_from(int(t), int(r)) - want))
    print("ADXRS three-point worst error %.4f mdps" % worst)
    assert worst <= 0.5625


def _calibrate(sim, g, temps=(-40, 25, 85), rate=200.0, n=300):
    pts = []
    for t in temps:
        sim.temp_c = t
        sim.rate_dps = 0.0
        vt, v0 = g.measure(n)
        sim.rate_dps = rate
        vt2, v1 = g.measure(n)
        pts.append(point((vt + vt2) / 2, v0, v1, rate))
    return pts


def test_sim_three_point_beats_single_point():
    sim = AnalogGyroSim(vref_mv=3300, divider=2.0, noise_mv=0.3, t_noise_mv=0.2, bits=12, seed=seeds.seed("adxrs_sim_7"))
    g3 = AnalogGyro(sim.rate, sim.temp, 3300, divider=2.0, t_smooth=4)
    g3.set_three_point(*_calibrate(sim, g3))
    g1 = AnalogGyro(sim.rate, sim.temp, 3300, divider=2.0)
    sim.temp_c = 25
    sim.rate_dps = 0
    _, v0 = g1.measure(300)
    sim.rate_dps = 200
    _, v1 = g1.measure(300)
    g1.set_single(v0, (v1 - v0) / 200)
    err1 = err3 = 0.0
    for t in (-40, -10, 25, 55, 85):
        sim.temp_c = t
        for r in (-250.0, 0.0, 150.0):
            sim.rate_dps = r
            for _ in range(100):  # the VT low-pass settles (a chamber changes far slower)
                g3.rate()
            m3 = np.mean([g3.rate() for _ in range(200)]) / 1000
            m1 = np.mean([g1.rate() for _ in range(50)]) / 1000
            err3 = max(err3, abs(m3 - r))
            err1 = max(err1, abs(m1 - r))
    # 12-bit ADC through a 2:1 divider: 1.6 mV per code = 0.27 dps; three-point keeps the whole
    # range within a fraction of a degree per second, single point drifts by several
    print("three-point %.3f dps, single-point %.3f dps" % (err3, err1))
    assert err3 < 0.5, err3
    assert err1 > 5.0, err1


def test_negative_scale_factor_and_not_calibrated():
    sim = AnalogGyroSim(vref_mv=3300, divider=2.0, scale_mv=(-6.0, 4.0e-4, 0.0))
    g = AnalogGyro(sim.rate, sim.temp, 3300, divider=2.0)
    with pytest.raises(ValueError, match="not calibrated"):
        g.rate()
    g.set_three_point(*_calibrate(sim, g, n=4))
    sim.temp_c = 60
    sim.rate_dps = 100.0
    assert abs(g.rate() - 100000) < 400


def test_single_point_needs_no_temp_channel_and_circuitpython_value():
    class AnalogIn:  # CircuitPython analogio.AnalogIn: .value, no read_u16
        def __init__(self, ch):
            self.ch = ch

        @property
        def value(self):
            return self.ch.read_u16()

    sim = AnalogGyroSim(vref_mv=3300, divider=2.0)
    g = AnalogGyro(AnalogIn(sim.rate), None, 3300, divider=2.0)
    sim.temp_c = 25
    v0 = sim.null_at(sim.vt_mv())
    g.set_single(v0, sim.scale_at(sim.vt_mv()))
    sim.rate_dps = -120.0
    assert abs(g.rate() + 120000) < 300
    with pytest.raises(ValueError, match="VT channel"):
        g.set_three_point((1900, 2500, 6), (2500, 2500, 6), (3000, 2500, 6))


def test_replay_adc_loops():
    a = ReplayADC([1, 2, 3])
    assert [a.read_u16() for _ in range(5)] == [1, 2, 3, 1, 2] and a.value == 3


def _chamber_csv(path, sim, temps, rates=(0.0, 200.0, -200.0), n=40):
    g = AnalogGyro(sim.rate, sim.temp, 3300, divider=2.0)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["temp_c", "vt_mv", "rate_dps", "out_mv"])
        for t in temps:
            sim.temp_c = t
            for r in rates:
                sim.rate_dps = r
                for _ in range(n):
                    tc, rc = g.read_codes()
                    w.writerow([t, round(tc * g.mv_per_code, 3), r, round(rc * g.mv_per_code, 3)])


def test_host_fit_cli_to_device(tmp_path):
    sim = AnalogGyroSim(vref_mv=3300, divider=2.0, noise_mv=0.5, t_noise_mv=0.3, seed=seeds.seed("adxrs_sim_11"))
    path = tmp_path / "gyro.csv"
    _chamber_csv(path, sim, (-40, 25, 85))
    out = tmp_path / "gyro.json"
    p = subprocess.run([sys.executable, "-m", "tools.fit", "adxrs", str(path), "--json", str(out)],
                       cwd=REPO, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    res = json.loads(out.read_text())
    assert res["method"] == "three-point"
    # the sim's truth is a quadratic in VT about VT(25 degC): the fit's reference point
    assert abs(res["vt_ref_mv"] - sim.vt25_mv) < 1.0
    assert abs(res["v0_mv"][0] - sim.null_mv[0]) < 0.5 and abs(res["v0_mv"][1] - sim.null_mv[1]) < 0.01
    assert abs(res["s_mv_per_dps"][0] - sim.scale_mv[0]) < 0.01
    g = AnalogGyro(sim.rate, sim.temp, 3300, divider=2.0)
    g.load_record(res["record"])
    for t in (-30, 40, 80):
        sim.temp_c = t
        sim.rate_dps = 75.0
        assert abs(np.mean([g.rate() for _ in range(100)]) - 75000) < 500


def test_host_fit_more_points_and_bad_input(tmp_path):
    sim = AnalogGyroSim(vref_mv=3300, divider=2.0)
    path = tmp_path / "g5.csv"
    _chamber_csv(path, sim, (-40, 0, 25, 60, 85), n=2)
    res = FA.fit_csv(str(path))
    assert res["method"].startswith("least-squares") and max(abs(p["null_error_dps"]) for p in res["points"]) < 0.05
    t = np.repeat([-40.0, 85.0], 2)
    with pytest.raises(FitError, match="needs at least 3 temperatures"):
        FA.fit_rows(t, 2500 + 9 * (t - 25), np.tile([0.0, 100], 2), np.full(4, 2500.0))
    t = np.repeat([-40.0, 25.0, 85.0], 2)
    with pytest.raises(FitError, match="missing rate"):
        FA.fit_rows(t, 2500 + 9 * (t - 25), np.zeros(6), np.full(6, 2500.0))
    # a rate output that follows the rate (12.5 mV/dps), so that only the named fault is present
    rate = np.tile([0.0, 100], 3)
    out = 2500.0 + 12.5 * rate
    with pytest.raises(FitError, match="VT does not rise"):
        FA.fit_rows(t, 2500 - 9 * (t - 25), rate, out)
    with pytest.raises(FitError, match="not sorted"):
        FA.fit_rows(t[::-1].copy(), 2500 + 9 * (t[::-1] - 25), rate, out)
    with pytest.raises(FitError, match="stuck rate output"):
        FA.fit_rows(t, 2500 + 9 * (t - 25), rate, np.full(6, 2500.0))
