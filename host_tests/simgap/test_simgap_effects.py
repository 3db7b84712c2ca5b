"""Each effect family finds an effect of its own kind in synthetic data (scored on held-out
segments of the one log), and the filters behind the families match hand computations. The logs' noise,
inputs and optional columns are the run's (TEMPCOMP_SEED)."""
import numpy as np
import pytest
from seeds import seed
from simgap_synth import make, play, profile

from tools.simgap import features as F
from tools.simgap import prep
from tools.simgap.diagnose import diagnose
from tools.simgap.effects import BY_NAME
from tools.simgap.features import Context, Prepared
from tools.simgap.logio import Log
from tools.simgap.report import text


def _prepared(t, T):
    n = len(t)
    log = Log("f", np.asarray(t, float), np.asarray(T, float), np.zeros((n, 3)), np.zeros((n, 3)))
    return Prepared(log, Context(log), np.ones(n, bool))


def test_play_operator_by_hand():
    p = _prepared(np.arange(8), [0, 1, 2, 3, 2, 1, 0, 1])
    assert F.play(p, 2.0).tolist() == [0, 0, 1, 2, 2, 2, 1, 1]


@pytest.mark.parametrize("uniform", [True, False])
def test_lowpass_matches_step_response(uniform):
    rng = np.random.default_rng(seed("simgap_effects/lowpass"))
    t = np.arange(400) * 0.5 if uniform else np.cumsum(np.r_[0, rng.uniform(0.1, 1, 399)])
    T = np.where(t > 0, 1.0, 0.0)
    y = F.lowpass(_prepared(t, T), 20.0)
    # A unit step applied just after t=0: the exact response is 1 - exp(-t/tau) at every
    # sample, whatever the spacing (both the IIR and the variable-step paths).
    assert np.allclose(y, 1 - np.exp(-t / 20.0), atol=1e-12)


def test_unstair_recovers_a_ramp_behind_a_coarse_reading():
    t = np.arange(2000.0)
    true = 10 + t * 0.01                  # 20 degC over the log
    reading = np.round(true)
    est = F.unstair(_prepared(t, reading), 0.0)
    mid = slice(200, 1800)
    assert np.sqrt(np.mean((est[mid] - true[mid]) ** 2)) < 0.03
    assert np.sqrt(np.mean((reading[mid] - true[mid]) ** 2)) > 0.25


def test_soak_weight_marks_held_steps_not_ramps():
    # The synthetic profile soaks at 25, 50, 0 and 45 degC between linear ramps (simgap_synth);
    # read in whole degrees, a soak holds one step for 240 samples, a ramp crosses one every 20.
    t, T = profile(3000)
    p = _prepared(t, np.round(T + 0.37))
    w = F.soak_weight(p)
    at = lambda f: w[int(f * (len(t) - 1))]   # noqa: E731
    assert [at(f) for f in (0.29, 0.54, 0.79)] == [1.0, 1.0, 1.0]          # mid-soak
    assert [at(f) for f in (0.16, 0.42, 0.66, 0.92)] == [0.0, 0.0, 0.0, 0.0]  # mid-ramp
    assert p.log is not None and Context(p.log).soaks
    # A staircase without soaks gets no soak column; a fine reading none at all.
    ramp = _prepared(np.arange(2000.0), np.round(10 + np.arange(2000.0) * 0.01))
    assert not Context(ramp.log).soaks and not np.any(F.soak_weight(ramp))
    assert not Context(_prepared(t, T).log).soaks
    cols = BY_NAME["temp_quantization"].columns
    assert cols(Context(p.log), p, 0.0, 0).shape[1] == 4
    assert cols(Context(ramp.log), ramp, 0.0, 0).shape[1] == 3


def _lag(t, T, tau):
    y, v = [], T[0]
    for i in range(len(T)):
        if i:
            v += (1 - np.exp(-(t[i] - t[i - 1]) / tau)) * (T[i] - v)
        y.append(v)
    return np.array(y)


N = 3000
F_TEMP_RATE, F_HYST = BY_NAME["temp_rate"], BY_NAME["hysteresis"]
_, _T = profile(N)
_rng = np.random.default_rng(seed("simgap_effects/columns"))
# Gravity along each axis in 10 of 30 stints of 100 rows, shuffled: every face is in the log and
# in several held-out segments (11 draws of 300-row stints left y out of the log at
# TEMPCOMP_SEED=2, and g_sensitivity had nothing to find).
ACC = np.repeat(np.eye(3)[_rng.permutation(np.arange(N // 100) % 3)], 100, axis=0)
SUPPLY = np.repeat(_rng.choice([3.0, 3.2, 3.4, 3.6], N // 100 + 1), 100)[:N]
RUN = np.repeat([0, 1, 2], N // 3)

CASES = {
    "offset_temperature": (lambda t, T, r: 15 * np.exp(-((T - 20) / 4) ** 2), {}),
    "sensitivity_temperature": (lambda t, T, r: 16 * 2e-5 * (T - 25) ** 2 * r[:, 0], {}),
    "hysteresis": (lambda t, T, r: 3 * (play(T, 6.0) - T), {}),
    "temp_rate": (lambda t, T, r: 2 * (T - _lag(t, T, 150.0)), {}),
    "cross_axis": (lambda t, T, r: 0.15 * r[:, 1], {}),
    "nonlinearity": (lambda t, T, r: 2e-3 * r[:, 0] ** 2, {}),
    "g_sensitivity": (lambda t, T, r: 12 * ACC[:, 1], {"acc": ACC}),
    "supply": (lambda t, T, r: 40 * (SUPPLY - 3.3), {"supply": SUPPLY}),
    # Settling after each of three power-ons (so held-out segments of other runs show it).
    "drift": (lambda t, T, r: 20 * np.exp(-(t - t[np.searchsorted(RUN, RUN)]) / 500), {"run": RUN}),
    "turn_on_bias": (lambda t, T, r: np.array([15.0, -10, 5])[RUN], {"run": RUN}),
}


def test_play_on_a_lagged_temperature_matches_hand_filters():
    t, T = profile(600)
    p = _prepared(t, T)
    assert np.allclose(F.play(p, 3.0, 80.0), play(_lag(t, T, 80.0), 3.0), atol=1e-9)
    assert np.allclose(F.play(p, 3.0), play(T, 3.0), atol=1e-12)


# Until the lagged loop was tried as a pair (select.LAGGED) the saturated model's loop and lag,
# each chosen alone (the loop on the reading: the lagged shapes need a lag in the state), fitted
# the lagged loop only in part; the noise model fitted to the rest (a Gauss-Markov term at
# TEMPCOMP_SEED=2, 11, 15, a walk at 3) took the x effects (7 LSB of lag, 12 of hysteresis, on a
# 2 LSB floor) from stage A: no verdict at all at 2 and 11. Now the pair is tried together, its
# shapes searched jointly, where neither passes alone (seed 3 still names the loop alone).
def _lagged_loop_case(run=None):
    # The package's hysteresis acts on the structure's temperature, which trails the reading
    # through a first-order lag; the offset also follows the lagged temperature.
    def effect(t, T, r):
        L = _lag(t, T, 150.0)
        return 2 * (T - L) + 4 * (play(L, 6.0) - L)

    log = make(effect, n=N, sigma=2.0, seed=seed("simgap_effects/lagged_hysteresis", run=run))
    res, ex = diagnose(log)
    assert {"temp_rate", "hysteresis"} <= set(res["verdict"][:2]), res["verdict"]
    assert res["final"]["ratio_to_noise"]["x"] < 1.1
    hyst = dict(ex["greedy"].state[0])["hysteresis"]
    assert isinstance(hyst, tuple) and hyst[1] > 0        # a (width, lag) shape was chosen
    # The same two effects with the play operators on the reading leave more behind.
    g = ex["greedy"]
    reading_only = min(np.sqrt(np.mean(g.prob.evaluate(0, [("temp_rate", tr), ("hysteresis", w)])["cv"] ** 2))
                       for tr in F_TEMP_RATE.shapes(g.prob.ctx) for w in F_HYST.shapes(g.prob.ctx))
    lagged = np.sqrt(np.mean(g.cur[0]["cv"] ** 2))
    # Better by more than 3 standard errors of an RMS of n noise samples (sigma / sqrt(2 n));
    # the flat "10 % better" held at the one seed it was written on, not at TEMPCOMP_SEED=5
    # (2.00 against 2.18: 8 %).
    n = len(g.cur[0]["cv"])
    assert lagged < reading_only - 3 * 2.0 / np.sqrt(2 * n)


@pytest.mark.xfail(strict=False, reason="issue 22: the lag + hysteresis pair not both named at "
                   "TEMPCOMP_SEED=3 and 34 of 1-50 (the loop alone on the reading; at 3 the pair "
                   "with the lagged loop then held-out z 0.9 under the walk fitted beside it), "
                   "1.15x at 310559 (make test, 2026-11-29); before the lagged pair 2, 3, 11, 34")
def test_hysteresis_on_the_lagged_temperature_found_with_its_lag():
    _lagged_loop_case()


@pytest.mark.parametrize("run", [2, 11])
def test_lagged_loop_found_where_the_noise_model_took_it(run):
    # The runs whose lagged loop got no verdict at all before the pair (regression).
    _lagged_loop_case(run)


@pytest.mark.parametrize("name", sorted(CASES))
def test_family_finds_its_own_effect(name):
    effect, kw = CASES[name]
    log = make(effect, n=N, sigma=2.0, seed=seed("simgap_effects/family/" + name), **kw)
    res, _ = diagnose(log)
    assert res["verdict"] and res["verdict"][0] == name, res["verdict"]
    # Only axis x carries the effect; it must come down to near the noise floor.
    assert res["final"]["ratio_to_noise"]["x"] < 1.15
    assert res["sim_only"]["withheld_rms"]["x"] > 1.5 * res["noise_floor"]["x"]
    e = next(e for e in res["effects"] if e["name"] == name)
    assert "x" in e["axes"] and e["significant"] and e["shrink"] > 0.3


def test_temp_quantization_found_on_a_coarse_reading():
    log = make(None, n=N, sigma=1.0, seed=seed("simgap_effects/temp_quantization"))
    # The output follows the true temperature (slope 4 LSB/degC); the reading is whole degrees.
    log.temp = np.round(log.temp + 0.37)
    res, _ = diagnose(log)
    assert res["verdict"][:1] == ["temp_quantization"]


def _coarse_reading_loop(run):
    # The loop acts on the true temperature; the reading is whole degrees.
    log = make(lambda t, T, r: 3 * (play(T, 6.0) - T), n=N, sigma=1.0,
               seed=seed("simgap_effects/hysteresis_coarse_reading", run=run))
    log.temp = np.round(log.temp + 0.37)
    res, _ = diagnose(log)
    return res, {e["name"]: e["axes"] for e in res["effects"] if e["name"] in res["verdict"]}


# None: this run's data. The others, each the data a former version failed (TEMPCOMP_SEED):
# 415318 - the lag/loop rule (select.Greedy._told_apart) without its staircase guard named the
#   loop temp_rate on all three axes;
# 3 (of 1-40; 710081 too, where a CI run failed) - the loop, established on x, was borrowed onto
#   y and z (judged there by the wander test alone) although temp_quantization, significant on
#   their held-out segments, fitted them better; select.Greedy._borrow_holds now keeps such a
#   borrow out unless a withheld log confirms it, and this log has none;
# 8 (of 1-40; 1, 7, 18, 24, 28, 32, 36 too) - a temp_rate took the soaks' error on y and z (the
#   true value sits 0.37 degC below the held step there, and unstair holds the step): the soak
#   column of temp_quantization now carries it.
# TEMPCOMP_SEED 1-40 on this code (2026-11-29): every one names the loop on x alone and
# temp_quantization on x, y, z, nothing else, x within 0.97x (main before: the loop alone on
# 39, seed 3 not; with the borrow check but no soak column, a temp_rate on 8). With the play operators on the steps the loop was missed on x at 3-6
# and 8 of 1-8 (a temp_rate took its place); on the de-staired estimate it is named on x.
@pytest.mark.parametrize("run", [None, 415318, 3, 8])
def test_hysteresis_behind_a_coarse_reading_named_on_its_axis_with_the_staircase(run):
    res, axes = _coarse_reading_loop(run)
    # y and z carry the offset law and the staircase only.
    assert axes.get("hysteresis") == ["x"], axes
    assert set(axes) == {"hysteresis", "temp_quantization"}, axes
    assert res["final"]["ratio_to_noise"]["x"] < 1.1
    for c in res["borrow_checks"]:
        # No withheld log: nothing tells a borrowed effect from its better-fitting rival.
        assert c["p_withheld_a"] is None and not c["kept"], c
        assert (f"{c['effect']} on {c['axis']}: established on other axes, but {c['rival']}" in text(res)
                and "no withheld half A to tell them apart (no withheld log" in text(res))


def test_nothing_claimed_on_the_plain_model():
    log = make(None, n=N, sigma=2.0, seed=seed("simgap_effects/plain"), acc=ACC, supply=SUPPLY, run=RUN)
    res, _ = diagnose(log)
    assert res["verdict"] == []
    assert all(0.9 < v < 1.1 for v in res["final"]["ratio_to_noise"].values())


def test_noise_floor_ignores_slow_structure_and_spikes():
    log = make(lambda t, T, r: 30 * np.sin(t / 700), n=N, sigma=2.5, seed=seed("simgap_effects/floor"))
    resid = log.out - np.median(log.out, axis=0)
    # Slow structure and the offsets' temperature trend stay out of first differences.
    floor = prep.noise_floor(resid, log)
    assert floor == pytest.approx([2.5] * 3, rel=0.08)


def test_spikes_found_even_on_an_input_step():
    log = make(None, n=N, sigma=2.0, seed=seed("simgap_effects/spikes"))
    step = int(np.flatnonzero(np.diff(log.ref[:, 2]) != 0)[3]) + 1
    rows = [0, 500, step, 2222]          # row 0: a spike on the very first sample too
    log.out[rows, [0, 1, 2, 0]] += [300, -250, 400, -200]
    assert set(np.flatnonzero(prep.spikes(log))) == set(rows)
