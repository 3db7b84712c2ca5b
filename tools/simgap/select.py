"""Greedy choice of effects by how much each shrinks the residual on held-out segments of the
training log (never the withheld log, which is scored once afterwards), significance counting
the residual's autocorrelation, and a check on which candidates the data cannot tell apart."""
import numpy as np
from scipy import stats

from . import noise
from .effects import BY_NAME, EFFECTS
from .logio import AXES

Z_SIG = 4.0          # z of the held-out gain (noise autocorrelation counted) an effect needs:
                     # one-sided p 3e-7: ~200 effect x axis x shape candidates are tried, and
                     # an autocorrelation time estimated from one log is itself uncertain
NOISE_FROM = "insample"
PRUNE_ABOVE = 1.5    # ... run only while the final held-out RMS is above 1.5x the floor
Z_KEEP = 4.0         # backward check: z against the final held-out residual's noise
Z_REST = 2.0         # ... and without its best held-out segment the rest still z > 2
MIN_REL = 0.01       # ... and the held-out sum of squares must drop by at least 1 %
MIN_NOISE = 0.02     # ... and by at least 2 % of the noise variance (not a rounding win)
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
        self.sigma = sigma                      # noise floor per axis of the scoring set
        self.state = {a: [] for a in range(3)}  # axis -> [(effect, shape)]
        self.cur = {a: prob.evaluate(a, [], withheld=False) for a in range(3)}
        self.steps = []
        self.untried = {}
        self.avail = {}
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

    def _try(self, name, axis):
        """Best shape of one effect on one axis and its improvement on the training log's
        held-out segments over the current state: both chosen and judged there only."""
        e = next(x for x in EFFECTS if x.name == name)
        best = None
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
        tau (the integrated autocorrelation time) of the noise. Both come from the residual of
        the saturated model (every candidate at once), so structure another effect will take
        does not count as noise, while a random walk, flicker or an out-of-catalogue driver,
        which no candidate predicts on held-out segments, gives a long tau and few
        independent samples of evidence."""
        r0, r1 = self.cur[axis]["cv"], v["res"]["cv"]
        ss0, ss1 = float(np.sum(r0 ** 2)), float(np.sum(r1 ** 2))
        gain = r0 ** 2 - r1 ** 2
        delta = r0 - r1

        def z_of(sel):
            den = 2 * sd * np.sqrt(tau * float(np.sum(delta[sel] ** 2)))
            return float(np.sum(gain[sel]) / den) if den > 0 else 0.0

        z = z_of(slice(None))
        # No single segment may carry the finding: with the segment that gains most left
        # out, the rest must still point the same way. A base model that extrapolates badly
        # into one segment, bent back by some shape there, gains in one place only.
        folds = self.prob.cv_fold
        fg = np.array([gain[folds == f].sum() for f in range(self.prob.nfold)])
        rest = folds != int(np.argmax(fg))
        z_rest = z_of(rest) if rest.any() else 0.0
        sig2 = self.sigma[axis] ** 2
        # (A per-run constant gains where a run's offset differs, run by run: its evidence
        # comes in runs, not segments, so it is exempt.)
        per_run = BY_NAME[v["name"]].per_run
        significant = bool(z > Z_SIG and (z_rest > Z_REST or per_run) and ss0 - ss1 > MIN_REL * ss0
                           and ss0 - ss1 > MIN_NOISE * len(r0) * sig2)
        v.update(rms_before=float(np.sqrt(ss0 / len(r0))), rms_after=float(np.sqrt(ss1 / len(r1))),
                 t=z, p=float(stats.norm.sf(z)), z_rest=z_rest, tau=tau,
                 significant=significant, score=(ss0 - ss1) / max(sig2, 1e-300))
        return v

    def _noise(self, trials, axis):
        """(sd, autocorrelation time) of the noise on one axis, from held-out residuals: of
        the saturated model (every candidate at once) and of the best single candidate, the
        less correlated. Held-out, not in-sample: fitted in-sample, drift and temperature
        shapes soak up part of a random walk and make what is left look whiter than it is."""
        best = None
        for tr in trials.values():
            if axis in tr:
                r = tr[axis]["res"]["cv"]
                ss = float(np.sum(r * r))
                if best is None or ss < best[0]:
                    best = (ss, r)
        cands = [best[1]] if best else [self.cur[axis]["cv"]]
        blocks = list(self.state[axis]) + [(n, tr[axis]["shape"]) for n, tr in trials.items()
                                           if axis in tr]
        if blocks and NOISE_FROM == "insample":
            pt = self.prob.train
            cands = [self.prob.full_residual(pt, axis, blocks)[pt.mask]]
        elif blocks:
            cands.append(self.prob.evaluate(axis, blocks, withheld=False)["cv"])
        stats_ = []
        for r in cands:
            r = r - np.mean(r)
            stats_.append((noise.autocorr_time(r), float(np.std(r))))
        tau, sd = min(stats_)
        return sd, tau

    def run(self):
        """Add the best significant effect (on the axes where it is significant) until none
        is left; an effect already added on some axes stays a candidate for the others."""
        pool = {n: list(ax) for n, ax in self.avail.items()}
        chosen = []
        self.record = {}          # (effect, axis) -> the trial that added it
        while True:
            trials = {n: {a: self._try(n, a) for a in ax} for n, ax in pool.items() if ax}
            for a in range(3):
                if not any(a in tr for tr in trials.values()):
                    continue
                sd, tau = self._noise(trials, a)
                for tr in trials.values():
                    if a in tr:
                        self._judge(tr[a], a, tau, sd)
            scores = {n: sum(v["score"] for v in tr.values() if v["significant"])
                      for n, tr in trials.items()}
            sig = [n for n in trials if any(v["significant"] for v in trials[n].values())]
            step = {"trials": trials, "scores": scores, "chosen": None}
            self.steps.append(step)
            if not sig:
                break
            win = max(sig, key=lambda n: scores[n])
            step["chosen"] = win
            for a, v in trials[win].items():
                # A power-on shifts every axis at once: a per-run constant found on some axes
                # is taken on every axis where it helps on the held-out segments at all.
                if v["significant"] or (BY_NAME[win].per_run and v["score"] > 0):
                    self.state[a].append((win, v["shape"]))
                    self.cur[a] = v["res"]
                    self.record[(win, a)] = v
                    pool[win].remove(a)
            if win not in chosen:
                chosen.append(win)
        # Effects (or axes) never added: their trial against the final model.
        for n, tr in self.steps[-1]["trials"].items():
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
                    e = next(x for x in EFFECTS if x.name == name)
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
        """Backward check with the whole model in place. The forward pass judged each gain
        against the in-sample residual of every candidate at once, which is liberal: drift and
        temperature shapes fitted in-sample soak up part of a random walk or of a driver the
        catalogue lacks. Here each chosen effect must still be significant against the
        held-out residual of the final model - white when the chosen effects explain the
        data, still correlated when a wander or an unknown driver is left - else the weakest
        goes, and the check repeats. Returns [(effect, axis, z)] removed."""
        removed = []
        for a in range(3):
            while self.state[a]:
                full = self.cur[a]
                r = full["cv"] - np.mean(full["cv"])
                if np.sqrt(np.mean(full["cv"] ** 2)) < PRUNE_ABOVE * self.sigma[a]:
                    break      # the chosen effects explain the data: nothing left to mislead
                tau, sd = noise.autocorr_time(r), float(np.std(r))
                worst = None
                for i, (name, shape) in enumerate(self.state[a]):
                    without = self.state[a][:i] + self.state[a][i + 1:]
                    v = {"name": name, "shape": shape, "res": full}
                    saved = self.cur[a]
                    self.cur[a] = self.prob.evaluate(a, without, withheld=False)
                    self._judge(v, a, tau, sd)
                    self.cur[a] = saved
                    keep = v["t"] > Z_KEEP and v["rms_after"] < v["rms_before"]
                    if not keep and (worst is None or v["t"] < worst[1]):
                        worst = (i, v["t"])
                if worst is None:
                    break
                name = self.state[a][worst[0]][0]
                removed.append((name, a, worst[1]))
                del self.state[a][worst[0]]
                self.cur[a] = self.prob.evaluate(a, self.state[a], withheld=False)
        return removed

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
