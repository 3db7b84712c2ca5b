"""The whole diagnosis of one training log (and optional withheld log): returns the JSON
contract as a dict, plus the arrays the plot needs."""
import numpy as np

from . import augmented, prep
from .effects import CATALOGUE
from .fit import Problem
from .logio import AXES
from .select import Greedy, design_gaps
from .where import localise


def _rms(v):
    return float(np.sqrt(np.mean(v ** 2))) if len(v) else float("nan")


def _per_axis(values, axes):
    return {AXES[a]: float(values[a]) for a in axes}


def diagnose(train, withheld=None, model=None):
    prob = Problem(train, withheld, model)
    base_t = np.column_stack([prob.full_residual(prob.train, a, []) for a in range(3)])
    sigma_t = prep.noise_floor(base_t, train, prob.train.mask)
    if withheld is not None:
        base_w = np.column_stack([prob.full_residual(prob.withheld, a, []) for a in range(3)])
        sigma = prep.noise_floor(base_w, withheld, prob.withheld.mask)
        source = f"withheld log {withheld.name}"
    else:
        sigma = sigma_t
        source = f"held-out segments of the training log ({prob.nfold} contiguous blocks)"
    g = Greedy(prob, sigma)
    verdict = g.run()
    g.refine()

    def scored(res):
        return res["w"] if res["w"] is not None else res["cv"]

    sim_only = [_rms(scored(prob.evaluate(a, []))) for a in range(3)]
    effects = []
    order = {n: i for i, n in enumerate(verdict)}
    for name in CATALOGUE:
        if name not in g.avail:
            continue
        rec = {a: g.record[(name, a)] for a in g.avail[name] if (name, a) in g.record}
        added = [a for a in rec if (name, a) in dict.fromkeys(
            (n, ax) for ax, blocks in g.state.items() for n, _ in blocks)]
        axes = added or list(rec)
        before = {a: rec[a]["rms_before"] for a in rec}
        after = {a: rec[a]["rms_after"] for a in rec}
        b2 = sum(before[a] ** 2 for a in axes)
        a2 = sum(after[a] ** 2 for a in axes)
        effects.append({
            "name": name, "axes": [AXES[a] for a in axes],
            "withheld_rms_before": _per_axis(before, rec),
            "withheld_rms_after": _per_axis(after, rec),
            "shrink": float(1 - np.sqrt(a2 / b2)) if b2 > 0 else 0.0,
            "significant": name in order,
            "rank": order.get(name),
            "shape": {AXES[a]: _shape_str(v["shape"]) for a, v in rec.items()},
            "t": {AXES[a]: round(float(v["t"]), 2) for a, v in rec.items()},
        })
    final = [_rms(scored(g.cur[a])) for a in range(3)]
    # Waterfall: per-axis withheld RMS after each greedy step.
    waterfall = [{"added": None, "withheld_rms": _per_axis(sim_only, range(3))}]
    for s in g.steps:
        if s["chosen"] is None:
            continue
        prev = dict(waterfall[-1]["withheld_rms"])
        for a, v in s["trials"][s["chosen"]].items():
            if v["significant"]:
                prev[AXES[a]] = v["rms_after"]
        waterfall.append({"added": s["chosen"], "withheld_rms": prev})
    confused, apart = g.confusions()
    gaps = design_gaps(prob, verdict, g.untried)
    seen = {frozenset(c["effects"]) for c in confused}
    not_ident = confused + [c for c in gaps if frozenset(c["effects"]) not in seen]
    where = localise(prob.train, base_t, sigma_t, prob.ctx)
    result = {
        "verdict": verdict,
        "effects": effects,
        "where": where,
        "final": {"withheld_rms": _per_axis(final, range(3)),
                  "unexplained_rms": {AXES[a]: float(np.sqrt(max(0.0, final[a] ** 2 - sigma[a] ** 2)))
                                      for a in range(3)},
                  "ratio_to_noise": {AXES[a]: float(final[a] / sigma[a]) if sigma[a] > 0 else None
                                     for a in range(3)}},
        "sim_only": {"withheld_rms": _per_axis(sim_only, range(3))},
        "noise_floor": _per_axis(sigma, range(3)),
        "noise_floor_train": _per_axis(sigma_t, range(3)),
        "not_identifiable": not_ident,
        "told_apart": apart,
        "untried": [{"name": n, "reason": r} for n, r in g.untried.items()],
        "waterfall": waterfall,
        "withheld_source": source,
        "unit": train.unit,
        "sim": "given model" if model is not None else "fitted on the training log",
        "rows": {"train": len(train), "train_outliers": int((~prob.train.mask).sum()),
                 "withheld": len(withheld) if withheld is not None else 0,
                 "withheld_outliers": int((~prob.withheld.mask).sum()) if withheld is not None else 0},
    }
    model_json = augmented.build(prob, g.state)
    held = prob.withheld if withheld is not None else prob.train
    model_json["host_check"] = augmented.host_check(model_json, prob, held,
                                                    "withheld" if withheld is not None else "training")
    result["model"] = model_json
    extras = {"prob": prob, "base_train": base_t, "greedy": g}
    return result, extras


def _shape_str(s):
    if isinstance(s, tuple) and isinstance(s[0], str):
        return f"{s[0]} tau={s[1]:.4g}s"
    if isinstance(s, tuple):   # hysteresis on a lagged temperature: (width, lag)
        return f"{float(s[0]):.4g} on lag tau={float(s[1]):.4g}s"
    if isinstance(s, float):
        return f"{s:.4g}"
    return str(s)
