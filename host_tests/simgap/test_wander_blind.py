"""Blind run of the gap diagnosis on the wander set (tools/gapbench/wander.py, written apart from
the diagnosis and from gen.py): one log per situation at one seed drawn at random per run
(printed; WANDER_SEED=N repeats it), diagnosed from its CSV files through the front door, then
scored against the generator's truth with issue 22's targets. `python -m tools gap-check --set
wander` runs the full sweep (20 seeds, 3 logs per situation)."""
import os

import pytest

from tools.gapbench import wander, wandercheck

SEED = int(os.environ["WANDER_SEED"])  # drawn per run by host_tests/helpers/seeds.py (set it to repeat one)
EFFECT_SITUATIONS = [s for s in wander.SITUATIONS if s not in wandercheck.NO_VERDICT]

# Checks that missed on some seed of the sweeps (docs/simgap.md, "The wander set": python -m tools
# gap-check --set wander --seeds 1-20 --logs 1, noise branch dfe2275, and --seeds 21-N of the same
# command on main 6dce6f0, whose choices the noise branch's speed work keeps, 2026-11-28). Each
# meets issue 22's 90 %-of-logs target per situation, but at the random seed of a run it fails a few
# runs in a hundred, which would make CI red that often for a known, measured rate: a miss is
# reported as XFAIL with its seed and the measured rate, a pass as XPASS. Remove an entry once a
# sweep of >= 50 seeds shows no miss for it; every other check must pass at any seed.
_SWEPT = "seeds 21-81"
KNOWN_GAPS = {
    ("no_verdict", "off_catalogue"): "issue 22: a verdict on 1/20 seeds 1-20 (9) and 6/61 " + _SWEPT +
        " (29, 30, 43, 65, 78: a temp_rate on one axis; 69: a drift); with the withheld half-A"
        " confirmation (2026-11-28, fourth round) 0/20 on 1-20 and 21-40",
    ("no_verdict", "rw_alone"): "issue 22: a verdict on 0/20 seeds 1-20 and 1/61 " + _SWEPT +
        " (28: a drift on z)",
    ("alone", "lag_rw"): "issue 22: named alone on 20/20 seeds 1-20 and 58/61 " + _SWEPT +
        " (37, 38: a drift beside it; 59: read as hysteresis), missed at WANDER_SEED=22105 (the lag"
        " refused on the in-sample path: its held-out guard, z -10.6 on the other segments)",
    ("rms", "lag_rw"): "issue 22: within 1.25x on 20/20 seeds 1-20 and 60/61 " + _SWEPT +
        " (59: 1.60x, read as hysteresis), missed at WANDER_SEED=22105 (2.30x, the lag not named)",
    ("alone", "hyst_rw"): "issue 22: named alone on 20/20 seeds 1-20 and 60/61 " + _SWEPT +
        " (24: not named, held-out z 1.6 under a Gauss-Markov term)",
    ("rms", "hyst_rw"): "issue 22: within 1.25x on 20/20 seeds 1-20 and 60/61 " + _SWEPT +
        " (24: 2.72x, not named)",
    ("alone", "aging"): "issue 22: named alone on 20/20 seeds 1-20 and 60/61 " + _SWEPT +
        " (61: the drift on z not named); also missed at WANDER_SEED=10255 (y's drift not named)",
    ("rms", "aging"): "issue 22: within 1.25x on 20/20 seeds 1-20 and 60/61 " + _SWEPT + " (61: 1.36x);"
        " also missed at WANDER_SEED=10255 (1.79x)",
    ("alone", "rw_drift"): "issue 22: named alone on 20/20 seeds 1-20 and 59/61 " + _SWEPT +
        " (49: a temp_rate beside it; 65: the smaller of two drifts not named)",
    ("rms", "rw_drift"): "issue 22: within 1.25x on 19/20 seeds 1-20 (3: 1.26x) and 57/61 " + _SWEPT +
        " (22, 29, 41, 47: 1.35-1.61x, the warm-up named but its shape leaves part of it); with"
        " reshape's nested-family test (2026-11-28) seeds 21-60 give 38/40 (29: 1.47x, 47: 1.58x)",
}


def _cases(check, situations):
    return [pytest.param(s, marks=pytest.mark.xfail(strict=False, reason=KNOWN_GAPS[(check, s)]))
            if (check, s) in KNOWN_GAPS else s for s in situations]


@pytest.fixture(scope="module")
def rows(tmp_path_factory):
    print("\nwander blind set at seed %d (WANDER_SEED=%d repeats it)" % (SEED, SEED))
    rows = wandercheck.run([SEED], logs=1, jobs=min(2, os.cpu_count() or 1),
                           outdir=str(tmp_path_factory.mktemp("wander")))
    for r in rows:
        print(wandercheck.log_line(r))
    wandercheck.report(rows)
    return {r["situation"]: r for r in rows}


def test_every_situation_was_diagnosed(rows):
    assert sorted(rows) == sorted(wander.SITUATIONS)


@pytest.mark.parametrize("situation", _cases("alone", EFFECT_SITUATIONS))
def test_planted_effect_named_alone_on_its_axes(rows, situation):
    r = rows[situation]
    assert r["alone"], "seed %d: planted %s, diagnosis claims %s" % (SEED, r["planted"], r["claims"])


@pytest.mark.parametrize("situation", _cases("no_verdict", wandercheck.NO_VERDICT))
def test_no_verdict_on_noise_and_off_catalogue_offsets(rows, situation):
    r = rows[situation]
    assert r["no_verdict"], "seed %d: verdict %s on %s" % (SEED, r["verdict"], r["claims"])


@pytest.mark.parametrize("situation", wander.SITUATIONS)
def test_unexplained_residual_warned_above_1_5x_the_floor(rows, situation):
    r = rows[situation]
    assert not r["unwarned"], "seed %d: final/%s floor %s without unexplained_residual on %s" % (
        SEED, r["floor"], r["ratio_to_noise"], r["unwarned"])


@pytest.mark.parametrize("situation", _cases("rms", [s for s in wander.SITUATIONS
                                                    if s != "off_catalogue"]))
def test_final_withheld_rms_within_1_25x_the_oracle_floor(rows, situation):
    r = rows[situation]
    assert r["rms_scored"]
    assert r["rms_ok"], "seed %d: withheld RMS / oracle floor %s (sim alone %s)" % (
        SEED, {a: round(v, 2) for a, v in r["rms_ratio"].items()},
        {a: round(r["sim_only_rms"][a] / r["oracle_floor"][a], 2) for a in wander.AXES})
