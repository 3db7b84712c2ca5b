"""What each log covers and what the training log identifies, checked before anything is
scored: a withheld log is evidence only where the training log has been (temperature, input),
and a base-model parameter the training data cannot pin down is fixed, never left to a
rank-deficient solve whose arbitrary split would later read as an "effect"."""
import numpy as np

from . import prep
from .logio import AXES
from .noise import autocorr_time

SPAN_SLOPE = 3.0     # degC of training temperature span below which no temperature law is
                     # identified (a plateau): offset slope, curvature and sensitivity slope fixed
SPAN_CURVE = 5.0     # degC below which the offset's curvature is fixed at 0 (slope only)
Z_LAW = 4.0          # ... except the sensitivity slope where the log itself shows it at |z| > 4
                     # (two-sided p 6e-5 per axis; HAC standard error, so a wandering bias does
                     # not inflate it): see base_identified
COVER_TOL = 0.5      # degC (or 2 % of the span) a withheld temperature may lie outside training


def _levels(v, rel=1e-3):
    rng = np.ptp(v)
    if rng == 0:
        return 1
    return len(np.unique(np.round(v / (rel * rng))))


def describe(log):
    """The coverage of one log, for the JSON and for the comparison."""
    br = prep.branch(prep.temp_rate(log))
    d = {"temp_c": [float(np.min(log.temp)), float(np.max(log.temp))],
         "heating_rows": int(np.sum(br == "heating")), "cooling_rows": int(np.sum(br == "cooling")),
         "soak_rows": int(np.sum(br == "soak")),
         "input_levels": {AXES[a]: _levels(log.ref[:, a]) for a in range(3)},
         "input_range": {AXES[a]: [float(np.min(log.ref[:, a])), float(np.max(log.ref[:, a]))]
                         for a in range(3)},
         "runs": int(len(np.unique(log.run))) if log.run is not None else 1,
         "duration": float(log.t[-1] - log.t[0]) if log.run is None else
         float(sum(np.ptp(log.t[log.run == r]) for r in np.unique(log.run)))}
    g = log.acc if log.acc is not None else (log.ref if log.meta.get("sensor") == "accel" else None)
    d["orientations"] = int(len(np.unique(np.round(g, 1), axis=0))) if g is not None else None
    return d


def covered(train, withheld):
    """Rows of the withheld log inside the training log's temperature range and input range."""
    lo, hi = float(np.min(train.temp)), float(np.max(train.temp))
    tol = max(COVER_TOL, 0.02 * (hi - lo))
    m = (withheld.temp >= lo - tol) & (withheld.temp <= hi + tol)
    for a in range(3):
        rlo, rhi = np.min(train.ref[:, a]), np.max(train.ref[:, a])
        rt = 0.05 * max(rhi - rlo, 1e-3 * max(abs(rlo), abs(rhi), 1e-12))
        m &= (withheld.ref[:, a] >= rlo - rt) & (withheld.ref[:, a] <= rhi + rt)
    return m


def sensitivity_slope_z(train, axis):
    """z of the sensitivity's temperature slope s1 in the training log: the output regressed
    on (1, dT, ref, dT * ref) by least squares, the standard error of the last coefficient
    from the heteroskedasticity-and-autocorrelation-consistent variance of its score
    (sum of (x_perp r)^2 times that product's integrated autocorrelation time), so a
    wandering bias or a left-over slow effect does not pass for precision. On a plateau the
    few hundredths of a degree the temperature wanders, times a large input (a rate table's
    hundreds of dps), can pin s1 down although no offset law is identifiable: the
    input steps modulate the column, which no slow offset mimics."""
    d = train.temp - np.mean(train.temp)
    r = train.ref[:, axis]
    X = np.column_stack([np.ones_like(d), d, r, d * r])
    y = train.out[:, axis]
    Q = np.linalg.qr(X[:, :3])[0]
    x = X[:, 3] - Q @ (Q.T @ X[:, 3])
    xx = float(x @ x)
    if not np.all(np.isfinite(y)) or xx <= 1e-12 * max(float(X[:, 3] @ X[:, 3]), 1e-300):
        return 0.0
    u = y - Q @ (Q.T @ y)
    b = float(x @ u) / xx
    res = u - b * x
    p = x * res
    var = float(p @ p) * autocorr_time(p) / xx ** 2
    return abs(b) / np.sqrt(var) if var > 0 else 0.0


def base_identified(train):
    """Per axis, which of the sim's five parameters (o0, o1, o2, s0, s1) the training log
    identifies, with the reasons for those it does not. Below SPAN_SLOPE no temperature law
    is identified, except a sensitivity slope the log shows at |z| > Z_LAW
    (sensitivity_slope_z): fixed at 0, it would leave its dT * ref structure for a
    catalogue effect to take (nonlinearity or cross-axis on the plateau's input steps)."""
    span = float(np.ptp(train.temp))
    out = {}
    for a in range(3):
        keep = [True] * 5
        why = []
        levels = _levels(train.ref[:, a])
        if span < SPAN_SLOPE:
            keep[1] = keep[2] = keep[4] = False
            law = "no temperature law"
            if levels >= 2:
                z = sensitivity_slope_z(train, a)
                if z > Z_LAW:
                    keep[4] = True
                    law = (f"no offset temperature law (the sensitivity's slope is fitted: the "
                           f"input steps show it at z = {z:.3g})")
            why.append(f"temperature spans {span:.2g} degC (< {SPAN_SLOPE:g}): {law}")
        elif span < SPAN_CURVE:
            keep[2] = False
            why.append(f"temperature spans {span:.2g} degC (< {SPAN_CURVE:g}): curvature fixed at 0")
        if levels < 2:
            # One input level: the sensitivity cannot be told from the offset; the offset
            # absorbs s0 * ref (exact for withheld rows at the same input, which coverage
            # requires).
            keep[3] = keep[4] = False
            why.append("one input level: sensitivity not identified (folded into the offset)")
        out[a] = (keep, why)
    return out


def differences(tr, wh):
    """What the withheld log has that the training log lacks (descriptions from describe)."""
    out = []
    for b in ("heating", "cooling"):
        if wh[f"{b}_rows"] > 0 and tr[f"{b}_rows"] == 0:
            out.append(f"the withheld log has {b} ramps, the training log none")
    if wh["soak_rows"] > 0 and tr["soak_rows"] == 0:
        out.append("the withheld log has soaks, the training log none")
    for a in AXES:
        lo, hi = tr["input_range"][a]
        wlo, whi = wh["input_range"][a]
        if wlo < lo or whi > hi:
            out.append(f"{a} input {wlo:g}..{whi:g} in the withheld log, {lo:g}..{hi:g} in training")
    if (wh["orientations"] or 0) > (tr["orientations"] or 0):
        out.append(f"{wh['orientations']} orientations in the withheld log, {tr['orientations']} in training")
    return out
