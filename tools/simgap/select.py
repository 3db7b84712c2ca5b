"""Greedy choice of effects under the axis's noise model, on held-out segments of the training
log (never the withheld log, which is scored once afterwards), and the check that a wandering
bias cannot explain the same improvement.

Two stages per greedy step:
  A. every candidate (effect x axis x shape) is fitted by GLS under the noise model of the
     saturated model (the current effects plus the best shape of every family, so structure a
     catalogue effect will take is not counted as noise) and scored on the one-step-ahead
     innovations of held-out segments; the gain must be significant (z counting what
     correlation the innovations keep) on more than one segment;
  B. the winner is claimed on an axis only if the held-out predictive log-likelihood of the
     model with it, under the noise model re-estimated with it in, beats the model without it
     under *its* re-estimated noise model (where a random walk or Gauss-Markov bias may take
     the slow part instead). An effect the wander explains about as well goes under
     not_identifiable with the experiment that would separate them."""
import numpy as np
from scipy import optimize, stats
from scipy.signal import lfilter

from . import noise as N
from .effects import BY_NAME, EFFECTS
from .logio import AXES

Z_SIG = 4.0          # z of the held-out gain (noise autocorrelation counted) an effect needs:
                     # one-sided p 3e-7: ~200 effect x axis x shape candidates are tried
Z_REST = 2.0         # ... and without its best held-out segment the rest still z > 2
MIN_REL = 0.01       # ... and the held-out sum of squares must drop by at least 1 %
MIN_NOISE = 0.02     # ... and by at least 2 % of the innovation variance (not a rounding win)
Z_WANDER = 3.72      # stage B, the likelihood-ratio test of the winner per axis against a
                     # wandering bias: one-sided p 1e-4 after the shape grid's Bonferroni
                     # correction (z of that p-value); a log without effects meets ~10 such
                     # tests (winners per axis and step), so ~1e-3 false claims per log
ALPHA_INSAMPLE = 1e-3  # stage A's in-sample path: family-wise false-positive rate per step
Z_STEP = 1.96        # the unlogged-step check: an effect must still add to the best step of the
                     # offset at an unlogged time at one-sided 2.5 % (it already passed Z_WANDER
                     # against the wander; this asks only whether an off-catalogue cause is an
                     # adequate explanation, so a conventional level, not a family-wise one)
BOOT = 40            # stage B's parametric bootstrap draws (Greedy._bartlett): the Bartlett
                     # scale's standard error about sqrt(2 / (BOOT df)) of itself
BOOT_CMAX = 4.0      # ... needed only where the test passes below this scale: under walk-only
                     # nulls (50 series, docs/simgap.md) the scale was 1.30 mean, 0.33 sd, 2.11 max
BOOT_SEED = 20261128  # fixed, so a diagnosis repeats exactly
RIVAL = 0.8          # a rival this close to the winner, absorbed by it, is not identifiable

# Experiments that separate two effects the data confounds.
NEEDS = {
    frozenset({"hysteresis", "temp_rate"}): "two ramp rates, and soaks reached from above and below",
    frozenset({"offset_temperature", "sensitivity_temperature"}): "several input levels (rates or orientations) at each temperature",
    frozenset({"offset_temperature", "hysteresis"}): "a heating branch as well as a cooling branch",
    frozenset({"offset_temperature", "drift"}): "a soak at constant temperature, or a second temperature cycle",
    frozenset({"offset_temperature", "temp_rate"}): "two ramp rates over the same temperatures",
    frozenset({"drift", "temp_rate"}): "a long soak after power-on, and a repeated ramp",
    frozenset({"drift", "hysteresis"}): "a repeated temperature cycle",
    frozenset({"drift", "turn_on_bias"}): "several power-on runs at the same temperature",
    frozenset({"cross_axis", "g_sensitivity"}): "six orientations while rotating about each axis",
    frozenset({"cross_axis", "nonlinearity"}): "rotation about each axis alone at several rates",
    frozenset({"temp_quantization", "temp_rate"}): "a slower ramp or a finer temperature reading",
    frozenset({"temp_quantization", "offset_temperature"}): "a finer temperature reading",
    frozenset({"supply", "offset_temperature"}): "supply steps at constant temperature",
    frozenset({"supply", "drift"}): "supply steps at constant temperature",
}


# Pairs that mask each other: each alone predicts the held-out segments worse, together
# they predict them (Greedy._joint).
JOINT = (("turn_on_bias", "drift"),)
# ... and the loop on the structure's temperature with the lag that makes that temperature
# (effects.Hysteresis: its lagged shapes exist only once a temp_rate is in): alone, the loop on
# the reading misses its late reversals and the lag takes the loop's branch offsets, and a
# noise model fitted beside them takes the rest (measured: the lagged-loop unit test, no
# verdict at TEMPCOMP_SEED=2 and 11 - a 7 LSB lag and a 12 LSB loop on a 2 LSB floor). Their
# shapes are searched together (Greedy._lagged_pair, written for this one pair: the lag's
# time constants and the loop's (width, lag) shapes).
LAGGED = ("temp_rate", "hysteresis")


def needs(a, b):
    return NEEDS.get(frozenset({a, b}), "an experiment that varies them independently")


def _bic(res, df):
    """BIC of a GLS fit from its in-sample innovations (Gaussian, variance profiled out) with
    df free columns (the base's columns, common to the fits it is compared with, left out)."""
    n = len(res["ins"])
    return 0.5 * n * np.log(max(float(np.sum(res["ins"] ** 2)), 1e-300)) + 0.5 * df * np.log(n)


def _same_shape(a, b):
    """Shapes are None, numbers, strings or tuples of them; a width and a (width, lag) pair
    must compare unequal rather than broadcast."""
    if isinstance(a, tuple) or isinstance(b, tuple):
        return (isinstance(a, tuple) and isinstance(b, tuple) and len(a) == len(b)
                and all(_same_shape(x, y) for x, y in zip(a, b)))
    if a is None or b is None or isinstance(a, str) or isinstance(b, str):
        return a == b
    return float(a) == float(b)


LAG_LOOP = frozenset({"temp_rate", "hysteresis"})   # the pair Greedy._told_apart compares


def _drop_simpler(trials):
    """Forget the second-chance shapes (trial["simpler"], from Greedy._try) once a step is
    decided: the trials stay in Greedy.steps and .record for the whole diagnosis, and each
    simpler shape holds a second set of residual arrays as long as the log."""
    for tr in trials.values():
        for v in tr.values():
            v.pop("simpler", None)


def _grid_peak(L):
    """Maximum over a grid (rows) of each column of L: the parabola's peak through the best
    point and its neighbours where the best point is inside the grid (then the peak lies
    within half a step of it), else the best point itself. At the grid's edge the parabola
    through three points of a rising profile extrapolates without bound (measured on the
    full set's offset_temperature + drift pair, x: one of 40 bootstrap draws at 2 LR* 94
    where the rest reached 9, which alone took the Bartlett scale from 2.0 to 4.1)."""
    top = np.argmax(L, axis=0)
    j = np.clip(top, 1, L.shape[0] - 2)
    c = np.arange(L.shape[1])
    a, b, d = L[j - 1, c], L[j, c], L[j + 1, c]
    den = a - 2 * b + d
    peak = np.where((den < 0) & (top == j),
                    b - (d - a) ** 2 / (8 * np.where(den < 0, den, -1.0)), b)
    return np.maximum(L.max(axis=0), peak)


class Greedy:
    def __init__(self, prob, sigma):
        self.prob = prob
        self.sigma = sigma                      # white floor per axis of the training log
        self.state = {a: [] for a in range(3)}  # axis -> [(effect, shape)]
        self.steps = []
        self.untried = {}
        self.avail = {}
        self.wander = []                        # (effect, axis, z, kind of wander, shape)
        self.swapped = []                       # effects a confusable rival replaced
        self.borrowed = set()                   # (effect, axis) taken in as established elsewhere
        self.stepped = []                       # effects an unlogged step explains as well
        self.step_rivals = []                   # half A's say on them (unlogged)
        self.joint = []                         # masking pairs added together (_joint)
        self._joint_refused = {}                # (pair, axis) -> state length the wander refused it at
        self.confirm = None                     # half A of the withheld log (diagnose sets it)
        self.step_rival = None                  # half A against a moved unlogged step (same)
        self.confirmations = []                 # every use of it (_confirm)
        self.borrow_checks = []                 # borrowed effects put to half A (_borrow_holds)
        self._consulted = {}    # (effect, axis) -> half A's p and its two parts (_consult)
        self._ncand = 1
        self._noise_cache = {}
        self._boot_cache = {}
        self.noise_info = {}
        for e in EFFECTS:
            ax = []
            for a in range(3):
                ok, why = e.usable(prob.ctx, prob.train, a)
                if ok:
                    ax.append(a)
                else:
                    self.untried.setdefault(e.name, why)
            if ax:
                self.avail[e.name] = ax
                self.untried.pop(e.name, None)
        self.cur = {a: prob.evaluate(a, [], withheld=False) for a in range(3)}

    # -- noise models -------------------------------------------------------------------

    def noise_for(self, axis, blocks):
        """Noise model of sim + blocks on the training log (effects in) by maximum profile
        likelihood: for every candidate noise model the effects' coefficients are re-fitted
        by GLS under it (so a walk and an effect compete for the same slow part), the Allan
        fit of the ordinary least-squares residual giving the starting values. The Allan
        deviation reported is the final GLS residual's. Cached per block list."""
        key = (axis, tuple((n, _key(s)) for n, s in blocks))
        if key in self._noise_cache:
            return self._noise_cache[key]
        p = self.prob
        pt = p.train
        dt = p.ctx.dt
        s2 = self.sigma[axis] ** 2
        r = p.full_residual(pt, axis, blocks, model=N.NoiseModel.white(self.sigma[axis], dt))[pt.mask]
        fit = N.fit_allan(N.allan(r - np.mean(r), dt))

        def ll_of(q, g2=0.0, phi=0.0):
            return p.loglik(axis, blocks, N.NoiseModel(s2, q, g2, phi, dt))

        model, lls = N.search(ll_of, int(pt.mask.sum()), s2, dt, fit)
        r = p.full_residual(pt, axis, blocks, model=model)[pt.mask]
        r = r - np.mean(r)
        ad = N.allan(r, dt)
        info = {"model": model, "allan": ad, "allan_fit": N.fit_allan(ad),
                "loglik": {k: v[0] for k, v in lls.items()},
                "params": [v[1] for v in lls.values()], "s2": s2,
                "profile": max(v[0] for v in lls.values()), "resid": r}
        self._noise_cache[key] = info
        return info

    def _effect_df(self, axis, name, shape):
        """Free parameters an effect adds on an axis: its columns, or one constant per run
        beyond the base intercept."""
        e = BY_NAME[name]
        if e.per_run:
            return max(1, len(np.unique(self.prob.runs_m)) - 1)
        return int(e.columns(self.prob.ctx, self.prob.train, shape, axis).shape[1])

    def _wander_check(self, axis, without, with_, name, z_pass=Z_WANDER):
        """Can a wandering bias explain the effect? A likelihood-ratio test in the state-space
        model: the profile likelihood of sim + with_ against sim + without, each maximised
        over its own noise model (white, random walk, Gauss-Markov: whatever slow part the
        effect would explain, the walk may take instead). Under no effect, twice the gain is
        asymptotically chi-squared with the effect's free parameters as degrees of freedom;
        with the noise model profiled and a slow column against a walk (near the boundary)
        it is larger, so where the test would pass, the reference is scaled by the
        parametric bootstrap's Bartlett factor (_bartlett). The shape was the best of the
        family's grid, so the p-value is Bonferroni-corrected for the grid. Returns (z, gain
        in nats, noise info without the effect): z is the normal deviate of the corrected
        p-value, compared with z_pass (Z_WANDER, or Z_STEP for the unlogged-step check)."""
        shape = with_[-1][1] if with_ and with_[-1][0] == name else dict(with_)[name]
        df = self._effect_df(axis, name, shape)
        grid = max(1, len(BY_NAME[name].shapes_given(self.prob.ctx, without)))
        return self._lr_z(axis, without, with_, df, grid, z_pass)

    def _lr_z(self, axis, without, with_, df, grid, z_pass=Z_WANDER):
        """The likelihood-ratio test of _wander_check for block lists without and with_ (df
        more free parameters, the best of a grid of that many shapes), its reference scaled
        by _bartlett where that decides against z_pass: (z, gain in nats, noise info of
        without)."""
        i0 = self.noise_for(axis, without)
        i1 = self.noise_for(axis, with_)
        # Each model also at the other's maximising noise parameters: the searches are local
        # (and a Gauss-Markov term is searched where its own Allan fit shows one), so this
        # keeps the two maxima comparable - the nested model never beats the larger one.
        dt = self.prob.ctx.dt

        def best(info, other, blocks):
            ll = info["profile"]
            for q, g2, phi in other["params"]:
                f = info["s2"] / other["s2"] if other["s2"] > 0 else 1.0
                m = N.NoiseModel(info["s2"], q * f, g2 * f, phi, dt)
                ll = max(ll, self.prob.loglik(axis, blocks, m)[0])
            return ll

        gain = float(best(i1, i0, with_) - best(i0, i1, without))
        def z_of(c):
            p = min(1.0 - 1e-12, float(stats.chi2.sf(2 * max(gain, 0.0) / c, max(1, df))) * grid)
            return float(stats.norm.isf(max(p, 1e-300)))     # finite: p is capped below 1

        z = z_of(1.0)
        if z >= z_pass and z_of(BOOT_CMAX) < z_pass:
            # Near the boundary (a slow column against a profiled walk) the chi-squared
            # reference is anti-conservative: calibrate it by the parametric bootstrap's
            # Bartlett-type scale, computed only where it can change the answer (c >= 1
            # only lowers z; a gain that passes even at BOOT_CMAX x the chi-squared is
            # far beyond any scale measured, and is not bootstrapped - the cost bound on
            # long logs, whose real effects gain thousands of nats).
            z = z_of(self._bartlett(axis, without, with_, i0))
            if z < z_pass and gain > 0 and self.confirm is not None:
                z = self._confirm(axis, without, with_, z, z_of(1.0), gain, z_pass)
        return z, gain, i0

    def _confirm(self, axis, without, with_, z, z_chi2, gain, z_pass=Z_WANDER):
        """An effect refused only by the wander scale (it passes at the chi-squared reference,
        not at the bootstrap's Bartlett scale: the null's fitted walk may BE the effect, which
        one power-on cannot tell from a slow law) is put to half A of the withheld log, its
        own power-on with its own walk: self.confirm returns the one-sided p-value of the
        predictive log-likelihood gain there (coefficients frozen from the training fit, each
        model under its own noise model; diagnose._withheld_confirm). The two p-values are
        independent under the null (different logs, different noise draws), so Fisher's
        method combines them: -2 (ln p_train + ln p_A) ~ chi-squared with 4 df, claimed at the
        level of the test that refused it (z of the combined p >= z_pass: Z_WANDER, one-sided
        1e-4, for stage B, the backward check and the nested families; Z_STEP for the
        unlogged-step check, where the walk's scale refuses a drift beside the best step just
        the same - measured at wander aging seed 2, y: z 3.23 at the chi-squared, 1.61 at the
        Bartlett scale). Half A is consulted once per (effect, axis) per diagnosis, and must
        prefer the effect over a shapeless clock-tied curve as well as over no effect
        (_consult). Returns the combined z where it passes, else the training z."""
        added = [b for b in with_ if b not in without]
        name = added[-1][0] if added else with_[-1][0]
        key = (name, axis)
        # One consultation of half A per (effect, axis) per diagnosis: the same effect put to
        # the same half again at a later stage (prune, reshape, the step check) would be a
        # fresh chance at the same level on the same rows (a multiple test with no
        # correction). Its first answer stands for every later stage.
        reused = key in self._consulted
        if not reused:
            self._consulted[key] = self._consult(axis, without, with_, name)
        p_a, parts = self._consulted[key]
        if p_a is None:
            return z
        p_t = float(stats.norm.sf(z))
        p_f = float(stats.combine_pvalues([max(p_t, 1e-300), max(p_a, 1e-300)],
                                          method="fisher").pvalue)
        z_f = float(stats.norm.isf(max(p_f, 1e-300)))
        self.confirmations.append({
            "effect": name, "axis": axis,
            "z_train": z, "z_chi2": z_chi2, "gain": float(gain), "p_train": p_t,
            "p_withheld_a": float(p_a), **parts, "reused": reused,
            "p_combined": p_f, "z_pass": z_pass,
            "confirmed": bool(z_f >= z_pass)})
        return z_f if z_f >= z_pass else z

    def _consult(self, axis, without, with_, name):
        """Half A's one-sided p for the effect `name` (added in with_ to without), against
        two alternatives, each with its coefficients frozen from training and under its own
        noise model: no effect (without), and - unless the unlogged step is already in
        without (the unlogged-step check, whose own null is then the alternative) - without
        plus effects.ClockCurve, a shapeless smooth curve in clock time fitted on training.
        The withheld log is its own power-on, but an off-catalogue cause (humidity, a
        neighbour switching on) may repeat there on the same schedule, so any clock-tied
        term that takes part of it predicts half A better than nothing (measured: the
        adversarial humidity bump on y named `drift`, p_A 0.005-0.017 against nothing). A
        catalogue effect is confirmed only where it also predicts A better than the
        shapeless curve: a real law predicts a repeat with its few coefficients, while the
        curve's extra freedom fitted the training log's own walk. The effect must beat both
        alternatives: an intersection-union test, whose p is the larger of the two, valid at
        the same level with no correction (each component test is at that level). The
        unlogged step itself (effects.UnloggedStep) was tried first as this alternative and
        changed nothing (p against it within 1 % of p against nothing on every humidity log:
        under a walk a frozen step is one innovation). Returns (p, its two parts); p is None
        where A has too few rows."""
        p_a = self.confirm(axis, without, with_)
        parts = {"p_withheld_a_vs_none": p_a, "p_withheld_a_vs_curve": None}
        if p_a is None or BY_NAME[name].per_run or any(
                b == "unlogged_step" for b, _ in without):
            return p_a, parts
        curve = BY_NAME["clock_curve"]
        p_c = self.confirm(axis, without + [(curve.name, curve.DEG)], with_)
        parts["p_withheld_a_vs_curve"] = p_c
        return (p_a if p_c is None else max(p_a, p_c)), parts

    def _bartlett(self, axis, without, with_, i0):
        """Bartlett-type scale of the likelihood-ratio statistic of with_ against without,
        by a parametric bootstrap under the fitted null: BOOT series of the null's fitted
        values plus noise drawn from its fitted noise model (white + random walk +
        Gauss-Markov), both models re-fitted on each with the noise model profiled, c = the
        mean of twice the log-likelihood ratio / its chi-squared mean (the degrees of
        freedom). The effect's shape stays the one chosen (its grid is Bonferroni-corrected
        apart). The profile is maximised over a grid of noise models (walk ratio on a
        log grid around both fits' values, refined by a parabola through the best three;
        the Gauss-Markov term at both fits' phi), all BOOT series filtered together per grid
        point, so its cost is a few filter passes of the design, not BOOT noise searches.
        c is floored at 1: the scale only ever makes the test stricter (a c below 1 with
        BOOT draws is within its standard error, about sqrt(2 / (BOOT df)), of 1).

        Why the null's noise model, although where the effect is real that fit has put the
        effect into its walk (a larger walk, a larger c: the restricted-estimate bootstrap's
        lost power, the full set's offset_temperature + drift pair on x, c 2.40): the
        alternative's fit is no cure. A slow column takes part of a true walk, so under the
        null the fit with the effect in reads a smaller walk (or a Gauss-Markov term and no
        walk), and draws from it under-state the statistic's spread. Measured by direct null
        simulation (series = a temperature law + white noise + a walk, the aging line
        offered; host_tests/simgap/test_simgap_bootstrap.py is its small version): 1,000
        draws at walk q/s2 1e-3, calibrated p below 1 % / 5 % in 1.6 % / 9.2 % with the
        null's draws, 8.1 % / 17.2 % with the alternative's (the chi-squared alone 16.9 % /
        37.3 %); at q/s2 2e-4 (300 draws) 4.7 % / 14.3 % against 25 % / 41 %. The smaller
        of the two walks is the alternative's in 99 % of those draws, and a bootstrap bias
        correction of its walk did not help (7.7 % / 18.7 %): the alternative's fit often
        has no walk at all to correct."""
        key = (axis, tuple((b, _key(s)) for b, s in without),
               tuple((b, _key(s)) for b, s in with_))
        if key not in self._boot_cache:
            self._boot_cache[key] = self._bartlett_uncached(axis, without, with_, i0)
        return self._boot_cache[key]

    def _bartlett_uncached(self, axis, without, with_, i0):
        i1 = self.noise_for(axis, with_)
        return self._bartlett_scale(axis, without, with_, i0, i1, i0["model"])

    def _bartlett_scale(self, axis, without, with_, i0, i1, mb, boot=BOOT, seed=BOOT_SEED):
        """The scale of _bartlett with the bootstrap noise drawn from model mb (the null's
        fitted values always the mean): _bartlett passes the null's fitted noise model, the
        size simulations of its docstring others."""
        p = self.prob
        dt = p.ctx.dt
        m0 = i0["model"]
        mask = p.train.mask
        y = p._ymasked(axis)
        fitted = y - p.full_residual(p.train, axis, without, model=m0)[mask]
        n = len(y)
        rng = np.random.default_rng(seed)
        Y = fitted[:, None] + rng.normal(0.0, np.sqrt(mb.s2), (n, boot))
        if mb.q > 0:
            Y += np.cumsum(rng.normal(0.0, np.sqrt(mb.q), (n, boot)), axis=0)
        if mb.g2 > 0:
            d = rng.normal(0.0, np.sqrt(mb.g2 * (1 - mb.phi ** 2)), (n, boot))
            d[0] = rng.normal(0.0, np.sqrt(mb.g2), boot)
            Y += lfilter([1.0], [1.0, -mb.phi], d, axis=0)
        per0 = any(BY_NAME[b].per_run for b, _ in without)
        per1 = any(BY_NAME[b].per_run for b, _ in with_)
        X0 = p._raw_design(axis, without, tuple((b, _key(s)) for b, s in without), per0)
        X1 = p._raw_design(axis, with_, tuple((b, _key(s)) for b, s in with_), per1)
        s2 = m0.s2
        qs = [m.q / m.s2 for m in (m0, i1["model"]) if m.q > 0]
        lq = np.log(qs) if qs else np.log([1e-3 / n])
        lgrid = np.arange(float(lq.min()) - 3.0, float(lq.max()) + 3.0 + 1e-9, 0.5)
        gms = [(0.0, 0.0)] + [(m.g2 / m.s2, m.phi) for m in (m0, i1["model"]) if m.g2 > 0]

        def ll(X, q, g2, phi):
            model = N.NoiseModel(s2, q * s2, g2 * s2, phi, dt)
            st = p.starts(p.train, axis, model)
            cols = [X]
            if model.walks and len(st) > 1:
                cols.append(N.level_columns(n, st, model)[:, 1:])
            k = sum(c.shape[1] for c in cols)
            Z = N.whiten(np.column_stack(cols + [Y]), model, st)
            U = Z[:, k:]
            if k:
                Q = np.linalg.qr(Z[:, :k])[0]
                U = U - Q @ (Q.T @ U)
            return -0.5 * n * (np.log(2 * np.pi * np.maximum(np.sum(U * U, axis=0) / n, 1e-300)) + 1)

        def profile(X):
            out = []
            for g2, phi in gms:
                out.append(ll(X, 0.0, g2, phi)[None])
                L = np.array([ll(X, np.exp(v), g2, phi) for v in lgrid])
                out.append(_grid_peak(L)[None])
            return np.max(np.concatenate(out), axis=0)

        lr2 = 2 * np.maximum(profile(X1) - profile(X0), 0.0)
        df = max(1, X1.shape[1] - X0.shape[1])
        return max(1.0, float(np.mean(lr2)) / df)

    # -- stage A ----------------------------------------------------------------------

    def _try(self, name, axis):
        """Best shape of one effect on one axis over the current state, under the axis's
        current (saturated) noise model: the shape is a model order, chosen by BIC of the GLS
        fit (its in-sample innovations' likelihood less 0.5 ln n per column) - not by the
        held-out segments, which cannot judge an effect that lives in one of them (a warm-up
        after the log's one power-on). Returns the trial with its held-out innovations."""
        e = BY_NAME[name]
        self.prob.prime(axis, self.state[axis])
        shapes = e.shapes_given(self.prob.ctx, self.state[axis])
        scored = []
        for shape in shapes:
            res = self.prob.evaluate(axis, self.state[axis] + [(name, shape)], withheld=False)
            df = self._effect_df(axis, name, shape)
            scored.append((_bic(res, df), len(scored), shape, res, df))
        _, _, shape, res, df = min(scored, key=lambda b: b[:2])
        trial = {"name": name, "shape": shape, "res": res, "df": df, "grid": len(shapes)}
        # The best shape with fewer columns, kept as a second chance (_simpler): on a grid
        # of time constants the richer shape's extra column often wins the BIC by fitting
        # the first minutes after power-on, then predicts a held-out first segment wildly.
        fewer = [b for b in scored if b[4] < df]
        if fewer:
            _, _, s2, r2, d2 = min(fewer, key=lambda b: b[:2])
            trial["simpler"] = {"name": name, "shape": s2, "res": r2, "df": d2, "grid": len(shapes)}
        return trial

    def _simpler_heldout(self, v, axis, tau, sd):
        """Stage A's second chance: a trial whose BIC-best shape fails the held-out test is
        judged again at the best shape with fewer columns (trial["simpler"], from _try),
        which replaces it if that passes. Measured at wander `aging` seed 107: a straight
        aging line on z chosen as exponential (tau 365 s) + line by the BIC, held-out z -3.6
        (the exponential's coefficient, fitted without the first segment, extrapolates
        wildly into it); the line alone z 325. Two tests at z > 4 instead of one per trial:
        the false-positive rate of stage A at most doubles (one-sided 3e-5 each), and stage
        B's Bonferroni factor already counts every shape of the grid."""
        alt = v.get("simpler")
        if v["significant"] or alt is None:
            return v
        self._judge(alt, axis, tau, sd)
        if not alt["significant"]:
            return v
        return dict(alt, simpler=None, richer=v["shape"])

    def _simpler_wander(self, v, axis, name, tau, sd):
        """Stage B's second chance, like _simpler_heldout's for stage A: a trial the wander
        check refuses at its BIC-best shape is tested at the best shape with fewer columns,
        which replaces it if it passes (the same Bonferroni factor for the grid: the shape
        is still one of its shapes). Measured at wander `aging` seed 111: a line on z as
        exponential + line, z 3.64, the line alone z 4.45 (which the unlogged-step check
        then refuses: one power-on). The simpler shape must pass stage A
        too where the richer one did (judged under the step's (sd, tau)). Returns the trial
        kept (its z_wander and loglik_gain set)."""
        alt = dict(v["simpler"], simpler=None, richer=v["shape"])
        if "significant" not in alt:
            self._judge(alt, axis, tau, sd)
        if v["significant"] and not alt["significant"]:
            return v
        self._refined(alt, axis, name)
        z2, gain2, _ = self._wander_check(axis, self.state[axis], self.state[axis] + [(name, alt["shape"])],
                                          name)
        if z2 < Z_WANDER:
            return v
        alt.update(z_wander=z2, loglik_gain=gain2)
        return alt

    def _refined(self, v, axis, name):
        """The trial v with its shape refined over the axis's current state (_refine); its
        in-sample residuals evaluated again only if the shape moved. Returns v, updated."""
        shape = self._refine(axis, self.state[axis], name, v["shape"])
        if not _same_shape(shape, v["shape"]):
            v.update(shape=shape, res=self.prob.evaluate(axis, self.state[axis] + [(name, shape)],
                                                         withheld=False))
        return v

    def _localised(self, name, i0, i1):
        """Does one held-out segment hold most of the evidence for the effect? True when more
        than half of the change it makes to the in-sample innovations (its fitted part after
        the whitening filter) lies in one segment - a settling after the log's one
        power-on, say: the other segments cannot predict it, so held-out prediction cannot
        judge it, and the in-sample likelihood ratio does (stage B and the withheld log then
        judge it like any other)."""
        if BY_NAME[name].per_run:
            return None
        d2 = (i0 - i1) ** 2
        tot = float(np.sum(d2))
        if tot <= 0:
            return None
        folds = self.prob.fold_m
        share = [float(np.sum(d2[folds == f])) for f in range(self.prob.nfold)]
        f = int(np.argmax(share))
        return f if share[f] > 0.5 * tot else None

    def _refine(self, axis, others, name, shape, model=None):
        """The shape's continuous parameter (time constant, width) by maximum likelihood of
        the GLS fit under the axis's noise model, between the grid's neighbours (scipy's
        bounded Brent search): a grid spaced by 2x leaves a warm-up or a lag mis-timed by
        up to 40 %, which shows as a residual of its own."""
        c = BY_NAME[name].continuous(self.prob.ctx, shape)
        if c is None:
            return shape
        x0, lo, hi, build = c
        model = model or self.prob.noise[axis]

        def f(x):
            return -self.prob.loglik(axis, others + [(name, build(x))], model)[0]

        o = optimize.minimize_scalar(f, bounds=(lo, hi), method="bounded",
                                     options={"xatol": 0.02, "maxiter": 14})
        return build(o.x) if o.fun < f(x0) else shape

    def _judge(self, v, axis, tau, sd):
        """Significance of one trial. The gain sum(r0^2 - r1^2) = sum(delta (2 r1 + delta)) is
        random through the noise in r1: its variance is 4 sd^2 tau sum(delta^2), with sd and
        tau (integrated autocorrelation time) of the saturated model's innovations - about 1
        when the noise model is right, longer when something slow is left that no candidate
        and no noise term predicts.

        That variance is too small where r1 holds more than the noise model's innovations:
        a held-out segment is predicted from coefficients the other segments fitted, so its
        r1 carries their estimation error, smooth along the segment, and 2 delta r1 then
        keeps its sign for tens to hundreds of rows (measured on wander logs whose guard
        refused a planted lag or loop: autocorrelation times of 20-250 rows where the
        innovations' is 1; the loss was spread over the segment, not in its first rows,
        where the filter has no state). The guard of the in-sample path (z_other below)
        therefore takes each segment's variance as the larger of that and the HAC
        estimate from the held-out products themselves, sum(p^2) x their own
        autocorrelation time (p = 2 delta r1 less its segment mean; segments independent).
        Only the guard: the held-out path's z and z_rest keep the in-sample variance, which
        (measured) would otherwise lose the loop at wander seed 24."""
        r0, r1 = self.cur[axis]["cv"], v["res"]["cv"]
        ss0, ss1 = float(np.sum(r0 ** 2)), float(np.sum(r1 ** 2))
        gain = r0 ** 2 - r1 ** 2
        delta = r0 - r1
        folds = self.prob.cv_fold

        def z_of(sel):
            den = 2 * sd * np.sqrt(tau * float(np.sum(delta[sel] ** 2)))
            return float(np.sum(gain[sel]) / den) if den > 0 else 0.0

        def z_segments(segs):
            g = var = 0.0
            for f in segs:
                s = folds == f
                p = 2 * delta[s] * r1[s]
                if not p.size:
                    continue
                p = p - p.mean()
                g += float(np.sum(gain[s]))
                var += max(4 * sd ** 2 * tau * float(np.sum(delta[s] ** 2)),
                           float(np.dot(p, p)) * N.autocorr_time(p))
            return g / np.sqrt(var) if var > 0 else 0.0

        z = z_of(slice(None))
        # No single segment may carry the finding: with the segment that gains most left
        # out, the rest must still point the same way.
        fg = np.array([gain[folds == f].sum() for f in range(self.prob.nfold)])
        rest = folds != int(np.argmax(fg))
        z_rest = z_of(rest) if rest.any() else 0.0
        s2 = float(v["res"]["s2"])
        per_run = BY_NAME[v["name"]].per_run
        heldout = bool(z > Z_SIG and (z_rest > Z_REST or per_run) and ss0 - ss1 > MIN_REL * ss0
                       and ss0 - ss1 > MIN_NOISE * len(r0) * s2)
        # An effect whose information one held-out segment holds (see _localised) is judged
        # in-sample under the same noise model instead: the likelihood ratio of the GLS fits
        # (chi-squared with the effect's columns as degrees of freedom), Bonferroni-corrected
        # for the shape grid and for every effect x axis tried at this step.
        i0, i1 = self.cur[axis]["ins"], v["res"]["ins"]
        lr = 0.5 * len(i0) * np.log(max(float(np.sum(i0 ** 2)), 1e-300) /
                                    max(float(np.sum(i1 ** 2)), 1e-300))
        p_lr = float(stats.chi2.sf(2 * max(lr, 0.0), v["df"])) * v["grid"] * self._ncand
        # ... unless the other held-out segments contradict it (their gain significantly
        # negative, one-sided 2.5 %, its variance from the held-out products as the
        # docstring says): a shape that fits one stretch and predicts the others
        # worse is a fit to something else (an unlogged cause), not that effect. The segment
        # that holds the evidence is left out of this check: predicted from the others, a
        # warm-up's columns extrapolate wildly there, which says nothing against it.
        lf = self._localised(v["name"], i0, i1)
        local = lf is not None
        z_other = 0.0
        if local:
            z_other = z_segments([f for f in range(self.prob.nfold) if f != lf])
        significant = (p_lr < ALPHA_INSAMPLE and z_other > -Z_REST) if local else heldout
        score = 2 * lr if local else (ss0 - ss1) / max(s2, 1e-300)
        v.update(cv_before=r0, rms_before=float(np.sqrt(ss0 / len(r0))), rms_after=float(np.sqrt(ss1 / len(r1))),
                 t=z, p=float(stats.norm.sf(z)), z_rest=z_rest, tau=tau, lr_insample=float(lr),
                 p_insample=min(1.0, p_lr), heldout_significant=heldout, local=local,
                 z_heldout_others=z_other,
                 significant=significant, score=score)
        return v

    def _saturated(self, trials, axis):
        return list(self.state[axis]) + [(n, tr[axis]["shape"]) for n, tr in trials.items()
                                         if axis in tr]

    def _noise_stats(self, trials, axis):
        """(sd, autocorrelation time) of the saturated model's in-sample innovations."""
        blocks = self._saturated(trials, axis)
        r = self.prob.evaluate(axis, blocks, withheld=False)["ins"]
        r = r - np.mean(r)
        return float(np.std(r)), N.autocorr_time(r)

    def _set_saturated_noise(self, trials):
        """Noise model per axis from the saturated model's residual, then the trials again
        under it (their GLS fits and innovations change with the filter)."""
        changed = False
        for a in range(3):
            if not any(a in tr for tr in trials.values()):
                continue
            info = self.noise_for(a, self._saturated(trials, a))
            self.noise_info[a] = {"saturated": info}
            if info["model"].key() != self.prob.noise[a].key():
                self.prob.set_noise(a, info["model"])
                changed = True
        return changed

    def run(self):
        """Add the best significant effect (on the axes where it is significant and where the
        wander cannot explain it) until none is left; an effect already added on some axes
        stays a candidate for the others."""
        pool = {n: list(ax) for n, ax in self.avail.items()}
        chosen = []
        self.record = {}          # (effect, axis) -> the trial that added it
        rejected = {}             # (effect, axis) -> state length when the wander check refused it
        first = True
        while True:
            trials = {n: {a: self._try(n, a) for a in ax} for n, ax in pool.items() if ax}
            if first:
                first = False
                if self._set_saturated_noise(trials):
                    self.cur = {a: self.prob.evaluate(a, self.state[a], withheld=False)
                                for a in range(3)}
                    trials = {n: {a: self._try(n, a) for a in ax} for n, ax in pool.items() if ax}
            self._ncand = max(1, sum(len(tr) for tr in trials.values()))
            nstats = {}                 # axis -> (sd, tau) of the saturated model's innovations
            for a in range(3):
                if not any(a in tr for tr in trials.values()):
                    continue
                sd, tau = nstats[a] = self._noise_stats(trials, a)
                for n, tr in trials.items():
                    if a in tr:
                        self._judge(tr[a], a, tau, sd)
                        tr[a] = self._simpler_heldout(tr[a], a, tau, sd)
                        # Turned down by the wander check with this same state: it stays in the
                        # saturated model (its structure is not noise) but may try again only
                        # once another effect has entered on the axis.
                        if rejected.get((n, a)) == len(self.state[a]):
                            tr[a]["significant"] = False
            scores = {n: sum(v["score"] for v in tr.values() if v["significant"])
                      for n, tr in trials.items()}
            sig = [n for n in trials if any(v["significant"] for v in trials[n].values())]
            step = {"trials": trials, "scores": scores, "chosen": None}
            self.steps.append(step)
            if not sig:
                _drop_simpler(trials)
                if self._joint(trials, rejected, nstats, pool):
                    continue
                break
            win = self._told_apart(max(sig, key=lambda n: scores[n]), sig, trials, step)
            added = False
            established = any(w["significant"] for w in trials[win].values())
            for a, v in trials[win].items():
                # An effect established on some axes (significant there at this step) is a
                # candidate on every other axis too, judged there by the likelihood-ratio
                # test below alone: it is the same physical cause (a power-on shifts every
                # axis at once; a warm-up settles on all of them), and the held-out segments
                # cannot judge an effect that only helps together with one not yet in (a
                # per-run constant beside an unmodelled warm-up makes the segments' runs
                # worse, and the warm-up alone is masked by the runs' steps). The test's
                # false-positive rate (Z_WANDER) holds for it as for any other claim.
                take = v["significant"] or established
                if not take:
                    continue
                self._refined(v, a, win)
                if not v["significant"] and not self._borrow_holds(a, win, v, trials):
                    continue
                with_ = self.state[a] + [(win, v["shape"])]
                z, gain, i0 = self._wander_check(a, self.state[a], with_, win)
                v.update(z_wander=z, loglik_gain=gain)
                if z < Z_WANDER and v.get("simpler") is not None:
                    v = trials[win][a] = self._simpler_wander(v, a, win, *nstats[a])
                    z, gain = v["z_wander"], v["loglik_gain"]
                if z < Z_WANDER:
                    rejected[(win, a)] = len(self.state[a])
                    if v["significant"]:
                        self.wander.append({"effect": win, "axis": a, "z": z, "gain": gain,
                                            "kind": N.describe(i0["model"], self.sigma[a]),
                                            "shape": v["shape"]})
                    continue
                pool[win].remove(a)
                if not v["significant"]:
                    self.borrowed.add((win, a))
                self.state[a].append((win, v["shape"]))
                self.cur[a] = v["res"]
                self.record[(win, a)] = v
                added = True
            if added:
                step["chosen"] = win
                if win not in chosen:
                    chosen.append(win)
            _drop_simpler(trials)
        # Effects (or axes) never added: their trial against the final model.
        for n, tr in self.steps[-1]["trials"].items():
            for a, v in tr.items():
                self.record.setdefault((n, a), v)
        for st in self.steps:
            for n, tr in st["trials"].items():
                for a, v in tr.items():
                    self.record.setdefault((n, a), v)
        return chosen

    def _borrow_holds(self, a, win, v, trials):
        """May the effect win, established on other axes, be borrowed onto axis a (where its
        held-out trial v is not significant)? Not where an effect that is significant on a's
        held-out segments at this step stands against it and the training log does not back
        the borrow - the rival fits a's training log better (profile likelihood less 0.5 ln n
        per column, each at its refined shape: _told_apart's comparison), or the borrowed
        effect makes a's held-out segments worse (held-out z below -Z_STEP) - unless half A of
        the withheld log says the borrowed effect adds to that rival (one-sided p of the
        per-row predictive gain of state + rival + win over state + rival, coefficients
        frozen from training, below the unlogged-step check's level: it asks whether the
        rival is an adequate explanation, as that check does). With no half A (no withheld
        log, or too few of its rows inside the training coverage) it is not borrowed there:
        one log cannot tell them apart. Measured: on a whole-degree reading the loop,
        established on x, was borrowed onto y and z where temp_quantization was significant
        (z 20-23) and fitted better (6-33 in BIC units); the loop then took the staircase's
        structure (host_tests/simgap, the coarse-reading tests, TEMPCOMP_SEED=3 and 710081).
        On the wander generator with a 1 degC reading (hyst_rw seed 4) a loop 23 degC wide,
        borrowed from y, fitted x better than temp_rate (significant there, as was
        temp_quantization, z 21.0) by 131 BIC units while it made x's held-out segments
        worse (z -10.4); half A says it adds nothing to temp_rate (p 0.99), and x takes
        temp_quantization instead. Asking half A beside every significant rival is too much:
        on the real TofuPilot gyro the loop, borrowed onto x at the first step (held-out z
        +4.6, fitting x better than the significant temp_rate by 7.1), was then refused (half
        A p 0.052) and x's withheld RMS went back from 145 to 659 mdps; and refusing every
        borrow beside a significant rival cost that x its loop, which half A confirms beside
        the drift (p 4e-25; docs/simgap.md, "Twelfth round"). Only ever keeps an effect out:
        a borrow passes stage B's wander test just the same afterwards. Each check is
        recorded (self.borrow_checks; a kept one moves the withheld log's scoring to half B)."""
        rivals = [n for n in trials if n != win and a in trials[n] and trials[n][a]["significant"]]
        if not rivals:
            return True
        st = self.state[a]
        n = len(self.cur[a]["ins"])
        b_win = self._profile_bic(a, st, win, v["shape"], n)   # v's shape is refined (run())
        p_pass = float(stats.norm.sf(Z_STEP))
        z_ho = float(v.get("t", 0.0))
        against = z_ho < -Z_STEP      # held out, it makes a worse
        for rv in rivals:
            sh, b_rv = self._trial_profile_bic(a, rv, trials[rv][a], n)
            margin = b_rv - b_win
            if not (margin > 0 or against):
                continue
            base = st + [(rv, sh)]
            p = None if self.confirm is None else self.confirm(a, base, base + [(win, v["shape"])])
            kept = p is not None and p < p_pass
            self.borrow_checks.append({"effect": win, "axis": a, "rival": rv,
                                       "bic_margin": float(margin),
                                       "z_heldout": z_ho, "p_withheld_a": p,
                                       "p_pass": p_pass, "kept": bool(kept)})
            if not kept:
                return False
        return True

    def _told_apart(self, win, sig, trials, step):
        """A thermal lag and a hysteresis (both split heating from cooling) significant on
        the same axes at one step: the held-out score favours the one with fewer columns
        (each held-out segment is predicted with every column's estimation error; the lag
        family has up to 7 columns, the loop 3), not the one the data favour. On the axes
        where both are significant they are compared as swap() compares them: by the
        profile likelihood (the noise model re-estimated with each in) less 0.5 ln n per
        column, each at its continuous parameter's maximum, and the rival takes the step if
        it wins on every one of those axes. Measured at wander `lag_rw`
        seed 113: a lag (tau 71 s) on z, held-out score hysteresis 18.8 against the lag's
        15.2, named hysteresis at 1.52x the floor.
        Only this pair, and only on a reading that is not a staircase: the profile
        likelihood does not tell a first offset law from a loop (at TEMPCOMP_SEED=415318 the
        rule put a hysteresis before the offset slope it rode on), and on a 1 degC staircase
        the lag's derivative of the de-staired estimate out-fits the loop it stands for
        (same seed: a loop named temp_rate on three axes). Not only where the rival is
        significant on every axis the winner is: at wander `lag_rw` seed 28 the loop was
        also significant (held out) on an axis the lag was not, which then refused it
        against the wander, and the lag (tau 128 s on x) had been named hysteresis at 4.0x
        the oracle floor."""
        if self.prob.ctx.quantised or win not in LAG_LOOP:
            return win
        rival = next(iter(LAG_LOOP - {win}))
        if rival not in sig:
            return win
        # Compared where both are significant: there the winner would take the axis and the
        # rival never get its turn. The winner's other axes stay its own (a lost step leaves
        # it in the pool for them).
        common = [a for a, v in trials[win].items()
                  if v["significant"] and a in trials[rival] and trials[rival][a]["significant"]]
        if not common:
            return win
        # The rival must win on every axis: the first axis it loses on decides (each axis
        # costs a noise search per model; on the bench's 1 M case the loop kept its step on
        # the first of three axes, 3.7 s -> about a third).
        step["profile_choice"] = {"winner": win, "rival": rival, "axes": common, "lost_on": None}
        for a in common:
            n = len(self.cur[a]["ins"])
            b = {}
            for name in (win, rival):
                b[name] = self._trial_profile_bic(a, name, trials[name][a], n)[1]
            if not b[rival] > b[win]:
                step["profile_choice"]["lost_on"] = a
                return win
        return rival

    def _joint(self, trials, rejected, nstats, pool):
        """Pairs that mask each other (JOINT), tried together once the greedy search finds no
        single effect: a power-on's constant and the warm-up after it each predict the
        held-out segments worse alone - a run's constant fitted on its settled half misses
        its warm-up half, and a warm-up fitted across runs takes their different offsets
        (measured: full blind set seed 13, drift + turn_on_bias, z_rest -56 and -124 alone,
        the final residual 3.6x the floor). The pair, each at the shape its own trial chose,
        is judged like one effect (the held-out gain, judged as a per-run effect is) and then
        by the same likelihood-ratio test against the wandering bias, with both effects'
        free parameters as degrees of freedom and the warm-up's shape grid as the Bonferroni
        factor, and half A of the withheld log where that test needs it. A pair the wander
        check refuses is not tried again on that axis until its state changes (the singles'
        own refusals, `rejected` from run(), keep the pair out the same way). nstats: axis ->
        (sd, tau) of this step's saturated model (run()). Returns whether a pair was added
        (the greedy search then goes on). The lagged loop (LAGGED) is tried the same
        way, its two shapes searched together (_lagged_pair)."""
        added = False
        for pair in JOINT:
            for a in range(3):
                have = {n for n, _ in self.state[a]}
                if self._joint_refused.get((pair, a)) == len(self.state[a]) or any(
                        n in have or a not in trials.get(n, {}) or rejected.get((n, a)) == len(
                            self.state[a]) for n in pair):
                    continue
                tr = [trials[n][a] for n in pair]
                blocks = self.state[a] + [(v["name"], v["shape"]) for v in tr]
                v = {"name": next((v["name"] for v in tr if BY_NAME[v["name"]].per_run), tr[-1]["name"]),
                     "shape": tr[-1]["shape"],
                     "res": self.prob.evaluate(a, blocks, withheld=False),
                     "df": sum(v["df"] for v in tr), "grid": int(np.prod([v["grid"] for v in tr]))}
                added |= self._add_joint(a, pair, v, blocks, nstats, pool)
        for a in range(3):
            if self._joint_refused.get((LAGGED, a)) == len(self.state[a]):
                continue
            v = self._lagged_pair(a, trials, rejected)
            if v is not None:
                added |= self._add_joint(a, LAGGED, v, v.pop("blocks"), nstats, pool)
        return added

    def _add_joint(self, a, pair, v, blocks, nstats, pool):
        """Judge the pair's trial v (blocks: the whole state it proposes) as _joint says, and
        take it in where it passes (its effects then leave the axis's pool of candidates, as
        run() does for one effect). Returns whether it did."""
        sd, tau = nstats[a]
        self._judge(v, a, tau, sd)
        if not v["significant"]:
            return False
        z, gain, _ = self._lr_z(a, self.state[a], blocks, v["df"], v["grid"])
        if z < Z_WANDER:
            self._joint_refused[(pair, a)] = len(self.state[a])
            return False
        self.state[a] = list(blocks)
        for n in pair:
            if a in pool.get(n, []):
                pool[n].remove(a)
        for n, shape in blocks:
            if n in pair:
                self.record[(n, a)] = dict(v, name=n, shape=shape, z_wander=z, loglik_gain=gain,
                                           joint=list(pair))
        self.cur[a] = v["res"]
        self.joint.append({"effects": list(pair), "axis": a, "z": float(v["t"]),
                           "z_wander": float(z), "gain": float(gain)})
        return True

    def _lagged_pair(self, a, trials, rejected):
        """The lag and the loop on its lagged temperature (LAGGED) as one candidate on axis a,
        where the lag is not in the state and the loop is not, or is on the reading (the
        state's loop is then replaced by the lagged one). Their shapes are chosen together
        by BIC of the GLS fit, as _try chooses one effect's: the lag's time constant and which
        of its two lags the loop follows (profiled at the loop's width on the reading: its
        trial's, or the state's), then the loop's width at that lag. Tried only where each
        explains something in-sample alone (its trial's likelihood ratio significant,
        p_insample < ALPHA_INSAMPLE, or the loop already in the state): a pair of effects that
        are each nothing in-sample is not looked for. The Bonferroni factor is the whole grid
        the pair is chosen from (every lag shape times every loop shape it allows); df the
        columns it adds. Returns the trial with its `blocks` (the proposed state), or None."""
        lag_name, loop_name = LAGGED
        st = self.state[a]
        have = dict(st)
        if lag_name in have or lag_name not in trials or a not in trials[lag_name]:
            return None
        if rejected.get((lag_name, a)) == len(st):
            return None
        if loop_name in have:
            if isinstance(have[loop_name], tuple):
                return None
            w0 = have[loop_name]
            base = [b for b in st if b[0] != loop_name]
            ins = [trials[lag_name][a]]
        else:
            if a not in trials.get(loop_name, {}) or rejected.get((loop_name, a)) == len(st):
                return None
            w0 = trials[loop_name][a]["shape"]
            w0 = w0[0] if isinstance(w0, tuple) else w0
            base = list(st)
            ins = [trials[lag_name][a], trials[loop_name][a]]
        if any(t.get("p_insample", 1.0) >= ALPHA_INSAMPLE for t in ins):
            return None
        blocks, res, df, grid = self._lagged_shapes(a, base, w0)
        if loop_name in have:
            df -= self._effect_df(a, loop_name, w0)
        return {"name": loop_name, "shape": blocks[-1][1], "res": res, "df": max(1, df),
                "grid": grid, "blocks": blocks}

    def _lagged_shapes(self, a, base, w0):
        """base + the LAGGED pair at the shapes BIC chooses (_lagged_pair), its residuals under
        the axis's noise model, the pair's columns, and the size of the grid searched."""
        lag_name, loop_name = LAGGED
        ctx = self.prob.ctx
        lag, loop = BY_NAME[lag_name], BY_NAME[loop_name]
        taus = lag.shapes_given(ctx, base)
        grid = sum(len(loop.shapes_given(ctx, base + [(lag_name, x)])) for x in taus)
        self.prob.prime(a, base)

        def bic(t_lag, s_loop):
            pair = [(lag_name, t_lag), (loop_name, s_loop)]
            res = self.prob.evaluate(a, base + pair, withheld=False)
            df = sum(self._effect_df(a, nm, sh) for nm, sh in pair)
            return _bic(res, df), res, df, base + pair

        _, t_lag, lg = min(((bic(x, (w0, lg))[0], x, lg) for x in taus for lg in lag.time_constants(x)),
                           key=lambda b: b[0])
        widths = [s for s in loop.shapes_given(ctx, base + [(lag_name, t_lag)])
                  if isinstance(s, tuple) and s[1] == lg]
        (_, res, df, blocks), _ = min(((bic(t_lag, s), s) for s in widths), key=lambda b: b[0][0])
        return blocks, res, df, grid

    def refine(self, passes=2):
        """Re-choose each added effect's shape with the others in place (BIC on the grid, then
        the continuous parameter by maximum likelihood): greedy order fixed the first
        effect's shape while the second was still missing."""
        for a in range(3):
            if len(self.state[a]) < 2:
                continue
            n = len(self.cur[a]["ins"])
            for _ in range(passes):
                changed = False
                for i, (name, shape) in enumerate(list(self.state[a])):
                    e = BY_NAME[name]
                    best = None
                    others = self.state[a][:i] + self.state[a][i + 1:]
                    for sh in e.shapes_given(self.prob.ctx, others):
                        ll, _ = self.prob.loglik(a, others + [(name, sh)], self.prob.noise[a])
                        bic = -ll + 0.5 * self._effect_df(a, name, sh) * np.log(n)
                        if best is None or bic < best[0]:
                            best = (bic, sh)
                    sh = self._refine(a, others, name, best[1])
                    if not _same_shape(sh, shape):
                        self.state[a][i] = (name, sh)
                        changed = True
                if not changed:
                    break
            self.cur[a] = self.prob.evaluate(a, self.state[a], withheld=False)

    def swap(self):
        """An effect that entered an axis only because it was established on another (run():
        the held-out segments of this axis never judged it significant) may be the wrong one
        of two effects the catalogue lists as confusable (NEEDS: a thermal lag and a
        hysteresis both split heating from cooling), its rival kept out by how its columns
        extrapolate into one held-out segment. Each such effect is compared with each
        confusable rival not on the axis, both with the axis's other
        effects in, by the profile likelihood (the noise model re-estimated with each in) less
        0.5 ln n per column (BIC), the rival at its best shape (grid by BIC under the axis's
        noise model, then its continuous parameter); the better one stays. The winner still
        faces prune(), the unlogged-step check and the withheld log."""
        for a in range(3):
            n = len(self.cur[a]["ins"])
            model = self.prob.noise[a]
            for i, (name, shape) in enumerate(list(self.state[a])):
                if (name, a) not in self.borrowed:
                    continue
                others = self.state[a][:i] + self.state[a][i + 1:]
                have = {b for b, _ in self.state[a]}
                best = (self.noise_for(a, self.state[a])["profile"]
                        - 0.5 * self._effect_df(a, name, shape) * np.log(n), name, shape)
                for rival in sorted(self.avail):
                    if (rival in have or a not in self.avail[rival] or BY_NAME[rival].per_run
                            or frozenset({name, rival}) not in NEEDS):
                        continue
                    grid = BY_NAME[rival].shapes_given(self.prob.ctx, others)
                    sh = min(grid, key=lambda s_: -self.prob.loglik(a, others + [(rival, s_)], model)[0]
                             + 0.5 * self._effect_df(a, rival, s_) * np.log(n))
                    sh = self._refine(a, others, rival, sh, model)
                    v = (self.noise_for(a, others + [(rival, sh)])["profile"]
                         - 0.5 * self._effect_df(a, rival, sh) * np.log(n))
                    if v > best[0]:
                        best = (v, rival, sh)
                if best[1] != name:
                    self.state[a][i] = (best[1], best[2])
                    self.swapped.append({"effect": name, "axis": a, "by": best[1]})
                    self.cur[a] = self.prob.evaluate(a, self.state[a], withheld=False)

    def _refine_profile(self, a, others, name, shape, model=None, rounds=3):
        """The shape's continuous parameter at the maximum of the profile likelihood, jointly
        with the noise model: _refine() under a fixed noise model, the noise model re-estimated
        with that shape in (noise_for), and again while the profile likelihood rises (a
        coordinate ascent). Refined under another shape's noise model alone, a family is
        compared off its own maximum (a warm-up's time constant bends to make up for a walk
        that noise model lacks). Returns (shape, noise info)."""
        sh = self._refine(a, others, name, shape, model)
        info = self.noise_for(a, others + [(name, sh)])
        for _ in range(rounds - 1):
            sh2 = self._refine(a, others, name, sh, info["model"])
            if _same_shape(sh2, sh):
                break
            i2 = self.noise_for(a, others + [(name, sh2)])
            if i2["profile"] <= info["profile"]:
                break
            sh, info = sh2, i2
        return sh, info

    def _trial_profile_bic(self, a, name, trial, n):
        """(shape, _profile_bic) of a step's trial of name on axis a over the current state,
        its shape refined first (_refine): how _told_apart and _borrow_holds compare rivals."""
        sh = self._refine(a, self.state[a], name, trial["shape"])
        return sh, self._profile_bic(a, self.state[a], name, sh, n)

    def _profile_bic(self, a, others, name, shape, n):
        """Profile log-likelihood of others + (name, shape) less 0.5 ln n per column."""
        info = self.noise_for(a, others + [(name, shape)])
        return info["profile"] - 0.5 * self._effect_df(a, name, shape) * np.log(n)

    def reshape(self):
        """Choose between an effect's shape families (a warm-up as one exponential, exponential
        plus a trend, or hyperbolic) each at its own best continuous parameter, by the profile
        likelihood (the noise model re-estimated with each shape in) less 0.5 ln n per column.
        On the grid the families are compared at time constants up to 2.3x off the true one,
        where a wrong family with a walk taking the rest can tie or win; the family chosen
        there then carries the wrong tail onto a new power-on. Each family's parameter is
        refined jointly with its own noise model (_refine_profile), and a family with more
        columns than the best smaller one must pass the wander test for them
        (_nested_claim). Effects with one family keep the shape of refine()."""
        for a in range(3):
            n = len(self.cur[a]["ins"])
            changed = False
            for i, (name, shape) in enumerate(list(self.state[a])):
                e = BY_NAME[name]
                others = self.state[a][:i] + self.state[a][i + 1:]
                grid = e.shapes_given(self.prob.ctx, others)
                if len({e.family(sh) for sh in grid}) < 2:
                    continue

                # Per family: the grid's best under the axis's noise model (cheap), its
                # continuous parameter refined, then the profile likelihood there.
                model = self.prob.noise[a]
                fams = {}
                for sh in grid:
                    v = self.prob.loglik(a, others + [(name, sh)], model)[0] \
                        - 0.5 * self._effect_df(a, name, sh) * np.log(n)
                    f = e.family(sh)
                    if f not in fams or v > fams[f][0]:
                        fams[f] = (v, sh)
                best = None
                ranked = []
                for f, (_, sh) in fams.items():
                    sh, _ = self._refine_profile(a, others, name, sh, model)
                    v = self._profile_bic(a, others, name, sh, n)
                    ranked.append((v, sh, f))
                    if best is None or v > best[0]:
                        best = (v, sh)
                best, demoted = self._nested_claim(a, others, name, best, ranked, grid)
                cur = self._profile_bic(a, others, name, shape, n)
                if demoted and self._effect_df(a, name, shape) <= self._effect_df(a, name, best[1]):
                    demoted = False     # the current shape claims no more than the one kept
                if (best[0] > cur or demoted) and not _same_shape(best[1], shape):
                    self.state[a][i] = (name, best[1])
                    changed = True
            if changed:
                self.cur[a] = self.prob.evaluate(a, self.state[a], withheld=False)

    def _nested_claim(self, a, others, name, best, ranked, grid):
        """A family with more columns than another (exponential + trend against the exponential,
        the line or the hyperbola) claims more than it: a lasting trend beside the warm-up. With
        one power-on a trend is also what a bias random walk looks like, and a walk that a trend
        has taken leaves a residual a stationary Gauss-Markov term fits, so the profile BIC (0.5
        ln n for the column) lets the walk's own trend in. The extra columns face the test any
        effect faces against a wandering bias (stage B, _lr_z): profile likelihoods, each over
        its own noise model, the larger family's grid Bonferroni-corrected, z >= Z_WANDER, df
        the extra columns; else the best smaller family (by profile BIC) stays. Returns
        ((profile BIC, shape), whether the larger family was turned down). Measured on the
        wander set's rw_drift seeds 41 and 47: exponential + trend under a Gauss-Markov term
        beat the true exponential under a walk by 7-8 nats, z 3.45 and 3.05 here."""
        e = BY_NAME[name]
        df_best = self._effect_df(a, name, best[1])
        smaller = [r for r in ranked if self._effect_df(a, name, r[1]) < df_best]
        if not smaller:
            return best, False
        v, sh, f = max(smaller, key=lambda r: r[0])
        ngrid = max(1, sum(1 for g_ in grid if e.family(g_) == e.family(best[1])))
        z, _, _ = self._lr_z(a, others + [(name, sh)], others + [(name, best[1])],
                             df_best - self._effect_df(a, name, sh), ngrid)
        return (best, False) if z >= Z_WANDER else ((v, sh), True)

    def prune(self):
        """Backward check with the whole model in place: each chosen effect must still beat
        the model without it whose noise model may wander (stage B against everything else
        chosen); else the weakest goes, and the check repeats. Returns [(effect, axis, z)]."""
        removed = []
        for a in range(3):
            while self.state[a]:
                worst = None
                for i, (name, shape) in enumerate(self.state[a]):
                    without = self.state[a][:i] + self.state[a][i + 1:]
                    z, gain, i0 = self._wander_check(a, without, self.state[a], name)
                    if z < Z_WANDER and (worst is None or z < worst[1]):
                        worst = (i, z, i0)
                if worst is None:
                    break
                name, shape = self.state[a][worst[0]]
                removed.append((name, a, worst[1]))
                self.wander.append({"effect": name, "axis": a, "z": worst[1], "gain": None,
                                    "kind": N.describe(worst[2]["model"], self.sigma[a]),
                                    "shape": shape})
                del self.state[a][worst[0]]
        return removed

    def _best_column(self, a, blocks, effect, shapes):
        """The one-column shape that most lowers the GLS sum of squares of blocks + it under
        the axis's noise model: each candidate column is whitened and projected off the
        blocks' filtered design (one QR), so a grid of a hundred shapes costs a hundred
        filter passes, not a hundred fits."""
        p = self.prob
        model = p.noise[a]
        X, scale, Xs, nlev, st = p._train_design(a, blocks, model)
        y = p._yw(a, model, st)
        m = p.train.mask
        if Xs.shape[1]:
            Q = np.linalg.qr(Xs)[0]
            u = y - Q @ (Q.T @ y)
        else:
            Q, u = None, y
        best, gain = shapes[0], -1.0
        for sh in shapes:
            c = N.whiten(effect.columns(p.ctx, p.train, sh, a)[m], model, st)[:, 0]
            if Q is not None:
                c = c - Q @ (Q.T @ c)
            cc = float(c @ c)
            if cc <= 1e-12 * max(float(y @ y), 1e-300):
                continue
            g = float(u @ c) ** 2 / cc
            if g > gain:
                best, gain = sh, g
        return best

    def unlogged(self):
        """Could an offset step at a time nothing logged explain the effect? (an off-catalogue
        cause: humidity, a stress relaxing, a neighbour switching on). The best step (effects.
        UnloggedStep, its onset and time constant by likelihood under the axis's noise model)
        goes in first; the effect must still add to it by the likelihood-ratio test of
        _wander_check, each model under its own profiled noise model, at z > Z_STEP. A
        temperature-driven effect that fits only because the temperature programme happens to
        correlate with the step, or a drift that is the step's slow tail, adds nothing once the
        step is in; a real lag, loop or warm-up keeps most of its gain (it repeats with every
        ramp or starts at the power-on, which no single step does). Per-run effects are not
        judged (a step cannot take a per-power-on constant's place). Returns [(effect, axis,
        z)] of the effects taken out."""
        removed = []
        step = BY_NAME["unlogged_step"]
        shapes = step.shapes(self.prob.ctx)
        for a in range(3):
            for name, shape in list(self.state[a]):
                if BY_NAME[name].per_run:
                    continue
                others = [b for b in self.state[a] if b[0] != name]
                best = self._best_column(a, others, step, shapes)
                base = others + [(step.name, best)]
                z, gain, i0 = self._wander_check(a, base, base + [(name, shape)], name,
                                                 z_pass=Z_STEP)
                if z < Z_STEP and self._step_moved(a, others, name, shape, best, z):
                    continue
                if z < Z_STEP:
                    removed.append((name, a, z))
                    self.state[a] = [b for b in self.state[a] if b[0] != name]
                    self.stepped.append({"effect": name, "axis": a, "z": z, "gain": gain,
                                         "step": best})
        return removed

    def _step_moved(self, a, others, name, shape, step_shape, z):
        """Half A's say on an effect the unlogged step explains as well on the training log:
        there the two are one trend (a line since the power-on and a slow step early in the
        log differ by a few per cent of its rise), but the step's cause keeps its own time in
        the withheld log, its own power-on, while the effect repeats with the power-on or
        the temperature programme. The effect, frozen from its training fit, must predict
        half A better than the step (size and settling frozen from training) at the onset
        that suits A best, one-sided at Z_STEP (diagnose._withheld_confirm.step_rival).
        Measured at wander `aging` seed 111: z's straight aging line, taken out by a step
        starting at 5-20 % of the training log with a time constant of half its span
        (training z below 0), beats the moved step on half A at z 2.03 and is named, 1.40x ->
        within 1.25x. At seeds 61 and 89 (z 0.88, 1.16 on training) the step's onset chosen
        on all of A won by its own choice (z -0.28, 1.12); cross-fitted, the line wins (z 2.25,
        2.69), while the off-catalogue logs' steps still beat the drift or lag they took out
        (z 0.01 to -5.1 at seeds 19, 53, 89, 102). A step whose cause repeats on the same
        schedule in every log is a clock-tied effect; no test on one withheld log tells it
        from one. Returns True when the effect stays."""
        if self.step_rival is None:
            return False
        p = self.step_rival(a, others + [(name, shape)], others + [("unlogged_step", step_shape)])
        if p is None:
            return False
        zr = float(stats.norm.isf(max(p, 1e-300)))
        kept = bool(zr >= Z_STEP)
        self.step_rivals.append({"effect": name, "axis": a, "z_train": float(z), "p_withheld_a": p,
                                 "z_withheld_a": zr, "z_pass": Z_STEP, "kept": kept,
                                 "step": [float(v) for v in step_shape]})
        return kept

    def finalise(self):
        """The final noise model per axis (the chosen effects in), set on the problem so the
        final fits, the withheld score and the exported model are GLS under it."""
        for a in range(3):
            info = self.noise_for(a, self.state[a])
            self.noise_info.setdefault(a, {})["final"] = info
            self.prob.set_noise(a, info["model"])
            self.cur[a] = self.prob.evaluate(a, self.state[a], withheld=False)

    def confusions(self):
        """Pairs the greedy path could not tell apart: at the step one was chosen, the other
        scored almost as well and stopped mattering once the winner was in."""
        out, apart = [], []
        for s, nxt in zip(self.steps[:-1], self.steps[1:]):
            win = s["chosen"]
            if win is None:
                continue
            for n, sc in s["scores"].items():
                if n == win or sc <= 0:
                    continue
                absorbed = nxt["scores"].get(n, 0.0) < 0.2 * sc
                ratio = sc / s["scores"][win]
                if absorbed and ratio >= RIVAL:
                    out.append({"effects": [win, n], "needs": needs(win, n),
                                "score_ratio": round(ratio, 3)})
                elif absorbed:
                    apart.append({"chosen": win, "rival": n, "score_ratio": round(ratio, 3)})
        return out, apart


def _key(s):
    if isinstance(s, tuple):
        return tuple(_key(x) for x in s)
    if isinstance(s, (float, np.floating)):
        return float(s)
    return s


WANDER_NEEDS = {
    "drift": "several power-on runs, or a longer soak: a drift repeats its shape after every "
             "power-on and keeps its sign, a wander does neither",
    "turn_on_bias": "several power-ons at the same temperature, each longer than the wander's "
                    "time scale",
    "offset_temperature": "a second temperature cycle over the same range: the offset law repeats, "
                          "a wander does not",
    "temp_rate": "repeated ramps (two rates, up and down): a lag repeats with every ramp, a wander "
                 "does not",
    "hysteresis": "a repeated temperature cycle: the loop repeats, a wander does not",
}

STEP_NEEDS = ("a log of the suspected cause (humidity, supply, mounting), or a repeat of the "
              "temperature programme: an effect repeats with its cause, a step at an unlogged "
              "time does not")


def wander_needs(name):
    return WANDER_NEEDS.get(name, "a repeat of the experiment (an effect repeats with its cause, "
                                  "a wander does not), or a longer log")


def design_gaps(prob, verdict, untried):
    """Confounds built into the experiment itself, found from the logs rather than the fit."""
    out = []
    log = prob.train.log
    from . import prep
    br = prep.branch(prep.temp_rate(log))
    if "offset_temperature" in verdict and "sensitivity_temperature" in untried:
        out.append({"effects": ["offset_temperature", "sensitivity_temperature"],
                    "needs": needs("offset_temperature", "sensitivity_temperature")})
    if not np.any(br == "heating") or not np.any(br == "cooling"):
        out.append({"effects": ["hysteresis", "offset_temperature"],
                    "needs": needs("hysteresis", "offset_temperature")})
    # Hysteresis and thermal lag both split heating from cooling; only a change of ramp rate
    # (lag scales with it, hysteresis does not) or a soak after each separates them. Without
    # real timestamps there is no rate at all.
    rate = np.abs(prep.temp_rate(log))
    moving = rate[br != "soak"]
    one_rate = moving.size < 10 or np.percentile(moving, 80) < 1.5 * np.percentile(moving, 20)
    no_clock = "row index" in log.meta.get("time", "")
    if one_rate or no_clock:
        out.append({"effects": ["hysteresis", "temp_rate"],
                    "needs": ("true timestamps, " if no_clock else "") + needs("hysteresis", "temp_rate")})
    on = log.t - log.t[prep.run_starts(log)]
    if np.std(on) > 0 and np.std(log.temp) > 0 and abs(np.corrcoef(on, log.temp)[0, 1]) > 0.9:
        out.append({"effects": ["drift", "offset_temperature"],
                    "needs": needs("drift", "offset_temperature")})
    if "g_sensitivity" in untried and prob.ctx.sensor != "accel":
        out.append({"effects": ["g_sensitivity", "offset_temperature"],
                    "needs": "several orientations relative to gravity"})
    return out


def axis_names(axes):
    return [AXES[a] for a in axes]
