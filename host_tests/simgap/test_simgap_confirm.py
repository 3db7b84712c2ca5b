"""The withheld log's two halves (tools/simgap/diagnose._withheld_split): half A confirms an
effect stage B refused only for the wander's scale, half B scores. Both must see the log's
whole temperature programme, neither may share a row with the other, and what the JSON says
of them must be what was used."""
import adversarial_logs as A
import numpy as np
from seeds import seeds

from tools.simgap import diagnose as D
from tools.simgap.fit import Problem


def test_halves_alternate_cover_the_temperature_range_and_share_no_row():
    s = seeds("simgap_confirm/split", 1)[0]
    tr, wh = A.make(seed=s), A.make(seed=s + 1)
    prob = Problem(tr, wh)
    inside = D.coverage.covered(tr, wh)
    sp = D._withheld_split(prob, wh, inside)
    a, b = sp["a"], sp["b"]
    assert not (a & b).any()
    covered = prob.withheld.mask & inside
    assert np.array_equal(a | b, covered)
    assert abs(int(a.sum()) - int(b.sum())) <= sp["block_rows"]
    # 20 contiguous blocks alternating A, B: 10 runs of consecutive covered rows in each half
    idx = np.flatnonzero(covered)
    lab = a[idx].astype(int)
    assert int(np.sum(np.diff(lab) != 0)) + 1 == D.SPLIT_BLOCKS
    # each half spans at least 90 % of the covered rows' temperature range (10 blocks spread
    # over the programme; A.make's "cycle" profile sweeps the range more than once)
    T = wh.temp
    span = np.ptp(T[covered])
    for h in (a, b):
        assert np.ptp(T[h]) >= 0.9 * span


def test_the_json_reports_the_split_it_used():
    s = seeds("simgap_confirm/json", 1)[0]
    res, ex = D.diagnose(A.make(seed=s, walk=0.05), A.make(seed=s + 1, walk=0.05))
    sp = res["withheld_split"]
    assert sp["blocks"] == D.SPLIT_BLOCKS
    assert sp["rows_a"] + sp["rows_b"] == int(ex["withheld_rows"].sum()) or sp["scored_on"] == "half B"
    confirmed = any(c["confirmed"] for c in sp["confirmations"])
    assert sp["scored_on"] == ("half B" if confirmed else "whole")
    if confirmed:
        assert int(ex["withheld_rows"].sum()) == sp["rows_b"]
    seen = set()
    for c in sp["confirmations"]:      # every use: refused only by the scale, on the test's level
        assert c["z_chi2"] >= c["z_pass"] > c["z_train"]
        assert 0 <= c["p_withheld_a"] <= 1 and c["p_combined"] <= 1
        # half A is consulted once per (effect, axis); a later stage reuses that answer
        key = (c["effect"], c["axis"])
        assert c["reused"] == (key in seen)
        seen.add(key)
        # the effect must beat both no effect and the clock curve: the larger p decides
        parts = [p for p in (c["p_withheld_a_vs_none"], c["p_withheld_a_vs_curve"]) if p is not None]
        assert c["p_withheld_a"] == max(parts)
    assert res["verdict"] == []         # no effect planted, a walk: nothing named
