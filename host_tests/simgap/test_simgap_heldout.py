"""Held-out segments (tools/simgap/fit.py, Problem.evaluate): under a wandering-bias noise model a
held-out segment's fit also leaves out the rows just after it (the whitening filter carries the
segment's data into them), so the segment may only be scored where the rows the fit still has
have been. The log's noise is the run's (TEMPCOMP_SEED)."""
import numpy as np
from seeds import seed

from tools.simgap import noise as N
from tools.simgap.fit import Problem
from tools.simgap.logio import Log


def _log(rng, law):
    # A chamber programme whose hot end (45-60 degC) is visited twice only: at the end of the
    # first of the six held-out segments and in the first half of the second - the rows the
    # filter's memory rule drops when the first is held out. The cold end belongs to the third.
    n, dt = 6000, 3.0
    t = np.arange(n) * dt
    kt = np.array([0, 250, 750, 1000, 1250, 1500, 1750, 2000, 2250, 2500, 2750, 3000, 3500,
                   3750, 4000, 4500, 5000, 5500, 5999]) * dt
    kT = np.array([25, 25, 44.8, 57.3, 60.4, 56, 31.5, 6.5, -9.6, -9.7, -4.3, 8.2, 33.2, 40.1,
                   39.1, 26.7, 14.2, 5.6, 7.4])
    T = np.interp(t, kt, kT)
    ref = np.zeros((n, 3))
    dT = T - 25
    # The sim's own law (offset quadratic in temperature) plus a cubic the sim lacks, the same on
    # every axis, a white noise of 3 LSB and a modest bias random walk (0.5 LSB per step).
    base = 50 + 4 * dT - 0.02 * dT ** 2 + law(dT)
    walk = np.cumsum(rng.normal(0, 0.05, (n, 3)), axis=0)
    out = base[:, None] + walk + rng.normal(0, 3.0, (n, 3))
    return Log("heldout", t, T, out, ref, {"sensor": "gyro"})


def test_a_true_law_is_not_judged_by_extrapolation_under_a_walk():
    rng = np.random.default_rng(seed("simgap_heldout/law"))
    log = _log(rng, lambda d: 1e-3 * d ** 3)
    prob = Problem(log)
    model = N.NoiseModel(9.0, q=0.05 ** 2, dt=3.0)
    for a in range(3):
        prob.set_noise(a, model)
    s = float(np.sqrt(model.filter()[2]))       # the innovations' sd the noise model implies
    for a in range(3):
        sim = prob.evaluate(a, [], withheld=False)["cv"]
        # A cubic lies in every cubic spline's span: with the law in the model, every scored
        # held-out innovation is noise (a 6-sigma bound per row, ~1e-9 per row under the
        # model), and the held-out residual is the innovations' sd; without it the law shows.
        law = prob.evaluate(a, [("offset_temperature", 4)], withheld=False)["cv"]
        scored = law != 0
        assert scored.mean() > 0.7
        assert np.max(np.abs(law)) < 6 * s
        assert np.sqrt(np.mean(law[scored] ** 2)) < 1.15 * s
        assert np.sum(sim ** 2) > np.sum(law ** 2)
