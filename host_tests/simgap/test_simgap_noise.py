"""The noise model under the gap diagnosis (tools/simgap/noise.py) against independent truth:
statsmodels' exact Kalman filter for the GLS it replaces, planted noise terms for the
estimates, a Monte Carlo for the floor, and small planted situations (one random seed per
run, printed; SIMGAP_NOISE_SEED overrides) for the wander check."""
import os
import zlib

import adversarial_logs as A
import numpy as np
import pytest
from simgap_synth import play
from statsmodels.tsa.statespace.structural import UnobservedComponents

from tools.simgap import noise as N
from tools.simgap.diagnose import diagnose

SEED = int(os.environ.get("SIMGAP_NOISE_SEED", np.random.SeedSequence().entropy % 10_000))


def setup_module(module):
    print(f"\nSIMGAP_NOISE_SEED={SEED}")


def _walk_plus_white(n, s, q, rng):
    return rng.normal(0, s, n) + np.cumsum(rng.normal(0, np.sqrt(q), n))


def test_gls_by_the_filter_matches_statsmodels_kalman():
    # y = 3 x + level(random walk) + white: statsmodels' exact Kalman filter with the
    # regression coefficient in the state (diffuse) against least squares on the
    # lfilter-whitened columns with the intercept as the initial level.
    rng = np.random.default_rng(SEED)
    n, s2, q = 3000, 4.0, 0.05
    x = np.sin(np.arange(n) / 60.0) + rng.normal(0, 0.3, n)
    y = 3.0 * x + 10 + _walk_plus_white(n, np.sqrt(s2), q, rng)
    mod = UnobservedComponents(y, level="llevel", exog=x[:, None], mle_regression=False)
    kres = mod.filter([s2, q])
    beta_kalman = float(kres.filtered_state[-1, -1])
    m = N.NoiseModel(s2, q)
    X = np.column_stack([np.ones(n), x])
    Xw, yw = N.whiten(X, m, np.array([0])), N.whiten(y, m, np.array([0]))
    beta = np.linalg.lstsq(Xw, yw, rcond=None)[0]
    assert beta[1] == pytest.approx(beta_kalman, abs=0.02)
    # ... and the truth within 4 standard errors of the GLS estimate.
    u = yw - Xw @ beta
    se = np.sqrt(np.var(u) * np.linalg.inv(Xw.T @ Xw)[1, 1])
    assert abs(beta[1] - 3.0) < 4 * se
    # The innovations' variance is the model's steady-state one.
    assert np.var(u[200:]) == pytest.approx(m.filter()[2], rel=0.1)
    assert m.filter()[2] == pytest.approx(float(kres.forecasts_error_cov[0, 0, -1]), rel=0.02)


@pytest.mark.parametrize("case", ["white", "walk", "gauss-markov"])
def test_estimate_recovers_planted_terms(case):
    rng = np.random.default_rng(SEED + 1)
    n, s = 20000, 2.0
    e = rng.normal(0, s, n)
    q = g2 = 0.0
    phi = 0.99
    if case == "walk":
        q = 0.01
        e += np.cumsum(rng.normal(0, np.sqrt(q), n))
    if case == "gauss-markov":
        from scipy.signal import lfilter
        g2 = 1.0
        e += lfilter([1], [1, -phi], rng.normal(0, np.sqrt(g2 * (1 - phi ** 2)), n))
    ad = N.allan(e, 1.0)
    assert np.all(ad["lo"] <= ad["adev"]) and np.all(ad["adev"] <= ad["hi"])
    m, _ = N.estimate(e, 1.0, np.array([0]), s * s, N.fit_allan(ad))
    assert m.s2 == pytest.approx(s * s, rel=0.1)
    if case == "white":
        assert m.is_white
    if case == "walk":
        assert m.q == pytest.approx(q, rel=0.4) and m.g2 == 0
    if case == "gauss-markov":
        assert m.g2 == pytest.approx(g2, rel=0.5) and m.phi == pytest.approx(phi, abs=0.01)


def test_floor_matches_monte_carlo():
    m = N.NoiseModel(4.0, 0.02, 1.0, 0.995)
    rng = np.random.default_rng(SEED + 2)
    n, reps = 2000, 3000
    from scipy.signal import lfilter
    e = rng.normal(0, 2, (reps, n)) + np.cumsum(rng.normal(0, np.sqrt(0.02), (reps, n)), axis=1)
    start = rng.normal(0, 1, (reps, 1)) * 0.995          # the Gauss-Markov term in steady state
    e += lfilter([1], [1, -0.995], rng.normal(0, np.sqrt(1 - 0.995 ** 2), (reps, n)), axis=1,
                 zi=start)[0]
    ms = np.mean((e - e.mean(axis=1, keepdims=True)) ** 2, axis=1)
    se = np.std(ms) / np.sqrt(reps)
    assert abs(m.floor_ms([(np.arange(n), True)]) - np.mean(ms)) < 4 * se + 0.02 * np.mean(ms)


def _lag(T, tau, dt=A.DT):
    out, v, a = np.empty_like(T), T[0], 1 - np.exp(-dt / tau)
    for i, x in enumerate(T):
        v += a * (x - v)
        out[i] = v
    return out


def _case(name, rng):
    """(effect or None, walk per sample, expected verdict on axis x alone)."""
    if name == "walk":
        return None, rng.uniform(0.1, 0.25), []
    if name == "lag_many_times_slope":
        # x's static slope is 3 mdps/degC; the lag weight 15-30x it (no ratio veto).
        w, tau = rng.uniform(45, 90), rng.uniform(150, 400)
        return (lambda t, T, r, a: w * (T - _lag(T, tau))), 0.0, ["temp_rate"]
    if name == "hysteresis_under_walk":
        c, h = rng.uniform(4, 8), rng.uniform(4, 10)
        return (lambda t, T, r, a: c * (play(T, h) - T)), 0.12, ["hysteresis"]
    if name == "aging":
        k = rng.choice([-1, 1]) * rng.uniform(20, 40)
        return (lambda t, T, r, a: k * t / 6000.0), 0.0, ["drift"]
    raise ValueError(name)


@pytest.mark.parametrize("name", ["walk", "lag_many_times_slope", "hysteresis_under_walk", "aging"])
def test_planted_situation(name):
    rng = np.random.default_rng(SEED + zlib.crc32(name.encode()) % 1000)
    eff, walk, truth = _case(name, rng)
    s = int(rng.integers(0, 10_000))
    res, ex = diagnose(A.make(seed=s, walk=walk, effect=eff), A.make(seed=s + 1, walk=walk, effect=eff))
    g = ex["greedy"]
    assert res["verdict"] == truth, (SEED, res["verdict"])
    assert [n for n, _ in g.state[0]] == truth and not g.state[1] and not g.state[2], (SEED, g.state)
    for ax in "xyz":
        nm = res["noise_model"][ax]
        assert nm["white"]["sigma"] == pytest.approx(2.0, rel=0.15)       # adversarial_logs' sigma
        if walk > 0:        # a planted walk is modelled (as a walk, or a slow Gauss-Markov term)
            assert nm["random_walk"] is not None or nm["bias_instability"] is not None
        r = res["final"]["ratio_to_noise"][ax]
        warned = any(w["code"] == "unexplained_residual" and w["axis"] == ax for w in res["warnings"])
        assert warned == (r > 1.5)
    if truth:
        e = next(e for e in res["effects"] if e["name"] == truth[0])
        lo, hi = e["shrink_interval"]
        assert lo <= e["shrink"] <= hi and lo > 0.2
    assert not any(w["code"] == "implausible_coefficient" and w["effect"] == "temp_rate"
                   and name == "lag_many_times_slope" and w.get("kept_out") for w in res["warnings"])


def test_bartlett_profile_peak_stays_inside_the_grid():
    # The stage B bootstrap's profile over the walk-ratio grid (select._grid_peak): at an
    # interior maximum the parabola through three points of a quadratic is its exact peak
    # (5 at x = 0.3 for 5 - (x - 0.3)^2 on x = -2..2); at the grid's edge (a profile still
    # rising) the value is the edge's own, never the parabola's extrapolation (through
    # -1000, 9, 10 that would be 9 + 1010^2 / 8064 = 135.5).
    from tools.simgap.select import _grid_peak
    x = np.arange(-2.0, 3.0)
    quad = 5 - (x - 0.3) ** 2
    edge = np.array([-2000.0, -1500.0, -1000.0, 9.0, 10.0])
    got = _grid_peak(np.column_stack([quad, edge]))
    assert got[0] == pytest.approx(5.0, abs=1e-12)
    assert got[1] == 10.0
