"""Where the sim departs from the log: the training residual split into cells along one
dimension at a time, each cell's share of the excess energy over the noise floor."""
import numpy as np

from . import prep
from .logio import AXES

NBANDS = 8


def _cells(p, axis, ctx):
    """(dimension, from, to, bool mask) for every cell of every dimension that applies."""
    log = p.log
    T = log.temp
    edges = np.linspace(ctx.tmin, ctx.tmax, NBANDS + 1)
    for i in range(NBANDS):
        lo, hi = edges[i], edges[i + 1]
        m = (T >= lo) & ((T < hi) if i < NBANDS - 1 else (T <= hi))
        yield "temperature", round(float(lo), 4), round(float(hi), 4), m
    br = prep.branch(prep.temp_rate(log))
    for b in ("heating", "soak", "cooling"):
        yield "branch", b, b, br == b
    ref = log.ref[:, axis]
    levels = np.unique(ref)
    if len(levels) >= 2:
        qs = np.unique(np.quantile(ref, np.linspace(0, 1, min(len(levels), 5) + 1)))
        for i in range(len(qs) - 1):
            lo, hi = qs[i], qs[i + 1]
            m = (ref >= lo) & ((ref < hi) if i < len(qs) - 2 else (ref <= hi))
            yield "input", float(lo), float(hi), m
    ton = p.ton
    tedges = np.linspace(0, max(ton.max(), 1e-9), NBANDS + 1)
    for i in range(NBANDS):
        lo, hi = tedges[i], tedges[i + 1]
        m = (ton >= lo) & ((ton < hi) if i < NBANDS - 1 else (ton <= hi))
        yield "time", round(float(lo), 3), round(float(hi), 3), m
    if log.run is not None and len(np.unique(log.run)) > 1:
        for r in np.unique(log.run):
            yield "run", int(r), int(r), log.run == r


def localise(p, resid, sigma, ctx, top=40):
    """resid: (N, 3) sim residual on prepared log p; sigma: noise floor per axis. A cell's
    share is its residual energy above the noise floor (sum r^2 - n sigma^2) over the excess
    of all three axes together, so an axis the sim fits to the floor contributes nothing and
    the top cell lies where the sim misfits most, whatever the data mass elsewhere."""
    clipped, totals = {}, {}
    m0 = p.mask
    for a in range(3):
        r = resid[:, a]
        # Clip at 6 sigma of the residual's own robust spread so one bad stretch cannot own
        # the whole map.
        med = np.median(r[m0])
        lim = 6 * max(1.4826 * np.median(np.abs(r[m0] - med)), sigma[a], 1e-300)
        clipped[a] = np.clip(r, med - lim, med + lim)
        totals[a] = float(np.sum(clipped[a][m0] ** 2) - m0.sum() * sigma[a] ** 2)
    # Only an axis whose excess is beyond what noise gives takes part.
    n0 = int(m0.sum())
    overall = sum(v for a, v in totals.items() if v > 9 * sigma[a] ** 2 * np.sqrt(2 * n0))
    out = []
    if overall <= 0:
        return out
    for a in range(3):
        rc = clipped[a]
        if totals[a] <= 9 * sigma[a] ** 2 * np.sqrt(2 * n0):
            continue
        found = False
        for dim, lo, hi, m in _cells(p, a, ctx):
            m = m & m0
            n = int(m.sum())
            if n < 5:
                continue
            e = float(np.sum(rc[m] ** 2) - n * sigma[a] ** 2)
            # A cell counts only if its excess is beyond what noise alone gives (the sum of
            # n squared Gaussian samples has spread sigma^2 * sqrt(2n)); 3x that, and a margin
            # for samples not being independent.
            if e < 3 * sigma[a] ** 2 * np.sqrt(2 * n) * 3:
                continue
            share = min(1.0, e / overall)
            mean = float(np.mean(rc[m]))
            out.append({"axis": AXES[a], "dimension": dim, "from": lo, "to": hi,
                        "share": round(share, 4), "n": n, "mean": mean,
                        "rms": float(np.sqrt(np.mean(rc[m] ** 2))),
                        "excess": e,
                        "z": float(mean / (sigma[a] / np.sqrt(n))) if sigma[a] > 0 else 0.0})
            found = True
        if not found:
            # The axis's excess is beyond noise but spread so evenly (a coarse temperature
            # reading's sawtooth, a small misfit everywhere) that no cell holds enough of it
            # to pass on its own: a cell's excess grows with n, its noise threshold with
            # sqrt(n), so an even spread is significant only over the whole log. Say so with
            # one cell over the whole temperature range rather than an empty map.
            m = m0
            n = int(m.sum())
            mean = float(np.mean(rc[m]))
            out.append({"axis": AXES[a], "dimension": "temperature",
                        "from": round(float(ctx.tmin), 4), "to": round(float(ctx.tmax), 4),
                        "share": round(min(1.0, totals[a] / overall), 4), "n": n, "mean": mean,
                        "rms": float(np.sqrt(np.mean(rc[m] ** 2))), "excess": totals[a],
                        "z": float(mean / (sigma[a] / np.sqrt(n))) if sigma[a] > 0 else 0.0})
    out.sort(key=lambda c: -c["share"])
    return out[:top]
