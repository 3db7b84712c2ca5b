"""Human-readable summary and the PNG (residual vs temperature by branch, localisation map,
before/after waterfall)."""
import numpy as np

from .logio import AXES


def text(res):
    u = res["unit"]
    L = []
    L.append(f"sim: {res['sim']}; scored on {res['withheld_source']}")
    rows = res["rows"]
    L.append(f"rows: train {rows['train']} ({rows['train_outliers']} outliers dropped)"
             + (f", withheld {rows['withheld']} ({rows['withheld_outliers']} outliers dropped)"
                if rows["withheld"] else ""))
    nf = res["noise_floor"]
    L.append("noise floor: " + ", ".join(f"{a} {nf[a]:.4g}" for a in nf) + f" {u}")
    so = res["sim_only"]["withheld_rms"]
    L.append("withheld RMS, sim only: " + ", ".join(f"{a} {so[a]:.4g}" for a in so) + f" {u}")
    if res["verdict"]:
        L.append("verdict (strongest first): " + ", ".join(res["verdict"]))
    else:
        L.append("verdict: none - the sim explains the data down to the noise floor "
                 "as far as this data can tell")
    for e in sorted(res["effects"], key=lambda e: (not e["significant"], e["rank"] or 0, -e["shrink"])):
        mark = "*" if e["significant"] else " "
        ax = ",".join(e["axes"])
        shown = e["axes"] if e["significant"] else e["withheld_rms_before"]
        pa = "; ".join(f"{a} {e['withheld_rms_before'][a]:.4g}->{e['withheld_rms_after'][a]:.4g}"
                       for a in shown)
        L.append(f" {mark} {e['name']:<24} shrink {100 * e['shrink']:6.1f}% on {ax:<6} ({pa})")
    fin = res["final"]
    L.append("final withheld RMS: " + ", ".join(
        f"{a} {fin['withheld_rms'][a]:.4g} ({fin['ratio_to_noise'][a]:.2f}x floor)"
        for a in fin["withheld_rms"]) + f" {u}")
    for c in res["not_identifiable"]:
        L.append(f"not identifiable: {' vs '.join(c['effects'])} - needs {c['needs']}")
    for c in res["untried"]:
        L.append(f"not tried: {c['name']} ({c['reason']})")
    if res["where"]:
        L.append("where (largest share of the training residual above the noise floor):")
        for c in res["where"][:6]:
            L.append(f"   {c['axis']} {c['dimension']:<11} {str(c['from']):>8} .. {str(c['to']):<8}"
                     f" share {100 * c['share']:5.1f}%  mean {c['mean']:+.4g} {u}")
    return "\n".join(L)


def plot(res, extras, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from . import prep

    prob = extras["prob"]
    log = prob.train.log
    r = extras["base_train"]
    m = prob.train.mask
    br = prep.branch(prep.temp_rate(log))
    fig, axs = plt.subplots(2, 3, figsize=(15, 8))
    colours = {"heating": "tab:red", "soak": "tab:grey", "cooling": "tab:blue"}
    for a in range(3):
        ax = axs[0, a]
        for b, c in colours.items():
            s = m & (br == b)
            ax.plot(log.temp[s], r[s, a], ".", ms=1.5, color=c, label=b)
        ax.set_title(f"{AXES[a]}: sim residual vs temperature (training)")
        ax.set_xlabel("temperature reading (degC)")
        ax.set_ylabel(f"residual ({res['unit']})")
        if a == 0:
            ax.legend(markerscale=6, loc="best")
    # Localisation map: share per axis x temperature band.
    ax = axs[1, 0]
    cells = [c for c in res["where"] if c["dimension"] == "temperature"]
    bands = sorted({(c["from"], c["to"]) for c in cells})
    grid = np.zeros((3, max(1, len(bands))))
    for c in cells:
        grid[AXES.index(c["axis"]), bands.index((c["from"], c["to"]))] = c["share"]
    im = ax.imshow(grid, aspect="auto", cmap="magma")
    ax.set_yticks(range(3), AXES)
    ax.set_xticks(range(len(bands)), [f"{lo:.0f}" for lo, _ in bands], fontsize=7)
    ax.set_xlabel("temperature band from (degC)")
    ax.set_title("share of excess residual by axis x band")
    fig.colorbar(im, ax=ax)
    ax = axs[1, 1]
    dims = ["branch", "time", "input", "run"]
    for i, d in enumerate(dims):
        cs = [c for c in res["where"] if c["dimension"] == d]
        for c in cs:
            ax.bar(i + 0.25 * (AXES.index(c["axis"]) - 1), c["share"], width=0.22,
                   color=["tab:orange", "tab:green", "tab:purple"][AXES.index(c["axis"])])
    ax.set_xticks(range(len(dims)), dims)
    ax.set_title("share by other dimensions (bars: x, y, z cells)")
    ax = axs[1, 2]
    wf = res["waterfall"]
    labels = ["sim"] + [w["added"] for w in wf[1:]]
    for a in range(3):
        ax.plot(range(len(wf)), [w["withheld_rms"][AXES[a]] for w in wf], "o-", label=AXES[a])
        ax.axhline(res["noise_floor"][AXES[a]], ls=":", color=f"C{a}")
    ax.set_xticks(range(len(wf)), labels, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel(f"withheld RMS ({res['unit']})")
    ax.set_title("withheld residual as effects are added (dotted: noise floor)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
