"""A withheld power-on whose bias walks where the training log's did not show it.

A random walk's realisation over one log can stay small by chance (rw_drift seed 182, z: 0.5 LSB
RMS over the training log, 2.9 over the withheld one, from one K). The training noise model is
then white, and the withheld log's level - which a walk from its own power-on makes unknowable -
would be scored as error. Built here from the wander generator (tools/gapbench/wander.py, written
apart from the diagnosis): its `white` situation (white noise and quantisation only, nothing
planted), with a walk from power-on added to one axis of the withheld log only, in the generator's
own physics (noise_parts) and at its range of K. The truth - which axis walks, what a perfect
model leaves - comes from the generator, never from the diagnosis. Seeds drawn per run (printed
at the end; TEMPCOMP_SEED repeats them)."""
import numpy as np
import pytest
from seeds import seed

from tools.gapbench import wander, wandercheck

AXES = wander.AXES


def _case(rng_seed, walk_axis):
    """The `white` case of rng_seed with a walk (K at the top of the generator's range: its
    realisation over the withheld log then moves the level by about the white sigma) added to
    walk_axis of the withheld log only (None: none). Returns (case, oracle floor per axis, the
    walk's standard deviation over the log in white sigmas)."""
    case = wander.make_case("white", rng_seed % 100000, 0)
    lg, truth = case["withheld"], case["truth"]
    scale = truth["scale_lsb_per_dps"]
    oracle = dict(truth["oracle_floor_lsb"])
    spread = 0.0
    if walk_axis is not None:
        rng = np.random.default_rng(rng_seed)
        k = wander.RRW[1]
        rw = wander.noise_parts(rng, len(lg["t"]), 0.0, None, k)["rw"] * scale
        noisy = lg["clean"][walk_axis] + lg["noise"][walk_axis]["white"] + rw
        lg["out"][walk_axis] = np.rint(noisy)
        e = lg["out"][walk_axis] - lg["clean"][walk_axis]
        oracle[walk_axis] = float(np.sqrt(np.mean((e - e.mean()) ** 2)))
        spread = float(np.std(rw) / (truth["axes"][walk_axis]["white_dps"] * scale))
    return case, oracle, spread


def _diagnose(tmp_path, case):
    paths = wander.write_case(case, str(tmp_path), "w")
    return wandercheck.diagnose_files(paths["train"], paths["withheld"], str(tmp_path / "w.json"))


def _withheld_walks(res):
    return {w["axis"] for w in res["warnings"]
            if w["code"] == "correlated_noise" and w.get("kind") == "random walk (withheld log)"}


@pytest.mark.parametrize("k", range(3))
def test_a_walk_on_the_withheld_log_alone_is_scored_less_its_mean(tmp_path, k):
    s = seed("withheld_walk", k)
    axis = AXES[s % 3]
    case, oracle, spread = _case(s, axis)
    res = _diagnose(tmp_path, case)
    assert res["verdict"] == [], "seed %d: a walk is no effect, got %s" % (s, res["verdict"])
    assert res["noise_model"][axis]["random_walk"] is None     # the training log shows none
    read = _withheld_walks(res)
    assert read <= {axis}, "seed %d: walk on %s, withheld walks read on %s" % (s, axis, sorted(read))
    # A realisation that moved by half the white sigma or more (measured: seeds 1-12 of this
    # construction, every one of 9 such read; one of 0.34 sigma not) must be read.
    if spread >= 0.5:
        assert read == {axis}, "seed %d: the walk moved %.2f white sigmas on %s, not read" % (
            s, spread, axis)
        assert res["noise_model"][axis]["withheld_random_walk"]["K"] > 0
    # The level a walk from power-on reaches is unknowable: scored less its mean, what is left
    # is within issue 22's 1.25x of what a perfect model leaves.
    ratio = {a: res["final"]["withheld_rms"][a] / oracle[a] for a in AXES}
    assert max(ratio.values()) <= 1.25, "seed %d: withheld RMS / oracle %s" % (s, ratio)


def test_no_walk_read_where_the_withheld_log_has_none(tmp_path):
    s = seed("withheld_walk_none")
    case, oracle, _ = _case(s, None)
    res = _diagnose(tmp_path, case)
    assert res["verdict"] == []
    assert _withheld_walks(res) == set(), "seed %d" % s
    assert all("withheld_random_walk" not in res["noise_model"][a] for a in AXES)
