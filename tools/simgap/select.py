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

from . import noise as N
from .effects import BY_NAME, EFFECTS
from .logio import AXES

Z_SIG = 4.0          # z of the held-out gain (noise autocorrelation counted) an effect needs:
                     # one-sided p 3e-7: ~200 effect x axis x shape candidates are tried
Z_REST = 2.0         # ... and without its best held-out segment the rest still z > 2
MIN_REL = 0.01       # ... and the held-out sum of squares must drop by at least 1 %
MIN_NOISE = 0.02     # ... and by at least 2 % of the innovation variance (not a rounding win)
Z_WANDER = 2.33      # stage B, a confirmatory test of the one winner per axis (one-sided 1 %):
                     # z of its held-out innovation gain under the noise model re-estimated
                     # without it (which may wander to explain it), correlation counted
Z_WANDER_REST = 1.0  # ... and still positive evidence without its best held-out segment
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


def needs(a, b):
    return NEEDS.get(frozenset({a, b}), "an experiment that varies them independently")


def _same_shape(a, b):
    """Shapes are None, numbers, strings or tuples of them; a width and a (width, lag) pair
    must compare unequal rather than broadcast."""
    if isinstance(a, tuple) or isinstance(b, tuple):
        return (isinstance(a, tuple) and isinstance(b, tuple) and len(a) == len(b)
                and all(_same_shape(x, y) for x, y in zip(a, b)))
    if a is None or b is None or isinstance(a, str) or isinstance(b, str):
        return a == b
    return float(a) == float(b)


class Greedy:
    def __init__(self, prob, sigma):
        self.prob = prob
        self.sigma = sigma                      # white floor per axis of the training log
        self.state = {a: [] for a in range(3)}  # axis -> [(effect, shape)]
        self.steps = []
        self.untried = {}
        self.avail = {}
        self.wander = []                        # (effect, axis, z, kind of wander, shape)
        self._noise_cache = {}
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
        """Noise model of the residual of sim + blocks on the training log (effects in): the
        Allan fit gives the starting values, the likelihood the model; one GLS refit under it
        and a re-estimate. Cached per block list."""
        key = (axis, tuple((n, _key(s)) for n, s in blocks))
        if key in self._noise_cache:
            return self._noise_cache[key]
        p = self.prob
        pt = p.train
        dt = p.ctx.dt
        model = N.NoiseModel.white(self.sigma[axis], dt)
        info = None
        for _ in range(2):
            r = p.full_residual(pt, axis, blocks, model=model)[pt.mask]
            r = r - np.mean(r)
            ad = N.allan(r, dt)
            fit = N.fit_allan(ad)
            prov = N.NoiseModel(max(fit["s2"], 1e-300), fit["q"], fit["g2"], fit["phi"], dt)
            st = p.starts(pt, axis, prov)
            new, lls = N.estimate(r, dt, st, self.sigma[axis] ** 2, fit)
            info = {"model": new, "allan": ad, "allan_fit": fit, "loglik": lls, "resid": r}
            if new.is_white and model.is_white:
                break
            model = new
        self._noise_cache[key] = info
        return info

    def _heldout_noise(self, axis, blocks):
        """The noise model under which sim + blocks predict the held-out segments best: white,
        the in-sample maximum-likelihood model, or a random walk whose size maximises the
        held-out likelihood (scipy's bounded Brent search); the scale is concentrated out on
        the held-out rows. Returns (loglik per row, innovations, NoiseModel)."""
        p = self.prob
        info = self.noise_for(axis, blocks)
        s2 = max(info["model"].s2, 1e-300)
        dt = p.ctx.dt
        memo = {}

        def ho(m):
            k = m.key()
            if k not in memo:
                u = p.evaluate(axis, blocks, withheld=False, model=m)["cv"]
                v = max(float(np.mean(u * u)), 1e-300)
                memo[k] = (-0.5 * np.log(2 * np.pi * v) - u * u / (2 * v), u, m)
            return memo[k]

        cands = [N.NoiseModel(s2, dt=dt), info["model"]]
        n = len(self.cur[axis]["cv"])
        o = optimize.minimize_scalar(
            lambda lq: -float(np.sum(ho(N.NoiseModel(s2, s2 * np.exp(lq), dt=dt))[0])),
            bounds=(np.log(1e-4 / n ** 2), np.log(10.0)), method="bounded",
            options={"xatol": 0.3, "maxiter": 12})
        cands.append(N.NoiseModel(s2, s2 * np.exp(o.x), dt=dt))
        return max((ho(m) for m in cands), key=lambda r: float(np.sum(r[0])))

    def _wanders_heldout(self, axis, blocks):
        """Does a wandering noise model predict the held-out segments of sim + blocks better
        than white noise, by more than BIC's 0.5 ln n nats and by a material amount?"""
        ll, _, m = self._heldout_noise(axis, blocks)
        if m.is_white:
            return False
        p = self.prob
        u = p.evaluate(axis, blocks, withheld=False, model=N.NoiseModel(m.s2, dt=m.dt))["cv"]
        v = max(float(np.mean(u * u)), 1e-300)
        lw = float(np.sum(-0.5 * np.log(2 * np.pi * v) - u * u / (2 * v)))
        n = len(u)
        material = m.q * n / 6 + m.g2 > 0.02 * m.s2
        return bool(material and float(np.sum(ll)) - lw > 0.5 * np.log(n))

    def _zd(self, d, name):
        """(z, z without the best held-out segment) of per-row gains d, correlation counted."""
        tau = N.autocorr_time(d - np.mean(d))
        sd = float(np.std(d))
        folds = self.prob.cv_fold

        def z_of(sel):
            n = int(np.sum(sel))
            return float(np.sum(d[sel]) / (sd * np.sqrt(n * tau))) if sd > 0 and n else 0.0

        z = z_of(np.ones(len(d), bool))
        fg = np.array([d[folds == f].sum() for f in range(self.prob.nfold)])
        rest = folds != int(np.argmax(fg))
        z_rest = z if BY_NAME[name].per_run else z_of(rest)   # per-run: evidence comes in runs
        return z, z_rest

    def _wander_check(self, axis, without, with_, name):
        """Can a wandering bias explain the effect's held-out gain? Two views, either enough:
        (1) nested: under the noise model re-estimated *without* the effect (its random walk or
        Gauss-Markov term takes whatever slow part the effect would explain), the effect still
        shrinks the one-step-ahead innovations of the held-out segments; (2) best against best:
        the held-out predictive log-likelihood of the model with the effect beats the model
        without it, each under the noise model that predicts its held-out segments best. The
        per-row gains must add up significantly (z counting their correlation) and not rest on
        one segment. A real lag, drift or loop predicts the rows where it acts; a fit to the
        walk does not. Returns (z, gain in nats, noise info without the effect)."""
        p = self.prob
        i0 = self.noise_for(axis, without)
        m0 = i0["model"]
        e0 = p.evaluate(axis, without, withheld=False, model=m0)
        e1 = p.evaluate(axis, with_, withheld=False, model=m0)
        s2 = max(e0["s2"], 1e-300)
        d = (e0["cv"] ** 2 - e1["cv"] ** 2) / (2 * s2)
        z, z_rest = self._zd(d, name)
        best = (z if z_rest >= Z_WANDER_REST else min(z, z_rest), float(np.sum(d)))
        if best[0] < Z_WANDER:
            l0, _, _ = self._heldout_noise(axis, without)
            l1, _, _ = self._heldout_noise(axis, with_)
            d2 = l1 - l0
            z2, z2_rest = self._zd(d2, name)
            v = z2 if z2_rest >= Z_WANDER_REST else min(z2, z2_rest)
            if v > best[0]:
                best = (v, float(np.sum(d2)))
        return best[0], best[1], i0

    # -- stage A ----------------------------------------------------------------------

    def _try(self, name, axis):
        """Best shape of one effect on one axis and its held-out innovations over the current
        state, under the axis's current (saturated) noise model."""
        e = BY_NAME[name]
        best = None
        self.prob.prime(axis, self.state[axis])
        for shape in e.shapes_given(self.prob.ctx, self.state[axis]):
            res = self.prob.evaluate(axis, self.state[axis] + [(name, shape)], withheld=False)
            ss = float(np.sum(res["cv"] ** 2))
            if best is None or ss < best[0]:
                best = (ss, shape, res)
        _, shape, res = best
        return {"name": name, "shape": shape, "res": res}

    def _judge(self, v, axis, tau, sd):
        """Significance of one trial. The gain sum(r0^2 - r1^2) = sum(delta (2 r1 + delta)) is
        random through the noise in r1: its variance is 4 sd^2 tau sum(delta^2), with sd and
        tau (integrated autocorrelation time) of the saturated model's innovations - about 1
        when the noise model is right, longer when something slow is left that no candidate
        and no noise term predicts."""
        r0, r1 = self.cur[axis]["cv"], v["res"]["cv"]
        ss0, ss1 = float(np.sum(r0 ** 2)), float(np.sum(r1 ** 2))
        gain = r0 ** 2 - r1 ** 2
        delta = r0 - r1

        def z_of(sel):
            den = 2 * sd * np.sqrt(tau * float(np.sum(delta[sel] ** 2)))
            return float(np.sum(gain[sel]) / den) if den > 0 else 0.0

        z = z_of(slice(None))
        # No single segment may carry the finding: with the segment that gains most left
        # out, the rest must still point the same way.
        folds = self.prob.cv_fold
        fg = np.array([gain[folds == f].sum() for f in range(self.prob.nfold)])
        rest = folds != int(np.argmax(fg))
        z_rest = z_of(rest) if rest.any() else 0.0
        s2 = float(v["res"]["s2"])
        per_run = BY_NAME[v["name"]].per_run
        significant = bool(z > Z_SIG and (z_rest > Z_REST or per_run) and ss0 - ss1 > MIN_REL * ss0
                           and ss0 - ss1 > MIN_NOISE * len(r0) * s2)
        v.update(cv_before=r0, rms_before=float(np.sqrt(ss0 / len(r0))), rms_after=float(np.sqrt(ss1 / len(r1))),
                 t=z, p=float(stats.norm.sf(z)), z_rest=z_rest, tau=tau,
                 significant=significant, score=(ss0 - ss1) / max(s2, 1e-300))
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
            for a in range(3):
                if not any(a in tr for tr in trials.values()):
                    continue
                sd, tau = self._noise_stats(trials, a)
                for n, tr in trials.items():
                    if a in tr:
                        self._judge(tr[a], a, tau, sd)
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
                break
            win = max(sig, key=lambda n: scores[n])
            added = False
            for a, v in trials[win].items():
                # A power-on shifts every axis at once: a per-run constant found on some axes
                # is taken on every axis where it helps on the held-out segments at all.
                take = v["significant"] or (BY_NAME[win].per_run and v["score"] > 0 and
                                            any(w["significant"] for w in trials[win].values()))
                if not take:
                    continue
                with_ = self.state[a] + [(win, v["shape"])]
                if not self._wanders_heldout(a, with_):
                    # With the effect in, the held-out segments hold no wander: no random walk
                    # is there to explain the effect (a walk estimated without it was the
                    # effect itself; judged held-out, so a shape that soaks up a walk in-sample
                    # does not hide it).
                    z, gain, i0 = np.inf, float(v["score"]) / 2, None
                else:
                    z, gain, i0 = self._wander_check(a, self.state[a], with_, win)
                v.update(z_wander=z, loglik_gain=gain)
                if z < Z_WANDER:
                    rejected[(win, a)] = len(self.state[a])
                    if v["significant"]:
                        self.wander.append({"effect": win, "axis": a, "z": z, "gain": gain,
                                            "kind": N.describe(i0["model"], self.sigma[a]),
                                            "shape": v["shape"]})
                    continue
                pool[win].remove(a)
                self.state[a].append((win, v["shape"]))
                self.cur[a] = v["res"]
                self.record[(win, a)] = v
                added = True
            if added:
                step["chosen"] = win
                if win not in chosen:
                    chosen.append(win)
        # Effects (or axes) never added: their trial against the final model.
        for n, tr in self.steps[-1]["trials"].items():
            for a, v in tr.items():
                self.record.setdefault((n, a), v)
        for st in self.steps:
            for n, tr in st["trials"].items():
                for a, v in tr.items():
                    self.record.setdefault((n, a), v)
        return chosen

    def refine(self, passes=2):
        """Re-choose each added effect's shape with the others in place: greedy order fixed
        the first effect's shape while the second was still missing."""
        for a in range(3):
            if len(self.state[a]) < 2:
                continue
            for _ in range(passes):
                changed = False
                for i, (name, shape) in enumerate(list(self.state[a])):
                    e = BY_NAME[name]
                    best = None
                    others = self.state[a][:i] + self.state[a][i + 1:]
                    for sh in e.shapes_given(self.prob.ctx, others):
                        blocks = list(self.state[a])
                        blocks[i] = (name, sh)
                        res = self.prob.evaluate(a, blocks, withheld=False)
                        ss = float(np.sum(res["cv"] ** 2))
                        if best is None or ss < best[0]:
                            best = (ss, sh)
                    if not _same_shape(best[1], shape):
                        self.state[a][i] = (name, best[1])
                        changed = True
                if not changed:
                    break
            self.cur[a] = self.prob.evaluate(a, self.state[a], withheld=False)

    def prune(self):
        """Backward check with the whole model in place: each chosen effect must still beat
        the model without it whose noise model may wander (stage B against everything else
        chosen); else the weakest goes, and the check repeats. Returns [(effect, axis, z)]."""
        removed = []
        for a in range(3):
            while self.state[a]:
                if self.noise_for(a, self.state[a])["model"].is_white:
                    break       # no wander left with the chosen effects in: nothing to explain them
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
