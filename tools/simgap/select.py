"""Greedy choice of effects by how much each shrinks the held-out residual, with a block
t-test for significance and a check on which candidates the data cannot tell apart."""
import numpy as np

from .effects import EFFECTS
from .logio import AXES

T_SIG = 2.0          # block t-statistic an improvement must reach (with the CV check below,
                     # two independent held-out sets must agree)
T_STRONG = 4.0       # withheld t-statistic that needs no support from the training segments
Z_STRONG = 8.0       # white-noise z of the gain for effects living in a few stretches
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


def block_t(d, nblocks=40):
    """t-statistic of mean(d) from contiguous block means, so slowly varying residuals
    (which are correlated sample to sample) are not counted as independent evidence."""
    n = len(d)
    B = max(2, min(nblocks, n // 25))
    means = np.array([c.mean() for c in np.array_split(d, B)])
    s = means.std(ddof=1)
    if s == 0:
        return np.inf if means.mean() > 0 else 0.0
    return float(means.mean() / (s / np.sqrt(B)))


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
        self.cur = {a: prob.evaluate(a, []) for a in range(3)}
        self.steps = []
        self.untried = {}
        self.avail = {}
        for e in EFFECTS:
            ax = []
            for a in range(3):
                ok, why = e.available(prob.ctx, prob.train, a)
                if ok:
                    ax.append(a)
                else:
                    self.untried.setdefault(e.name, why)
            if ax:
                self.avail[e.name] = ax
                self.untried.pop(e.name, None)

    def _score_set(self, res):
        return res["w"] if res["w"] is not None else res["cv"]

    def _try(self, name, axis):
        """Best shape of one effect on one axis (by training held-out error) and its
        withheld improvement over the current state."""
        e = next(x for x in EFFECTS if x.name == name)
        best = None
        for shape in e.shapes_given(self.prob.ctx, self.state[axis]):
            res = self.prob.evaluate(axis, self.state[axis] + [(name, shape)], withheld=False)
            ss = float(np.sum(res["cv"] ** 2))
            if best is None or ss < best[0]:
                best = (ss, shape)
        shape = best[1]
        res = self.prob.evaluate(axis, self.state[axis] + [(name, shape)])
        r0, r1 = self._score_set(self.cur[axis]), self._score_set(res)
        ss0, ss1 = float(np.sum(r0 ** 2)), float(np.sum(r1 ** 2))
        t = block_t(r0 ** 2 - r1 ** 2)
        sig2 = self.sigma[axis] ** 2
        cv_ok = True
        if res["w"] is not None:
            # With a withheld log the training segments should agree, not just that one log.
            # They may not while a second effect is still missing (a per-run offset held out
            # together with the unmodelled settling at the start of that run), so a strong
            # withheld improvement stands on its own.
            cv_ok = (np.sum(res["cv"] ** 2) < np.sum(self.cur[axis]["cv"] ** 2)
                     or block_t(r0 ** 2 - r1 ** 2) > T_STRONG)
        # A large gain concentrated in a few stretches (settling after power-on) has too few
        # informative blocks for the block test; a white-noise z-test with a high bar takes
        # it when the block test at least points the same way.
        delta = r0 - r1
        z = (ss0 - ss1) / max(2 * self.sigma[axis] * np.sqrt(np.sum(delta ** 2)), 1e-300)
        strong = z > Z_STRONG and t > 1.0 and ss0 - ss1 > 0.05 * ss0
        significant = bool((t > T_SIG or strong) and ss0 - ss1 > MIN_REL * ss0
                           and ss0 - ss1 > MIN_NOISE * len(r0) * sig2 and cv_ok)
        return {"shape": shape, "res": res, "rms_before": float(np.sqrt(ss0 / len(r0))),
                "rms_after": float(np.sqrt(ss1 / len(r1))), "t": t, "significant": significant,
                "score": (ss0 - ss1) / max(sig2, 1e-300)}

    def run(self):
        """Add the best significant effect (on the axes where it is significant) until none
        is left; an effect already added on some axes stays a candidate for the others."""
        pool = {n: list(ax) for n, ax in self.avail.items()}
        chosen = []
        self.record = {}          # (effect, axis) -> the trial that added it
        while True:
            trials = {n: {a: self._try(n, a) for a in ax} for n, ax in pool.items() if ax}
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
                if v["significant"]:
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
            self.cur[a] = self.prob.evaluate(a, self.state[a])

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
