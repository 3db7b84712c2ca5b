"""The wander generator (tools/gapbench/wander.py, written apart from the diagnosis) read through a
whole-degree temperature reading (make_case's reading_lsb: every draw as in the fine case).

Probed on seeds 1-10 of every situation (docs/simgap.md, "Thirteenth round"): the planted effect
named on its axes in 78 of 80 logs, beside temp_quantization (the reading's staircase) where the
axis' temperature slope makes it matter. One miss was a borrow: the loop planted on y, established
there, was borrowed onto x, where temp_quantization and temp_rate were significant held out and the
loop made the held-out segments worse - but fitted x's training log better (a 23 degC wide loop),
so the borrow check (select.Greedy._borrow_holds) never asked the withheld log. It now does when
the borrowed effect makes the axis' held-out segments worse; half A says the loop adds nothing."""
import os

from tools.gapbench import wander, wandercheck


def test_a_loop_is_not_borrowed_onto_an_axis_whose_held_out_segments_it_makes_worse(tmp_path):
    case = wander.make_case("hyst_rw", 4, 0, reading_lsb=1.0)
    truth = case["truth"]
    paths = wander.write_case(case, str(tmp_path), "c")
    res = wandercheck.diagnose_files(paths["train"], paths["withheld"], os.path.join(str(tmp_path), "c.json"))
    got = wandercheck.claims(res)
    planted = [a for a in wander.AXES if truth["effects"][a] == ["hysteresis"]]
    assert planted == ["y"]
    assert [a for a in wander.AXES if "hysteresis" in got[a]] == planted, got
    # nothing else but the reading's staircase anywhere
    assert all(set(got[a]) <= {"hysteresis", "temp_quantization"} for a in wander.AXES), got
    x = [c for c in res["borrow_checks"] if (c["effect"], c["axis"]) == ("hysteresis", "x")]
    assert len(x) == 1 and not x[0]["kept"], x
    assert x[0]["z_heldout"] < -1.96 and x[0]["bic_margin"] < 0, x    # the held-out arm, not the fit's
    assert x[0]["p_withheld_a"] > x[0]["p_pass"]
