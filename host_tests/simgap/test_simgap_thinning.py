"""A log longer than the diagnosis' row budget is diagnosed on every k-th row (rows.stride):
its noise model must still be read at the log's own sample step. The truth is the planted
noise (adversarial_logs: white sigma per row, a bias walk of `walk` per sqrt(row), DT s
between rows), not the tool's own arithmetic."""
import adversarial_logs as A
import numpy as np
import pytest
from seeds import seed

from tools.simgap.diagnose import MAX_ROWS, diagnose


def test_noise_model_of_a_thinned_log_is_read_at_the_log_step():
    n = 3 * MAX_ROWS + 5_000          # stride 4
    sigma, walk = 2.0, 0.02
    res, _ = diagnose(A.make(n=n, seed=seed("simgap_thinning/train"), sigma=sigma, walk=walk),
                      A.make(n=n // 4, seed=seed("simgap_thinning/withheld"), sigma=sigma, walk=walk))
    k = res["rows"]["stride"]["train"]
    assert k == int(np.ceil(n / MAX_ROWS)) == 4
    for ax in "xyz":
        nm = res["noise_model"][ax]
        assert nm["stride"] == k
        assert nm["log_sample_period"] == pytest.approx(A.DT)
        assert nm["sample_period"] == pytest.approx(k * A.DT)
        # Dropping rows keeps each row's white noise: sigma, and N = sigma sqrt(DT) of the
        # log as written (read at the thinned step it would come out sqrt(4) = 2x too big).
        assert nm["white"]["sigma"] == pytest.approx(sigma, rel=0.1)
        assert nm["white"]["N"] == pytest.approx(sigma * np.sqrt(A.DT), rel=0.1)
        # The walk's increments add over the k rows: K = walk / sqrt(DT) per sqrt(s).
        rw, gm = nm["random_walk"], nm["bias_instability"]
        if rw is None:
            # One realisation of a walk over the log (95,000 rows, 190,000 s) sometimes reverts
            # enough that the likelihood prefers a Gauss-Markov bias instead (z in 1 of 147 axes at
            # TEMPCOMP_SEED 1-49, and at 409211: tau_c 5,100-8,400 s). Below tau_c the two are
            # the same process: a GM of sigma_b and tau_c moves by 2 sigma_b^2 dt / tau_c per dt,
            # the walk's K^2 dt. So the stride is checked through that equivalent K (read at
            # the thinned step, tau_c in samples would put it 2x off).
            assert gm is not None, "the planted walk read as neither a walk nor a Gauss-Markov bias"
            K = gm["sigma"] * np.sqrt(2.0 / gm["tau_c"])
            q = K ** 2 * nm["sample_period"]
        else:
            K, q = rw["K"], rw["q_per_sample"]
        # 147 axes at TEMPCOMP_SEED 1-49: K / truth 0.78-1.15 (sd 0.07), so rel 0.5 is ~7 sd.
        assert K == pytest.approx(walk / np.sqrt(A.DT), rel=0.5)
        assert q == pytest.approx(k * walk ** 2, rel=1.0)
