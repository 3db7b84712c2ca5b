"""The fitted model - the sim plus the verdict's effects - as the JSON `model` section, in
physical units and in terms a device can evaluate sample by sample (docs/API in
docs/simgap.md, "The model section"). `predict` evaluates the section itself, so the host's
figures in `host_check` come from exactly the numbers a device receives."""
import numpy as np
from scipy.interpolate import BSpline

from . import features as F
from .effects import TempRate
from .logio import AXES

SCHEMA = "tempcomp.simgap.model/1"

# Term names per effect, in the order of the effect's regressor columns (effects.py).
TERMS = {
    "temp_rate": ("D1", "D1_dT", "D2", "D2_dT", "D1_sq", "ref_D1", "ref_D2"),
    "temp_quantization": ("e", "e_dT", "e_ref", "soak"),    # soak: only with soaks in training
}
SUPPLY_TERMS = {"linear": ("v",), "quadratic": ("v", "v_sq"), "linear+ratiometric": ("v", "v_ref"),
                "quadratic+ratiometric": ("v", "v_sq", "v_ref"),
                "full": ("v", "v_sq", "v_ref", "v_dT")}
NL_TERMS = {"square": ("ref_sq",), "cube": ("ref_cube",), "square+cube": ("ref_sq", "ref_cube"),
            "odd-square+cube": ("ref_absref", "ref_cube")}


def _f(v):
    return float(v)


def _knots(ctx, n_inner):
    lo, hi = ctx.tmin, ctx.tmax
    inner = np.linspace(lo, hi, n_inner + 2)[1:-1]
    return [_f(k) for k in np.r_[[lo] * 4, inner, [hi] * 4]]


def effect_entry(ctx, name, shape, coef, axis, causal_temp):
    """One effect's JSON entry: its shape parameters and coefficients in physical units."""
    c = [_f(v) for v in coef]
    e = {"name": name}
    if name == "offset_temperature":
        e.update(form="spline", degree=3, knots_c=_knots(ctx, shape), clamp_c=[ctx.tmin, ctx.tmax],
                 coef=c)
    elif name == "sensitivity_temperature":
        if shape == 0:
            e.update(form="poly", coef={"ref_dT2": c[0], "ref_dT3": c[1]})
        else:
            e.update(form="spline", degree=3, knots_c=_knots(ctx, shape),
                     clamp_c=[ctx.tmin, ctx.tmax], coef=c)
    elif name == "hysteresis":
        w, tau = shape if isinstance(shape, tuple) else (shape, 0.0)
        e.update(widths_c=[_f(w), _f(2 * w), _f(4 * w)], lag_tau_s=_f(tau),
                 input="reading" if causal_temp else "destaired", coef=c)
    elif name == "temp_rate":
        t1, t2 = TempRate.time_constants(shape)
        e.update(tau_s=[_f(t1), _f(t2)], input="reading" if causal_temp else "destaired",
                 coef=dict(zip(TERMS[name], c)))
    elif name == "cross_axis":
        others = [AXES[b] for b in range(3) if b != axis]
        e.update(form=shape, from_axes=others, coef=c[:2])
        if shape != "linear":
            e["coef_dT"] = c[2:]
    elif name == "nonlinearity":
        e.update(form=shape, coef=dict(zip(NL_TERMS[shape], c)))
    elif name == "g_sensitivity":
        e.update(form=shape, coef=c[:3])
        if shape != "linear":
            e["coef_dT"] = c[3:]
    elif name == "supply":
        e.update(form=shape, v0=_f(ctx.supply_mean), coef=dict(zip(SUPPLY_TERMS[shape], c)))
    elif name == "drift":
        f, tau = shape
        if f == "linear":
            e.update(form=f, tau_s=0.0, coef={"slope_per_s": c[0]})
        else:
            e.update(form=f, tau_s=_f(tau), coef={"amplitude": c[0]})
        if f == "exp+linear":
            e["coef"]["slope_per_s"] = c[1]
    elif name == "temp_quantization":
        e.update(smooth=_f(shape), coef=dict(zip(TERMS[name], c)))
    else:
        raise ValueError(name)
    return e


def build(prob, state, extra_bias=None):
    """The `model` section for the final per-axis effect lists `state` {axis: [(name, shape)]}.
    extra_bias {axis: {withheld run: shift}}: constants recognised on a withheld log's own
    power-on(s), captured from the first rows of each run."""
    ctx = prob.ctx
    log = prob.train.log
    time_unit = "row" if "row index" in log.meta.get("time", "") else "s"
    out = {"schema": SCHEMA, "sensor": ctx.sensor, "out_unit": log.unit,
           "ref_unit": log.meta.get("ref_unit", "ref"), "acc_unit": "g", "supply_unit": "V",
           "time_unit": time_unit, "t0_c": ctx.t0, "temp_range_c": [ctx.tmin, ctx.tmax],
           "sample_period_s": ctx.dt,
           "sim": "given" if prob.model is not None else "fitted",
           "base_only": {}, "axes": {}}
    for a in range(3):
        ax = AXES[a]
        base0, _, _ = prob.coefficients(a, [])
        base, parts, tob = prob.coefficients(a, state[a])
        if prob.model is not None:
            (o, s) = prob.model.coef[ax]
            shift = prob.model.t0 - ctx.t0
            base0 = base = _shift_base(o, s, shift)
        out["base_only"][ax] = _base_json(base0)
        entry = _base_json(base)
        if prob.model is None:
            keep, why = ctx.base[a]
            entry["identified"] = {"offset": keep[:3], "sensitivity": keep[3:]}
            if why:
                entry["not_identified_because"] = why
        effects = [effect_entry(ctx, n, sh, c, a, not ctx.quantised) for n, sh, c in parts]
        if tob is not None or (extra_bias and a in extra_bias):
            e = {"name": "turn_on_bias", "new_run": "capture"}
            if tob is not None:
                e["per_run"] = {str(k): v for k, v in tob.items()}
            if extra_bias and a in extra_bias:
                e["withheld_shift"] = {str(k): _f(v) for k, v in extra_bias[a].items()}
            effects.append(e)
        entry["effects"] = effects
        out["axes"][ax] = entry
    return out


def _shift_base(o, s, shift):
    """A given model's polynomial (in T - t0') re-expanded about the tool's t0 (shift =
    t0' - t0): o(T) = o0 + o1 (d - shift) + o2 (d - shift)^2."""
    o0, o1, o2 = o
    s0, s1 = s
    return np.array([o0 - o1 * shift + o2 * shift ** 2, o1 - 2 * o2 * shift, o2,
                     s0 - s1 * shift, s1])


def _base_json(b):
    return {"offset": [_f(v) for v in b[:3]], "sensitivity": [_f(v) for v in b[3:5]]}


def _bspline(e, T):
    k = np.asarray(e["knots_c"])
    lo, hi = e["clamp_c"]
    x = np.clip(T, lo, hi - 1e-9 * max(1.0, hi - lo))
    return BSpline.design_matrix(x, k, e["degree"]).toarray() @ np.asarray(e["coef"])


def predict(model, log, p, axis, base_only=False):
    """Evaluate the section on log (prepared as p) for one axis, as a device would (the filters
    run causally over the rows; the destaired temperature is the host's, see the docs)."""
    ax = AXES[axis]
    T = log.temp
    dT = T - model["t0_c"]
    ref = log.ref[:, axis]
    b = model["base_only"][ax] if base_only else model["axes"][ax]
    o0, o1, o2 = b["offset"]
    s0, s1 = b["sensitivity"]
    y = o0 + o1 * dT + o2 * dT * dT + (s0 + s1 * dT) * ref
    if base_only:
        return y
    for e in model["axes"][ax]["effects"]:
        y = y + _effect_value(model, e, log, p, axis, T, dT, ref)
    return y


def _effect_value(model, e, log, p, axis, T, dT, ref):
    n = e["name"]
    c = e.get("coef")
    if n == "offset_temperature":
        return _bspline(e, T)
    if n == "sensitivity_temperature":
        if e["form"] == "poly":
            return ref * (c["ref_dT2"] * dT ** 2 + c["ref_dT3"] * dT ** 3)
        return ref * _bspline(e, T)
    if n == "hysteresis":
        tau = e["lag_tau_s"]
        q = e.get("input") == "destaired"
        u = F.temperature(p, tau, q, reading=T)
        return sum(ck * (F.play(p, w, tau, q) - u) for ck, w in zip(c, e["widths_c"]))
    if n == "temp_rate":
        q = e["input"] == "destaired"
        u = F.temperature(p, 0.0, q, reading=T)
        D1 = u - F.lowpass(p, e["tau_s"][0], q)
        D2 = u - F.lowpass(p, e["tau_s"][1], q)
        cols = {"D1": D1, "D1_dT": D1 * dT, "D2": D2, "D2_dT": D2 * dT, "D1_sq": D1 * D1,
                "ref_D1": ref * D1, "ref_D2": ref * D2}
        return sum(c[k] * cols[k] for k in c)
    if n == "cross_axis":
        o = np.column_stack([log.ref[:, AXES.index(a)] for a in e["from_axes"]])
        v = o @ np.asarray(c)
        if "coef_dT" in e:
            v = v + (o * dT[:, None]) @ np.asarray(e["coef_dT"])
        return v
    if n == "nonlinearity":
        cols = {"ref_sq": ref ** 2, "ref_cube": ref ** 3, "ref_absref": ref * np.abs(ref)}
        return sum(c[k] * cols[k] for k in c)
    if n == "g_sensitivity":
        acc = log.acc if log.acc is not None else np.zeros((len(log), 3))
        v = acc @ np.asarray(c)
        if "coef_dT" in e:
            v = v + (acc * dT[:, None]) @ np.asarray(e["coef_dT"])
        return v
    if n == "supply":
        s = log.supply if log.supply is not None else np.full(len(log), e["v0"])
        v = s - e["v0"]
        cols = {"v": v, "v_sq": v * v, "v_ref": v * ref, "v_dT": v * dT}
        return sum(c[k] * cols[k] for k in c)
    if n == "drift":
        if e["form"] == "linear":
            return c["slope_per_s"] * p.ton
        x = p.ton / e["tau_s"]
        if e["form"] == "hyperbolic":
            return c["amplitude"] / (1.0 + x)
        v = c["amplitude"] * np.exp(-x)
        if e["form"] == "exp+linear":
            v = v + c["slope_per_s"] * p.ton
        return v
    if n == "temp_quantization":
        u = F.unstair(p, e["smooth"]) - T
        v = c["e"] * u + c["e_dT"] * u * dT + c["e_ref"] * u * ref
        if "soak" in c:
            v = v + c["soak"] * F.soak_weight(p)
        return v
    if n == "turn_on_bias":
        return np.zeros(len(log))   # a constant captured per power-on (host_check removes it)
    raise ValueError(n)


def host_check(model, prob, p, name):
    """RMS of (out - prediction) per axis on prepared log p, base alone and augmented, with
    every power-on's own constant removed where the model has turn_on_bias; the figures a
    device replay of the same rows should reproduce."""
    m = p.mask
    runs = p.log.run if p.log.run is not None else np.zeros(len(p), int)
    rms = {"base_only": {}, "augmented": {}}
    for a in range(3):
        ax = AXES[a]
        for key, bo in (("base_only", True), ("augmented", False)):
            r = (p.log.out[:, a] - predict(model, p.log, p, a, base_only=bo))[m]
            if not bo and any(e["name"] == "turn_on_bias" for e in model["axes"][ax]["effects"]):
                rr = runs[m]
                for k in np.unique(rr):
                    r[rr == k] -= r[rr == k].mean()
            rms[key][ax] = float(np.sqrt(np.mean(r * r))) if r.size else None
    return {"log": name, "rows": int(m.sum()), "rms": rms, "unit": model["out_unit"]}

