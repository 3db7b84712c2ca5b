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
# gap-check --set wander --logs 1). Each meets issue 22's 90 %-of-logs target per situation, but at
# the random seed of a run it fails a few runs in a hundred, which would make CI red that often for
# a known, measured rate: a miss is reported as XFAIL with its seed and the measured rate, a pass as
# XPASS. An entry goes once a sweep of >= 50 seeds on the current code shows no miss for it: the
# random walk alone (no verdict) and the hysteresis under a walk (named alone, within 1.25x) lost
# theirs on 2026-11-28 (seeds 1-20 and 41-70 on the final code, 50 seeds, no miss; rw_alone also
# 21-40; the earlier miss 24 for the loop met there too). The lag under a walk lost its entries on
# the same sweep and got them back when a CI run missed at WANDER_SEED=16153; a 200-seed sweep
# (71-270, 2026-11-28) then measured its rate. The heavy lag's named-alone check got one when the
# seventh round's sweep of seeds 71-110 missed at 94, and lost it when the ninth round mended that
# confusion (seeds 41-110 on the landed code and 111-200 on its unguarded first version, 160
# seeds, no miss). The hysteresis under a walk got its two back on 2026-11-29 (thirteenth round),
# when fresh seed 201 missed. Every other check must pass at any seed.
KNOWN_GAPS = {
    ("no_verdict", "off_catalogue"): "issue 22: a verdict on 1/80 seeds 1-80 on the code of"
        " 2026-11-29, tenth round, and 1/120 seeds 1-120 on the ninth's (69: a drift on x - the"
        " generator's humidity step came 4287 s after the power-on in the training log and 4366 s in the withheld one, the same schedule, which no test on"
        " one withheld log tells from a clock-tied effect); on older code also 9, 29, 30, 43, 65, 78"
        " (a temp_rate on one axis)",
    ("alone", "aging"): "issue 22: named alone on 79/80 seeds 1-80 on the code of 2026-11-29 (tenth"
        " round; 59: a line under one power-on that a walk explains as well, drift against the walk"
        " z 2.5, reported under not_identifiable); 61 and 89 (an unlogged step's onset chosen on the"
        " rows it was scored on) and 107, 111 were mended on 2026-11-29 (test_mended_...); also"
        " missed at WANDER_SEED=10255 and 46378 (CI runs of 2026-11-28, older code)",
    ("rms", "aging"): "issue 22: within 1.25x on 79/80 seeds 1-80 on the code of 2026-11-29 (59:"
        " 1.38x); also missed at WANDER_SEED=10255 (1.79x) and 46378 (older code)",
    ("alone", "hyst_rw"): "issue 22: named alone on 99 of 100 seeds swept on the code of 2026-11-29,"
        " thirteenth round (1-20, 41-60, 181-240, docs/simgap.md; 201: a loop of 6.4 LSB, 2.7 degC wide, on x under a"
        " walk the noise model read at twice its true K - 0.103 against 0.048 LSB/sqrt(s) - which"
        " took the loop: nothing named, held-out x 1.91 -> 1.84 with it)",
    ("rms", "hyst_rw"): "issue 22: within 1.25x on 99 of 100 seeds swept on the code of 2026-11-29,"
        " thirteenth round (201: 2.28x, the loop above not named; 1.23x the tool's own model floor)",
    ("alone", "lag_rw"): "issue 22: named alone on 80/80 seeds 1-80 on the code of 2026-11-29 (tenth"
        " round); still missed at WANDER_SEED=16153 (a CI run of 2026-11-28: the lag on x vetoed on"
        " the withheld log, its shrink's 90 % interval reaching below 0 under the walk); 28, 113 and"
        " 193 (named hysteresis) were mended on 2026-11-29",
    ("rms", "lag_rw"): "issue 22: within 1.25x on 80/80 seeds 1-80 on the code of 2026-11-29 (tenth"
        " round); still missed at WANDER_SEED=16153 (1.43x)",
    ("alone", "rw_drift"): "issue 22: named alone on 79/80 seeds 1-80 on the code of 2026-11-29 (tenth"
        " round; 65: x's 23 LSB warm-up, whose time constant the walk leaves flat in the profile"
        " likelihood, vetoed on the withheld log)",
    ("rms", "rw_drift"): "issue 22: within 1.25x on 76/80 seeds 1-80 on the code of 2026-11-29 (tenth"
        " round; 3: 1.26x, 29: 1.47x, 47: 1.58x - the warm-up named, its time constant 11-23 % off,"
        " the same under the generator's own noise parameters: the training realisation's)",
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


# Misses the sweeps found and the eighth, ninth and thirteenth rounds (2026-11-29) mended, each at
# its own seed (the generator's truth, read after the diagnosis, says what is planted; nothing here
# is the tool's own output copied back). They fail on the code before the mend.
MENDED = [
    # A straight aging line on z (-3.65 LSB/h on a 0.68 LSB white floor) chosen by the BIC as
    # exponential + line, whose exponential extrapolates wildly into a held-out first segment
    # (held-out z -3.6): nothing named, 3.72x the oracle floor. The line alone, stage A's second
    # chance (select.Greedy._simpler_heldout), is held-out z 325.
    ("aging", 107),
    # A straight aging line on z that an offset step at an unlogged time (onset at 5-20 % of the
    # training log, time constant half its span) explains as well on the training log: taken
    # out, 1.40x. On withheld half A the line beats that step moved to its best onset there
    # (select.Greedy._step_moved): the step's cause keeps its own time in each log.
    ("aging", 111),
    # Straight aging lines (z at seed 61, x at 89) taken out the same way, whose moved step had
    # chosen its onset on the very rows it was scored on and won by that choice (half A z -0.28,
    # 1.12): 1.36x and 1.61x. Cross-fitted (each half of A's blocks scored at the onset the other
    # half likes best) the lines win, z 2.25 and 2.69.
    ("aging", 61),
    ("aging", 89),
    # A lag (tau 71 s) on z: the loop's 3 columns predicted the held-out segments better than the
    # lag's 7 (score 18.8 against 15.2) while the profile likelihood prefers the lag by far:
    # named hysteresis, 1.52x. Told apart by the profile BIC (select.Greedy._told_apart).
    ("lag_rw", 113),
    # The same confusion under a heavy lag (weight 4x the static slope, tau 132 s), 1.00x but
    # named hysteresis.
    ("lag_heavy", 94),
    # A lag (tau 128 s) on x under a walk: the loop was significant held out on x and on y (where
    # the wander check then refused it), the lag on x alone, so the two were never compared and
    # the loop took x: named hysteresis, 4.01x. Compared where both are significant: the lag.
    ("lag_rw", 28),
    # The warm-up on x named alone, but z (nothing planted) at 1.45x: z's walk (K 0.022
    # LSB/sqrt(s)) moved 0.5 LSB RMS over the training log - its noise model white - and 2.9
    # over the withheld one, whose level was then scored as error. The withheld residual's own
    # walk test (diagnose: withheld_walk) scores that power-on less its mean, as on an axis whose
    # training bias walks (test_wander_withheld_walk.py builds the case at random seeds).
    ("rw_drift", 182),
]


@pytest.mark.parametrize("situation,seed", MENDED)
def test_mended_misses_named_alone_within_1_25x(tmp_path, situation, seed):
    r = wandercheck.run_one((situation, seed, 0, str(tmp_path)))
    assert r["alone"], "%s seed %d: planted %s, diagnosis claims %s" % (
        situation, seed, r["planted"], r["claims"])
    assert r["rms_ok"], "%s seed %d: withheld RMS / oracle floor %s" % (
        situation, seed, {a: round(v, 2) for a, v in r["rms_ratio"].items()})
