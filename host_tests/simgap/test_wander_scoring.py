"""The wander set's scoring on hand-written diagnosis results: what counts as named, alone, warned
and within the oracle floor, and how a situation's logs make a seed pass."""
import io

import pytest

from tools.gapbench import wandercheck


def truth(situation="lag_rw", effects=None, oracle=2.0, in_cat=True):
    effects = effects or {"x": [], "y": [], "z": []}
    return {"situation": situation, "seed": 3, "index": 0, "effects": effects, "in_catalogue": in_cat,
            "oracle_floor_lsb": {a: oracle for a in "xyz"}}


def result(claims, rms=(2.0, 2.0, 2.0), ratio=(1.0, 1.0, 1.0), warned=(), noise_model=False):
    res = {"verdict": sorted({e for v in claims.values() for e in v}),
           "model": {"axes": {a: {"effects": [{"name": e} for e in claims.get(a, [])]} for a in "xyz"}},
           "final": {"withheld_rms": dict(zip("xyz", rms)), "ratio_to_noise": dict(zip("xyz", ratio))},
           "sim_only": {"withheld_rms": dict(zip("xyz", rms))},
           "warnings": [{"code": "unexplained_residual", "axis": a} for a in warned]}
    if noise_model:
        res["noise_model"] = {}
    return res


def test_named_alone_needs_the_effect_on_its_axis_and_nothing_else():
    t = truth(effects={"x": ["temp_rate"], "y": [], "z": []})
    r = wandercheck.score(result({"x": ["temp_rate"]}), t)
    assert r["named"] and r["alone"] and not r["no_verdict"]
    r = wandercheck.score(result({"x": ["temp_rate", "hysteresis"]}), t)
    assert r["named"] and not r["alone"]
    r = wandercheck.score(result({"x": [], "y": ["temp_rate"]}), t)  # the right name on the wrong axis
    assert not r["named"] and not r["alone"]
    r = wandercheck.score(result({"x": ["temp_rate"], "z": ["drift"]}), t)  # something else elsewhere
    assert r["named"] and not r["alone"]


def test_the_staircase_of_a_coarser_reading_is_the_readings_not_an_extra_effect():
    t = truth(effects={"x": ["temp_rate"], "y": [], "z": []})
    claims = {"x": ["temp_rate", "temp_quantization"], "y": ["temp_quantization"]}
    r = wandercheck.score(result(claims), t)          # the generator's own fine reading
    assert r["named"] and not r["alone"] and r["staircase_axes"] == []
    r = wandercheck.score(result(claims), dict(t, reading_lsb_c=1.0))
    assert r["named"] and r["alone"] and r["staircase_axes"] == ["x", "y"]
    r = wandercheck.score(result({"y": ["temp_quantization"]}), dict(truth("white"), reading_lsb_c=1.0))
    assert r["no_verdict"] and r["verdict"] == []
    r = wandercheck.score(result({"y": ["temp_quantization", "drift"]}), dict(truth("white"), reading_lsb_c=1.0))
    assert not r["no_verdict"] and r["verdict"] == ["drift"]
    # staircase or not, the planted effect itself must still be named
    r = wandercheck.score(result({"x": ["temp_quantization"]}), dict(t, reading_lsb_c=1.0))
    assert not r["named"]


def test_unexplained_residual_expected_above_1_5x_on_that_axis():
    t = truth()
    r = wandercheck.score(result({}, ratio=(1.6, 1.2, 1.5)), t)
    assert r["unwarned"] == ["x"] and r["floor"] == "white"
    r = wandercheck.score(result({}, ratio=(1.6, 1.2, 1.5), warned=("x",), noise_model=True), t)
    assert r["unwarned"] == [] and r["floor"] == "model"
    r = wandercheck.score(result({}, ratio=(1.6, 1.2, 1.5), warned=("y",)), t)
    assert r["unwarned"] == ["x"]


def test_rms_against_the_oracle_floor_only_where_the_effect_is_in_the_catalogue():
    r = wandercheck.score(result({}, rms=(2.5, 2.0, 2.0)), truth(oracle=2.0))
    assert r["rms_ok"] and r["rms_ratio"]["x"] == pytest.approx(1.25)
    r = wandercheck.score(result({}, rms=(2.51, 2.0, 2.0)), truth(oracle=2.0))
    assert not r["rms_ok"]
    r = wandercheck.score(result({}, rms=(9.0, 2.0, 2.0)), truth("off_catalogue", oracle=2.0, in_cat=False))
    assert r["rms_ok"] and not r["rms_scored"]


def test_a_situation_passes_at_90_percent_of_its_logs():
    t = truth(effects={"x": ["temp_rate"], "y": [], "z": []})
    good = wandercheck.score(result({"x": ["temp_rate"]}), t)
    bad = wandercheck.score(result({}), t)
    ok, codes = wandercheck.situation_cell([good] * 9 + [bad])
    assert ok == {"N": True, "W": True, "R": True} and codes == []
    ok, codes = wandercheck.situation_cell([good] * 8 + [bad] * 2)
    assert not ok["N"] and codes == ["N8/10"]
    ok, codes = wandercheck.situation_cell([good, good, bad])  # 3 logs: all must hold
    assert not ok["N"]


def test_the_set_passes_on_19_of_20_seeds():
    rows = []
    for seed in range(1, 21):
        t = dict(truth("rw_alone"), seed=seed)
        rows.append(dict(wandercheck.score(result({"y": ["drift"]} if seed == 4 else {}), t), name="n"))
    assert wandercheck.report(rows, io.StringIO())
    rows[4] = dict(wandercheck.score(result({"x": ["drift"]}), dict(truth("rw_alone"), seed=5)), name="n")
    out = io.StringIO()
    assert not wandercheck.report(rows, out)
    assert "18/20 (need 19): FAIL" in out.getvalue()


@pytest.mark.parametrize("text, seeds", [("1-3", [1, 2, 3]), ("7", [7]), ("1,4,9-10", [1, 4, 9, 10])])
def test_seed_lists(text, seeds):
    assert wandercheck.parse_seeds(text) == seeds


@pytest.mark.parametrize("text", ["", "3-1", "a", "1-b"])
def test_bad_seed_lists_are_named(text):
    with pytest.raises(ValueError, match="seed"):
        wandercheck.parse_seeds(text)


@pytest.mark.parametrize("step", ["0", "-1", "nan", "11"])
def test_a_reading_step_that_is_no_temperature_step_is_named(step, capsys):
    from tools.gapbench import check
    with pytest.raises(SystemExit) as e:
        check.main(["--set", "wander", "--seeds", "1", "--reading-lsb", step])
    assert e.value.code == 2
    assert "--reading-lsb %s: a temperature step in degC" % step in capsys.readouterr().err
