"""Human-readable summary and the PNG: residual against temperature and against time for the
training and the withheld log, the where-map by excess over the noise floor, and the
before/after waterfall. One colour per axis everywhere (AXIS_COLOURS)."""
import numpy as np

from .logio import AXES

AXIS_COLOURS = {"x": "#1f77b4", "y": "#2ca02c", "z": "#d62728"}
WITHHELD_COLOUR = "#444444"


def _fmt_ratio(v):
    return "n/a" if v is None else f"{v:.2f}x"


def text(res):
    u = res["unit"]
    L = []
    L.append(f"sim: {res['sim']}; effects chosen on {res.get('selected_on', 'held-out data')}; "
             f"scored on {res['withheld_source']}")
    rows = res["rows"]
    L.append(f"rows: train {rows['train']} ({rows['train_outliers']} outliers dropped)"
             + (f", withheld {rows['withheld']} ({rows['withheld_outliers']} outliers dropped)"
                if rows["withheld"] else ""))
    nf = res["noise_floor"]
    L.append("white noise floor: " + ", ".join(f"{a} {nf[a]:.4g}" for a in nf) + f" {u}")
    mf = res.get("model_floor", nf)
    L.append("noise model's floor (white + what the wandering bias adds there): "
             + ", ".join(f"{a} {mf[a]:.4g}" for a in mf) + f" {u}")
    for a, nm in res.get("noise_model", {}).items():
        parts = [f"white {nm['white']['sigma']:.4g} {u}"]
        if nm.get("random_walk"):
            rw = nm["random_walk"]
            parts.append(f"random walk K {rw['K']:.3g} {rw['unit']}"
                         + (f" (dominates from {rw['read_at']:.3g} {nm['averaging_time_unit']})"
                            if rw.get("read_at") else ""))
        if nm.get("bias_instability"):
            bi = nm["bias_instability"]
            parts.append(f"bias instability {bi['sigma']:.3g} {u}, Tc {bi['tau_c']:.3g} "
                         f"{nm['averaging_time_unit']}")
        L.append(f"noise model {a}: " + ", ".join(parts))
    so = res["sim_only"]["withheld_rms"]
    L.append("scored RMS, sim only: " + ", ".join(f"{a} {so[a]:.4g}" for a in so) + f" {u}")
    ratio = res["final"]["ratio_to_noise"]
    high = [(a, r) for a, r in ratio.items() if r is not None and r > 1.5]
    if res["verdict"]:
        L.append("verdict (strongest first): " + ", ".join(res["verdict"]))
    elif high:
        L.append("verdict: none - no effect in the catalogue explains what is left: "
                 + ", ".join(f"{a} at {r:.2f}x the noise floor" for a, r in high)
                 + " (see warnings)")
    else:
        L.append("verdict: none - the sim explains the data to within 1.5x the noise floor on "
                 "every axis, as far as this data can tell")
    for e in sorted(res["effects"], key=lambda e: (not e["significant"], e["rank"] or 0, -e["shrink"])):
        mark = "*" if e["significant"] else " "
        ax = ",".join(e["axes"])
        shown = e["axes"] if e["significant"] else e["withheld_rms_before"]
        pa = "; ".join(f"{a} {e['withheld_rms_before'][a]:.4g}->{e['withheld_rms_after'][a]:.4g}"
                       for a in shown if a in e["withheld_rms_before"])
        on = e.get("scored_on", "withheld")
        ci = e.get("shrink_interval") or [None, None]
        cis = (f" [90 % {100 * ci[0]:.1f}..{100 * ci[1]:.1f}%]" if ci[0] is not None else "")
        L.append(f" {mark} {e['name']:<24} shrink {100 * e['shrink']:6.1f}%{cis} on {ax:<6} ({pa}) [{on}]")
    fin = res["final"]
    iv = fin.get("withheld_rms_interval", {})

    def _iv(a):
        c = iv.get(a) or [None, None]
        return f" [90 % {c[0]:.4g}..{c[1]:.4g}]" if c[0] is not None else ""

    L.append("final scored RMS: " + ", ".join(
        f"{a} {fin['withheld_rms'][a]:.4g}{_iv(a)} ({_fmt_ratio(fin['ratio_to_noise'][a])} the model "
        f"floor, {_fmt_ratio(fin.get('ratio_to_white_floor', {}).get(a))} the white floor)"
        for a in fin["withheld_rms"]) + f" {u}")
    sp = res.get("withheld_split")
    if sp and (sp["confirmations"] or sp.get("step_rivals")):
        L.append(f"withheld log split in {sp['blocks']} alternating blocks of {sp['block_rows']} rows: "
                 f"half A ({sp['rows_a']} rows) confirms, half B ({sp['rows_b']} rows) scores "
                 f"{'the figures above' if sp['scored_on'] == 'half B' else 'nothing (A confirmed nothing; the whole log scored)'}")
        for c in sp["confirmations"]:
            L.append(f"{'confirmed' if c['confirmed'] else 'not confirmed'} on withheld half A: "
                     f"{c['effect']} on {c['axis']}, refused on the training log only by the wander's "
                     f"scale (z {c['z_chi2']:.2f} at chi-squared, {c['z_train']:.2f} calibrated); "
                     f"p on half A {c['p_withheld_a']:.2g}, Fisher-combined p {c['p_combined']:.2g} "
                     f"(needs z >= {c['z_pass']:.2f})")
    for c in (sp or {}).get("step_rivals", []):
        L.append(f"{c['effect']} on {c['axis']}: an offset step at an unlogged time explains it as well on "
                 f"the training log (z {c['z_train']:.2f}); on withheld half A, against that step moved to "
                 f"its best time there, z {c['z_withheld_a']:.2f} (needs {c['z_pass']:.2f}): "
                 + ("kept" if c["kept"] else "not kept"))
    for c in res.get("borrow_checks", []):
        p = c["p_withheld_a"]
        m = c["bic_margin"]
        fit = (f"{c['rival']} (significant there) fits this axis better on the training log by {m:.1f} "
               "(BIC units)" if m > 0 else
               f"{c['rival']} is significant there and {c['effect']} makes its held-out segments worse "
               f"(z {c['z_heldout']:.1f}; on the training log it fits better by {-m:.1f} BIC units)")
        L.append(f"{c['effect']} on {c['axis']}: established on other axes, but {fit}; "
                 + (f"on withheld half A it adds to {c['rival']} at p {p:.2g} (needs < {c['p_pass']:.3g}): "
                    if p is not None else "no withheld half A to tell them apart (no withheld log, or too few "
                    "of its rows inside the training coverage): ")
                 + ("borrowed" if c["kept"] else "not borrowed"))
    for j in res.get("joint", []):
        L.append(f"judged together: {' + '.join(j['effects'])} on {','.join(j['axes'])} - each alone "
                 f"predicts the held-out segments worse (held-out z {', '.join(map(str, j['z']))}; "
                 f"against the wandering bias z {', '.join(map(str, j['z_wander']))})")
    for c in res.get("not_confirmed", []):
        if c.get("reason"):
            L.append(f"not confirmed: {c['effect']} on {c['axis']} ({c['withheld_rms_without']:.4g} -> "
                     f"{c['withheld_rms_with']:.4g} {u} withheld): {c['reason']}; left out")
            continue
        L.append(f"not confirmed: {c['effect']} on {c['axis']} was chosen on the training log but makes "
                 f"the withheld log worse ({c['withheld_rms_without']:.4g} -> {c['withheld_rms_with']:.4g} "
                 f"{u}); left out")
    for w in res.get("warnings", []):
        L.append(f"warning [{w['code']}]: {w['message']}")
    for c in res["not_identifiable"]:
        L.append(f"not identifiable: {' vs '.join(c['effects'])} - needs {c['needs']}")
    for c in res["untried"]:
        L.append(f"not tried: {c['name']} ({c['reason']})")
    if res["where"]:
        L.append("where (cells ranked by z, their mean residual over its standard error; share of the "
                 "training residual energy above the noise floor, all axes):")
        for c in res["where"][:6]:
            L.append(f"   {c['axis']} {c['dimension']:<11} {str(c['from']):>8} .. {str(c['to']):<8}"
                     f" z {c['z_eff']:+6.1f}  share {100 * c['share']:5.1f}%  mean {c['mean']:+.4g} {u}")
    return "\n".join(L)


def band_labels(edges):
    """Labels 'lo..hi' for consecutive edges with as many decimals as it takes for every
    label to differ (a plateau's bands are a few hundredths of a degree wide)."""
    for dec in range(0, 6):
        labels = [f"{lo:.{dec}f}..{hi:.{dec}f}" for lo, hi in zip(edges[:-1], edges[1:])]
        if len(set(labels)) == len(labels):
            return labels
    return labels


def _cell_label(c):
    if c["dimension"] in ("branch", "run"):
        return f"{c['axis']} {c['dimension']} {c['from']}"
    lo, hi = float(c["from"]), float(c["to"])
    span = abs(hi - lo)
    dec = 0 if span >= 10 else (1 if span >= 1 else (2 if span >= 0.1 else 3))
    return f"{c['axis']} {c['dimension']} {lo:.{dec}f}..{hi:.{dec}f}"


def plot(res, extras, path):
    """Write the PNG; returns what was drawn (panel titles, colours), for the tests."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    prob = extras["prob"]
    g = extras["greedy"]
    log = prob.train.log
    m = prob.train.mask
    u = res["unit"]
    base_t = extras["base_train"]
    final_t = np.column_stack([prob.full_residual(prob.train, a, g.state[a]) for a in range(3)])
    have_w = "base_withheld" in extras
    if have_w:
        wl = prob.withheld.log
        wm = prob.withheld.mask
        base_w = extras["base_withheld"]
        final_w = np.column_stack([extras["score_withheld"][a] - _corr_full(extras, a, len(wl))
                                   for a in range(3)])
    fig = plt.figure(figsize=(17, 17), layout="constrained")
    gs = fig.add_gridspec(4, 3)
    drawn = {"titles": [], "axis_colours": dict(AXIS_COLOURS), "withheld_drawn": have_w}
    # Row 1: residual vs temperature, one panel per axis, both logs.
    for a in range(3):
        ax = fig.add_subplot(gs[0, a])
        c = AXIS_COLOURS[AXES[a]]
        ax.plot(log.temp[m], base_t[m, a], ".", ms=1.5, color=c, alpha=0.35,
                label="training: sim residual")
        ax.plot(log.temp[m], final_t[m, a], ".", ms=1.2, color=c, alpha=0.9,
                label="training: final model")
        if have_w:
            ax.plot(wl.temp[wm], final_w[wm, a], "x", ms=2, color=WITHHELD_COLOUR, alpha=0.6,
                    label="withheld: final model")
        nf = res["noise_floor"][AXES[a]]
        ax.axhspan(-nf, nf, color="0.85", zorder=0, label="+-noise floor")
        t = f"{AXES[a]}: residual vs temperature"
        ax.set_title(t)
        drawn["titles"].append(t)
        ax.set_xlabel("temperature reading (degC)")
        ax.set_ylabel(f"residual ({u})")
        if a == 0:
            ax.legend(markerscale=5, fontsize=7, loc="best")
    # Row 2: residual vs time, training then withheld.
    for a in range(3):
        ax = fig.add_subplot(gs[1, a])
        c = AXIS_COLOURS[AXES[a]]
        tt = log.t - log.t[0]
        ax.plot(tt[m], base_t[m, a], ".", ms=1.2, color=c, alpha=0.3, label="sim residual")
        ax.plot(tt[m], final_t[m, a], ".", ms=1.2, color=c, label="final model")
        if have_w:
            same_run = "power_on_s" in wl.meta and "power_on_s" in log.meta
            # Cut from the same run (same clock): at its own time; else after the training log.
            off = float(tt[-1]) * 1.02
            tw = wl.t - log.t[0] if same_run else wl.t - wl.t[0] + off
            ax.plot(tw[wm], base_w[wm, a], ".", ms=1.2, color=WITHHELD_COLOUR, alpha=0.3)
            ax.plot(tw[wm], final_w[wm, a], ".", ms=1.2, color=WITHHELD_COLOUR,
                    label="withheld (same clock)" if same_run else "withheld (after the training log)")
            if not same_run:
                ax.axvline(off, color="k", lw=0.8, ls="--")
        unit_t = "rows" if "row index" in log.meta.get("time", "") else "s"
        t = f"{AXES[a]}: residual vs time"
        ax.set_title(t)
        drawn["titles"].append(t)
        ax.set_xlabel(f"time from the start of the log ({unit_t})")
        ax.set_ylabel(f"residual ({u})")
        if a == 0:
            ax.legend(markerscale=5, fontsize=7, loc="best")
    # Row 3: where-map by excess, waterfall, warnings.
    ax = fig.add_subplot(gs[2, 0])
    cells = res["where"][:12]
    if cells:
        labels = [_cell_label(c) for c in cells][::-1]
        vals = [100 * c["share"] for c in cells][::-1]
        cols = [AXIS_COLOURS[c["axis"]] for c in cells][::-1]
        ax.barh(range(len(cells)), vals, color=cols)
        ax.set_yticks(range(len(cells)), labels, fontsize=7)
        ax.set_xlabel("share of the residual energy above the noise floor (%)")
    else:
        ax.text(0.5, 0.5, "no cell above the noise floor", ha="center", va="center",
                transform=ax.transAxes)
        ax.set_yticks([])
    t = "where: cells above the floor, ranked by their mean's z"
    ax.set_title(t)
    drawn["titles"].append(t)
    drawn["where_labels"] = [_cell_label(c) for c in cells]
    ax = fig.add_subplot(gs[2, 1])
    wf = res["waterfall"]
    labels = ["sim"] + [w["added"] for w in wf[1:]]
    for a in range(3):
        c = AXIS_COLOURS[AXES[a]]
        ax.plot(range(len(wf)), [w["withheld_rms"][AXES[a]] for w in wf], "o-", color=c,
                label=AXES[a])
        ax.axhline(res.get("model_floor", res["noise_floor"])[AXES[a]], ls=":", color=c)
    ax.set_xticks(range(len(wf)), labels, rotation=20, ha="right", fontsize=8)
    ax.set_ylabel(f"scored RMS ({u})")
    ax.set_yscale("log")
    t = "before/after: scored RMS as effects are added (dotted: floors)"
    ax.set_title(t, fontsize=10)
    drawn["titles"].append(t)
    ax.legend(fontsize=8)
    ax = fig.add_subplot(gs[2, 2])
    ax.axis("off")
    lines = ["verdict: " + (", ".join(res["verdict"]) or "none")]
    lines += [f"final/floor {a}: {_fmt_ratio(r)}" for a, r in res["final"]["ratio_to_noise"].items()]
    for w in res.get("warnings", [])[:8]:
        lines.append(f"[{w['code']}] {w.get('axis', '')} {w.get('effect', '')}".rstrip())
    ax.text(0.0, 1.0, "\n".join(lines), va="top", ha="left", family="monospace", fontsize=9,
            transform=ax.transAxes, wrap=True)
    t = "summary"
    ax.set_title(t)
    drawn["titles"].append(t)
    # Row 4: the Allan deviation of each axis's final training residual with its 90 %
    # intervals, the fitted noise model and its terms; the verdict's shrinks with intervals.
    ax = fig.add_subplot(gs[3, 0:2])
    drawn["allan_axes"] = []
    for a in range(3):
        info = g.noise_info.get(a, {}).get("final")
        if not info or not info["allan"]["m"].size:
            continue
        ad, nm = info["allan"], info["model"]
        c = AXIS_COLOURS[AXES[a]]
        yerr = [ad["adev"] - ad["lo"], ad["hi"] - ad["adev"]]
        ax.errorbar(ad["tau"], ad["adev"], yerr=yerr, fmt="o", ms=3, color=c, capsize=2,
                    label=f"{AXES[a]}: Allan deviation (90 % CI)")
        mm = np.geomspace(1, ad["m"][-1], 100)
        from .noise import avar_terms
        terms = avar_terms(mm, nm.s2, nm.q, nm.g2, nm.phi)
        ax.plot(mm * nm.dt, np.sqrt(nm.avar(mm)), "-", color=c, lw=1.5,
                label=f"{AXES[a]}: fitted noise model")
        for name, ls in (("white", ":"), ("random_walk", "--"), ("bias_instability", "-.")):
            v = terms[name]
            if np.any(v > 0):
                ax.plot(mm * nm.dt, np.sqrt(v), ls, color=c, lw=0.8, alpha=0.7,
                        label=f"{AXES[a]}: {name.replace('_', ' ')}")
        drawn["allan_axes"].append(AXES[a])
    ax.set_xscale("log")
    ax.set_yscale("log")
    tu = "rows" if "row index" in log.meta.get("time", "") else "s"
    ax.set_xlabel(f"averaging time ({tu})")
    ax.set_ylabel(f"Allan deviation ({u})")
    ax.legend(fontsize=7, ncol=3, loc="best")
    t = "noise model: Allan deviation of the final training residual and the fitted terms"
    ax.set_title(t, fontsize=10)
    drawn["titles"].append(t)
    ax = fig.add_subplot(gs[3, 2])
    eff = [e for e in res["effects"] if e["significant"]]
    if eff:
        for i, e in enumerate(eff):
            ci = e.get("shrink_interval") or [None, None]
            x = 100 * e["shrink"]
            ax.barh(i, x, color="0.6")
            if ci[0] is not None:
                ax.errorbar(x, i, xerr=[[x - 100 * ci[0]], [100 * ci[1] - x]], fmt="none",
                            color="k", capsize=4)
        ax.set_yticks(range(len(eff)), [f"{e['name']} ({','.join(e['axes'])})" for e in eff],
                      fontsize=8)
        ax.set_xlabel("shrink of the scored RMS (%), 90 % interval")
    else:
        ax.text(0.5, 0.5, "no effect in the verdict", ha="center", va="center",
                transform=ax.transAxes)
        ax.set_yticks([])
    t = "shrink per verdict effect (block bootstrap)"
    ax.set_title(t, fontsize=10)
    drawn["titles"].append(t)
    drawn["shrink_bars"] = [e["name"] for e in eff]
    fig.savefig(path, dpi=80, format="png")
    plt.close(fig)
    return drawn


def _corr_full(extras, a, n):
    """The start-up constant per withheld run, spread over all rows (0 where none)."""
    corr = extras.get("tob_corr", {})
    if a not in corr:
        return np.zeros(n)
    full = np.zeros(n)
    full[extras["withheld_rows"]] = corr[a]
    return full
