"""The diagnosis' model section (schema tempcomp.simgap.model/1) as a model the board runs
(lib/tempcomp/augment.py): `python -m tools.simgap TRAIN.csv ... --json OUT.json --export MODEL.json`.

MODEL.json holds
  "device": the augmented model (the base re-fitted with the verdict's effects, and the effects
            as augment.py features and terms), in the integers a board reads (its "board" LSBs);
  "base":   the sim alone (the diagnosis' base_only fit), what `replay --base-only` runs;
  "store":  the device model packed for the coefficient store (`python -m tools store put`),
            "store_base" the same for the base (`put --base`);
  "on_device" / "not_on_device": which verdict effects the board applies, and why not the others;
  "host":   the diagnosis' own RMS on the withheld log (sim alone and augmented) to compare with
            a replay.
An empty verdict exports the base model (device == base)."""
import json

import numpy as np

from . import devmodel

FORMAT = "tempcomp.augmented-model/1"
# out unit per ref unit where a log's input never changes and the sensitivity is unidentified
UNIT_RATIO = {("mdps", "dps"): 1000.0, ("dps", "dps"): 1.0, ("mg", "g"): 1000.0, ("g", "g"): 1.0,
              ("udps", "dps"): 1e6, ("mdps", "mdps"): 1.0, ("mg", "mg"): 1.0}
T_LSB = 0.01  # the board's temperature reading in the export: centi-degC
SUPPLY_LSB = 0.001
ACC_LSB = 0.001
GAIN_LIMIT = 0.06  # augment.py refuses sensitivity terms above 1/16 at the features' bounds


class ExportError(ValueError):
    pass


class _Builder:
    def __init__(self):
        self.features = []
        self.offset_terms = [[], [], []]
        self.gain_terms = [[], [], []]
        self.cross = [[], [], []]

    def feat(self, kind, **p):
        f = dict(kind=kind, **p)
        for i, g in enumerate(self.features):
            if g == f:
                return i
        self.features.append(f)
        return len(self.features) - 1

    def prod(self, a, b):
        return self.feat("prod", a=min(a, b), b=max(a, b))


def _s0(ax):
    return float(ax["sensitivity"][0])


def _effect(b, e, i, ax, notes):
    """Add effect entry e of axis i; returns None or the reason it cannot run on a board."""
    name = e["name"]
    s0 = _s0(ax)
    if name == "hysteresis":
        lag = float(e.get("lag_tau_s", 0.0))
        if e.get("input") == "destaired":
            notes.append("hysteresis on axis %d: the host used the destaired reading; the board "
                         "uses its reading" % i)
        for w, c in zip(e["widths_c"], e["coef"]):
            p = {"width": float(w)}
            if lag > 0:
                p["lag"] = lag
            b.offset_terms[i].append([b.feat("play", **p), float(c)])
    elif name == "temp_rate":
        t1, t2 = (float(t) for t in e["tau_s"])
        if e.get("input") == "destaired":
            notes.append("temp_rate on axis %d: the host used the destaired reading; the board "
                         "uses its reading" % i)
        c = e["coef"]
        d1, d2, dT = b.feat("lag", tau=t1), b.feat("lag", tau=t2), b.feat("dT")
        for fi, k in ((d1, "D1"), (b.prod(d1, dT), "D1_dT"), (d2, "D2"), (b.prod(d2, dT), "D2_dT"),
                      (b.prod(d1, d1), "D1_sq")):
            if c.get(k):
                b.offset_terms[i].append([fi, float(c[k])])
        for fi, k in ((d1, "ref_D1"), (d2, "ref_D2")):
            if c.get(k):
                b.gain_terms[i].append([fi, float(c[k]) / s0])
    elif name == "drift" and e["form"] == "linear":
        b.offset_terms[i].append([b.feat("uptime"), float(e["coef"]["slope_per_s"])])
    elif name == "drift":
        tau = float(e["tau_s"])
        c = e["coef"]
        kind = {"exp": "drift_exp", "exp+linear": "drift_exp", "hyperbolic": "drift_hyp"}.get(e["form"])
        if kind is None:
            return "drift form %r unknown to the board" % e["form"]
        b.offset_terms[i].append([b.feat(kind, tau=tau), float(c["amplitude"])])
        if c.get("slope_per_s"):
            b.offset_terms[i].append([b.feat("uptime"), float(c["slope_per_s"])])
    elif name == "g_sensitivity":
        dT = b.feat("dT")
        for k in range(3):
            a = b.feat("acc", axis=k)
            b.offset_terms[i].append([a, float(e["coef"][k])])
            if e.get("coef_dT"):
                b.offset_terms[i].append([b.prod(a, dT), float(e["coef_dT"][k])])
    elif name == "cross_axis":
        axes = "xyz"
        for j, src in enumerate(e["from_axes"]):
            k1 = float(e["coef_dT"][j]) / s0 if e.get("coef_dT") else 0.0
            if k1:
                b.feat("dT")
            b.cross[i].append([axes.index(src), float(e["coef"][j]) / s0, k1])
    elif name == "supply":
        return "supply is handled with the model's v0"  # (see _supply)
    elif name == "sensitivity_temperature" and e.get("form") == "poly":
        dT = b.feat("dT")
        d2 = b.prod(dT, dT)
        c = e["coef"]
        if c.get("ref_dT2"):
            b.gain_terms[i].append([d2, float(c["ref_dT2"]) / s0])
        if c.get("ref_dT3"):
            b.gain_terms[i].append([b.prod(d2, dT), float(c["ref_dT3"]) / s0])
    else:
        reason = {"offset_temperature": "folded into the board's cubic offset(T)",
                  "sensitivity_temperature": "a spline sensitivity(T) has no board form",
                  "nonlinearity": "no board form (input-dependent gain)",
                  "temp_quantization": "needs the future of the reading (non-causal)",
                  "turn_on_bias": "a per-power-on constant: capture it at start-up (session re-zero)"}
        return reason.get(name, "unknown to the board")
    return None


def _supply(b, e, i, ax, v0):
    # v = supply - v0_axis = u + d with u = supply - v0 (the board's one v0), d = v0 - v0_axis
    d = v0 - float(e["v0"])
    c = e["coef"]
    s0 = _s0(ax)
    u = b.feat("supply")
    o = list(ax["offset"])
    s = list(ax["sensitivity"])
    cv, cq, cr, cd = (float(c.get(k, 0.0)) for k in ("v", "v_sq", "v_ref", "v_dT"))
    o[0] += cv * d + cq * d * d
    if cv or cq:
        b.offset_terms[i].append([u, cv + 2 * cq * d])
    if cq:
        b.offset_terms[i].append([b.prod(u, u), cq])
    if cr:
        s[0] += cr * d
        b.gain_terms[i].append([u, cr / s0])
    if cd:
        o[1] += cd * d
        b.offset_terms[i].append([b.prod(u, b.feat("dT")), cd])
    ax["offset"], ax["sensitivity"] = o, s


def _cubic_offset(ax, spline, trange):
    """The offset_temperature spline's values on a grid over the training range (the board's
    offset is one polynomial, fitted to base + spline by the caller); returns (values, T)."""
    from scipy.interpolate import BSpline
    lo, hi = trange
    T = np.linspace(lo, hi, 400)
    knots = np.asarray(spline["knots_c"])
    cl = np.clip(T, spline["clamp_c"][0], spline["clamp_c"][1] - 1e-9 * max(1.0, hi - lo))
    val = BSpline.design_matrix(cl, knots, int(spline.get("degree", 3))).toarray() @ np.asarray(spline["coef"])
    return val, T


def build(res, train_log, sensitivity=None):
    """The export dict from a diagnosis result (its "model" section) and the training log."""
    mod = res.get("model")
    if not mod or mod.get("schema") != "tempcomp.simgap.model/1":
        raise ExportError("the diagnosis result has no model section of schema tempcomp.simgap.model/1")
    t0 = float(mod["t0_c"])
    tr = [float(v) for v in mod["temp_range_c"]]
    axes = "xyz"
    # what a board can read; everything below is in these units
    out = train_log.out
    # the offsets must stay inside the raw range where the board extrapolates them (the
    # calibrated span widened by half of it each side, fixedpoint.EXTRAPOLATE)
    half = (tr[1] - tr[0]) / 2
    Tx = np.linspace(tr[0] - half, tr[1] + half, 200) - t0
    reach = max(float(np.max(np.abs(out))),
                max(float(np.max(np.abs(np.polyval(list(reversed(g[a]["offset"])), Tx))))
                    for g in (mod["axes"], mod["base_only"]) for a in axes))
    if np.all(out == np.round(out)) and reach < 32768:
        raw_lsb = 1.0
    else:
        raw_lsb = reach * 1.25 / 32767
    ratio = UNIT_RATIO.get((mod["out_unit"], mod["ref_unit"]))
    notes = []
    b = _Builder()
    aug = {a: json.loads(json.dumps(mod["axes"][a])) for a in axes}
    base = {a: json.loads(json.dumps(mod["base_only"][a])) for a in axes}
    for group in (aug, base):
        for i, a in enumerate(axes):
            ax = group[a]
            ident = (mod["axes"][a].get("identified") or {}).get("sensitivity", [True])[0]
            if np.ptp(train_log.ref[:, i]) == 0 or not ident or not _s0(ax) > 0:
                nominal = sensitivity or ratio
                if nominal is None:
                    raise ExportError("axis %s: the log never moves the input, so the sensitivity is "
                                      "not identified; give --sensitivity (%s per %s)"
                                      % (a, mod["out_unit"], mod["ref_unit"]))
                if group is aug:
                    notes.append("axis %s: sensitivity not identified by the log (input never "
                                 "changes); nominal %g %s per %s" % (a, nominal, mod["out_unit"], mod["ref_unit"]))
                # the fit put s * ref into the offset where the input stood still at r0 (gravity on
                # an accelerometer's axis): take the nominal s * r0 back out of it
                r0 = float(np.median(train_log.ref[:, i]))
                o = [float(c) for c in ax["offset"]]
                o[0] -= (float(nominal) - _s0(ax)) * r0 if _s0(ax) > 0 else float(nominal) * r0
                ax["offset"] = o
                ax["sensitivity"] = [float(nominal), 0.0]
    on, off = [], []
    v0 = None
    for i, a in enumerate(axes):
        ax = aug[a]
        for e in ax.get("effects", []):
            if e["name"] == "supply":
                v0 = float(e["v0"]) if v0 is None else v0
                _supply(b, e, i, ax, v0)
                why = None
            elif e["name"] == "offset_temperature":
                val, T = _cubic_offset(ax, e, tr)
                d = T - t0
                basev = np.polyval(list(reversed(ax["offset"])), d)
                c = np.polyfit(d, basev + val, 3)[::-1]
                dev = float(np.max(np.abs(np.polyval(c[::-1], d) - basev - val)))
                ax["offset"] = [float(x) for x in c]
                notes.append("offset_temperature on axis %s: the board's cubic offset(T) follows the "
                             "spline within %.3g %s over %.1f..%.1f degC" % (a, dev, mod["out_unit"], tr[0], tr[1]))
                why = None
            else:
                why = _effect(b, e, i, ax, notes)
            (off if why else on).append({"name": e["name"], "axis": a, **({"reason": why} if why else {})})
    board = {"t_lsb": T_LSB, "t_off": 0.0, "raw_lsb": raw_lsb, "raw_range": [-32768, 32767],
             "t0": t0, "t_cal": tr, "supply_lsb": SUPPLY_LSB, "supply0": v0 or 0.0, "acc_lsb": ACC_LSB}

    def dev_model(group, with_terms):
        s_min = min(_s0(group[a]) for a in axes)
        # output counts per ref unit: a power of ten giving 1.6..16 counts per raw code
        out_scale = float(10.0 ** np.floor(np.log10(16 * s_min / raw_lsb)))
        m = dict(board, out_scale=out_scale,
                 offset=[[float(c) for c in group[a]["offset"]] for a in axes],
                 sensitivity=[[float(c) for c in group[a]["sensitivity"]] for a in axes])
        if with_terms:
            m.update(features=json.loads(json.dumps(b.features)), offset_terms=b.offset_terms,
                     gain_terms=b.gain_terms, cross=b.cross)
        return m

    dev = dev_model(aug, True)
    _set_bounds(dev, train_log)
    return {"format": FORMAT, "unit": mod["ref_unit"], "out_unit": mod["out_unit"],
            "time_unit": mod.get("time_unit", "s"), "verdict": list(res.get("verdict", [])),
            "on_device": on, "not_on_device": off, "notes": notes,
            "device": dev, "base": dev_model(base, False),
            "host": mod.get("host_check")}


def _set_bounds(dev, log):
    """Clamp bounds of the features from the training log: twice the largest value seen (the
    board counts a clamp); shrunk towards 1.2x if the sensitivity terms would exceed 1/16."""
    feats = dev.get("features", [])
    if not feats:
        return
    inp = devmodel.board_inputs(dev, log, 0.0)
    F = devmodel.features(dev, inp)
    peak = np.max(np.abs(F), axis=0) if len(F) else np.zeros(len(feats))
    for margin in (2.0, 1.5, 1.2):
        for j, f in enumerate(feats):
            if f["kind"] in ("lag", "supply", "acc", "prod"):
                floor = {"lag": 0.5, "supply": 0.05, "acc": 1.0, "prod": 1e-9}[f["kind"]]
                f["bound"] = float(max(margin * peak[j], floor))
            elif f["kind"] == "uptime":
                f["bound"] = float(max(margin * peak[j], 86400.0))
        worst = 0.0
        for i in range(3):
            g = sum(abs(c) * feats[fi].get("bound", 1.0) for fi, c in dev["gain_terms"][i])
            worst = max(worst, g)
        if worst <= GAIN_LIMIT:
            return
    raise ExportError("the sensitivity terms reach %.3g of the sensitivity at the training log's "
                      "extremes; the board supports 1/16" % worst)


def pack(dev):
    """The device model as the store's values: (ints, frac) per value, ~30 significant bits."""
    import sys

    from tools import LIB
    if LIB not in sys.path:
        sys.path.insert(0, LIB)
    from tempcomp import augment  # the device's own layout
    vals, fracs = [], []
    for x in augment.pack(dev):
        f = 30 - int(np.ceil(np.log2(abs(x) + 1e-300))) if x else 0
        f = int(max(-31, min(31, f)))
        v = int(round(x * 2.0 ** f))
        while abs(v) >= 2 ** 31:
            f -= 1
            v = int(round(x * 2.0 ** f))
        vals.append(v)
        fracs.append(f)
    return vals, fracs


def write(path, res, train_log, sensitivity=None):
    exp = build(res, train_log, sensitivity)
    for key, dev in (("store", exp["device"]), ("store_base", exp["base"])):
        vals, fracs = pack(dev)
        exp[key] = {"kind": "augment", "values": vals, "frac": fracs}
    with open(path, "w") as f:
        json.dump(exp, f, indent=1)
    return exp
