"""Where the sim departs from the log: the training residual split into cells along one
dimension at a time; the cells whose excess energy over the noise floor is beyond noise, each
with its share of that excess, ranked by how surely the cell's mean departs from zero."""
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


def _cell(axis, dim, lo, hi, share, rc, m, excess, sigma, keep):
    """One map entry for the rows m of the clipped residual rc. z is the cell's mean over its
    standard error were the cell white noise at the floor sigma; z_eff the same over sqrt(n keep)
    rows, keep = n_eff / n under the noise's autocorrelation. A zero floor (a noiseless log)
    gives z 0 and still ranks cells by mean x sqrt(n_eff) through the tiny stand-in for sigma."""
    n = int(m.sum())
    mean = float(np.mean(rc[m]))
    return {"axis": AXES[axis], "dimension": dim, "from": lo, "to": hi,
            "share": round(share, 4), "n": n, "mean": mean,
            "rms": float(np.sqrt(np.mean(rc[m] ** 2))), "excess": excess,
            "z": float(mean / (sigma / np.sqrt(n))) if sigma > 0 else 0.0,
            "z_eff": float(mean / (max(sigma, 1e-300) / np.sqrt(n * keep)))}


def localise(p, resid, sigma, ctx, top=40):
    """resid: (N, 3) sim residual on prepared log p; sigma: noise floor per axis. A cell's
    share is its residual energy above the noise floor (sum r^2 - n sigma^2) over the excess
    of all three axes together, so an axis the sim fits to the floor contributes nothing.

    Cells are ranked by |z_eff|, the cell's mean residual over its standard error under the
    noise alone (the floor sigma over sqrt(n_eff), n_eff = n (1 - rho) / (1 + rho), rho the
    noise's lag-1 autocorrelation on that axis). Ranking by share favoured big cells: an input
    cell holding half the rows carries half of any misfit's energy though its mean is near zero,
    and outranked the heating/cooling branch or temperature band the misfit lives in. A cell
    mixing two opposite offsets (one straddling both branches) has a mean near zero and ranks
    below a cell holding one of them. (The cell's own spread in the error instead of the floor
    was tried: it let a neighbouring band with a small, even offset outrank a band only partly
    covered by the misfit, 4/46 seeds against main's 2/46.)"""
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
        if totals[a] <= 9 * sigma[a] ** 2 * np.sqrt(2 * n0):
            continue
        rc = clipped[a]
        # The noise's lag-1 autocorrelation rho, from the first differences so that the slow
        # misfit being located does not count as noise: for AR(1) noise the differences' lag-1
        # autocorrelation is -(1 - rho) / 2. The AR(1) effective sample size of a cell's mean is
        # exact for a contiguous stretch and on the safe side for scattered stretches.
        d = np.diff(rc[m0])
        d = d - np.mean(d)
        a1 = float(np.dot(d[1:], d[:-1]) / max(float(np.dot(d, d)), 1e-300))
        rho = min(max(1 + 2 * a1, 0.0), 0.99)
        keep = (1 - rho) / (1 + rho)
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
            out.append(_cell(a, dim, lo, hi, min(1.0, e / overall), rc, m, e, sigma[a], keep))
            found = True
        if not found:
            # The axis's excess is beyond noise but spread so evenly (a coarse temperature
            # reading's sawtooth, a small misfit everywhere) that no cell holds enough of it
            # to pass on its own: a cell's excess grows with n, its noise threshold with
            # sqrt(n), so an even spread is significant only over the whole log. Say so with
            # one cell over the whole temperature range rather than an empty map.
            out.append(_cell(a, "temperature", round(float(ctx.tmin), 4), round(float(ctx.tmax), 4),
                             min(1.0, totals[a] / overall), rc, m0, totals[a], sigma[a], keep))
    out.sort(key=lambda c: -abs(c["z_eff"]))
    return out[:top]
