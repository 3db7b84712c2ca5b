"""'where' (tools/simgap/where.py): which axes take part in the map. An axis's excess over the
floor is tested against its spread under white noise at that floor, read from the same first
differences the floor comes from. The logs' noise is the run's (TEMPCOMP_SEED)."""
import numpy as np
from seeds import seed
from simgap_synth import make

from tools.simgap import where
from tools.simgap.diagnose import diagnose


def test_excess_spread_under_white_noise_matches_a_simulation():
    # The excess sum(r^2 over the kept rows) - n sigma^2, sigma^2 the mean of d^2 / 2 over the
    # steady pairs, computed here by brute force on 4,000 white-noise series; its spread must be
    # the one _excess_sd derives. Kept rows and steady pairs as a log has them: a pair is lost at
    # every input step (every 25th row) and around rows the outlier rule drops.
    rng = np.random.default_rng(seed("simgap_where/sd"))
    n, reps, sigma = 2000, 4000, 1.7
    rows = rng.random(n) > 0.01
    pairs = rows[1:] & rows[:-1]
    pairs[24::25] = False
    r = rng.normal(0, sigma, (reps, n))
    d = np.diff(r, axis=1)[:, pairs]
    s2 = np.mean(d * d, axis=1) / 2
    excess = np.sum(r[:, rows] ** 2, axis=1) - rows.sum() * s2
    # _excess_sd given the floor read from the series itself (as the diagnosis gives it): its
    # value over that floor squared depends on the rows and pairs only; at the true sigma:
    sd = where._excess_sd(np.sqrt(s2[0]), np.sqrt(s2[0]), rows, pairs) / s2[0] * sigma ** 2
    z = excess / sd
    # 4,000 draws: the mean's standard error is 0.016 and the sd's 1.1 %; the bounds are ~5 of them.
    assert abs(np.mean(z)) < 0.08
    assert 0.94 < np.std(z) < 1.06
    # ... which is well below the sigma^2 sqrt(2n) of n squares against a known sigma.
    assert np.std(excess) < 0.85 * sigma ** 2 * np.sqrt(2 * rows.sum())


def test_an_even_staircase_misfit_gets_a_map_and_white_noise_none():
    # The output follows the true temperature (4 LSB/degC) but the reading is in whole degrees:
    # the sim leaves a sawtooth of +-2 LSB spread evenly over the log, below the noise (2.5 LSB),
    # so no single cell's excess is beyond noise, only the axis's total. The axis must still
    # take part (issue 22: the reduced blind set's 1 degC case at GAP_SEED=98609 got an empty
    # map) - and a log with white noise only gets none.
    log = make(None, n=4000, sigma=2.5, seed=seed("simgap_where/stair"))
    log.temp = np.round(log.temp + 0.37)
    res, _ = diagnose(log)
    assert res["where"] and res["where"][0]["excess"] > 0
    res, _ = diagnose(make(None, n=4000, sigma=2.5, seed=seed("simgap_where/white")))
    assert res["where"] == []
