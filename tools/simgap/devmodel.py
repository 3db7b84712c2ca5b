"""The augmented device model (lib/tempcomp/augment.py) in float64: the reference its integer path
is measured against, and the forward model the export fits.

Inputs are what a board sees, as the integers it reads (see `board_inputs`): the temperature
reading t, the raw codes, time steps in ms, the supply and accelerometer readings. The model is
the dict `--export` writes under "device" (docs/augment.md)."""
import numpy as np

KINDS = ("dT", "lag", "play", "drift_exp", "drift_hyp", "uptime", "supply", "acc", "prod")


def board_inputs(m, log, uptime0_s=0.0):
    """The integers a board would read for each row of a diagnosis log, per the model's LSBs:
    {t, raw (N,3), dt_ms, supply, acc (N,3), uptime0_ms}."""
    t = np.round((log.temp - m.get("t_off", 0.0)) / m["t_lsb"]).astype(np.int64)
    raw = np.round(log.out / m.get("raw_lsb", 1.0)).astype(np.int64)
    lo, hi = m.get("raw_range", (-32768, 32767))
    clipped = int(np.sum((raw < lo) | (raw > hi)))
    raw = np.clip(raw, lo, hi)  # a board's ADC saturates there too; counted
    ms = np.round((log.t - log.t[0]) * 1000.0).astype(np.int64)
    dt = np.r_[0, np.diff(ms)]
    # a new run, or the clock starting again, is a power-on for the board: it starts afresh
    new = np.r_[False, dt[1:] <= 0]
    if log.run is not None:
        new |= np.r_[False, np.diff(log.run) != 0]
    dt = np.where(new, 0, np.maximum(dt, 0))
    sup = np.zeros(len(t), np.int64)
    if log.supply is not None:
        sup = np.round(log.supply / m.get("supply_lsb", 0.001)).astype(np.int64)
    acc = np.zeros((len(t), 3), np.int64)
    if log.acc is not None:
        acc = np.round(log.acc / m.get("acc_lsb", 0.001)).astype(np.int64)
    return {"t": t, "raw": raw, "dt_ms": dt, "supply": sup, "acc": acc,
            "uptime0_ms": int(round(uptime0_s * 1000.0)), "starts": np.flatnonzero(new),
            "raw_clipped": clipped}


def temperature(m, t):
    return t * m["t_lsb"] + m.get("t_off", 0.0)


def t0_aligned(m):
    """t0 moved to the nearest reading, as the device counts dT from a reading."""
    t_lsb, t_off = m["t_lsb"], m.get("t_off", 0.0)
    return round((m.get("t0", 25.0) - t_off) / t_lsb) * t_lsb + t_off


def _lowpass(x, dt_ms, tau, new):
    al = 1.0 - np.exp(-dt_ms / (tau * 1000.0))
    y = np.empty(len(x))
    v = x[0]
    for i in range(len(x)):
        if new[i]:
            v = x[i]
        elif i:
            v += al[i] * (x[i] - v)
        y[i] = v
    return y


def _play(x, h, new):
    y = np.empty(len(x))
    v = x[0]
    for i, xi in enumerate(x.tolist()):
        if new[i]:
            v = xi
        if xi - h > v:
            v = xi - h
        elif xi + h < v:
            v = xi + h
        y[i] = v
    return y


def features(m, inp):
    """(N, nfeat) feature values in their physical units (degC, s, V, g, 1)."""
    T = temperature(m, inp["t"].astype(float))
    dt = inp["dt_ms"].astype(float)
    new = np.zeros(len(T), bool)
    new[np.asarray(inp.get("starts", []), int)] = True
    seg = np.cumsum(new)  # power-on count: uptime restarts at 0 at each
    cum = np.cumsum(dt)
    first = np.r_[0, np.flatnonzero(new)]
    up = cum - cum[first][seg] + np.where(seg == 0, inp["uptime0_ms"], 0)
    feats = m.get("features", [])
    F = np.zeros((len(T), len(feats)))
    lps = {}

    def lp(tau):
        if tau not in lps:
            lps[tau] = _lowpass(T, dt, tau, new)
        return lps[tau]

    for j, f in enumerate(feats):
        k = f["kind"]
        if k == "dT":
            v = T - t0_aligned(m)
        elif k == "lag":
            v = T - lp(float(f["tau"]))
        elif k == "play":
            lag = float(f.get("lag", 0.0))
            x = lp(lag) if lag > 0 else T
            v = _play(x, float(f["width"]) / 2, new) - x
        elif k == "drift_exp":
            v = np.exp(-up / (float(f["tau"]) * 1000.0))
        elif k == "drift_hyp":
            v = 1.0 / (1.0 + up / (float(f["tau"]) * 1000.0))
        elif k == "uptime":
            v = up / 1000.0
        elif k == "supply":
            v = inp["supply"] * m.get("supply_lsb", 0.001) - m.get("supply0", 0.0)
        elif k == "acc":
            v = inp["acc"][:, int(f["axis"])] * m.get("acc_lsb", 0.001)
        elif k == "prod":
            v = F[:, int(f["a"])] * F[:, int(f["b"])]
        else:
            raise ValueError("unknown feature kind %r" % k)
        F[:, j] = v
    return F


def _terms(m, F, dT):
    n = len(dT)
    dO = np.zeros((n, 3))
    e = np.zeros((n, 3))
    K = np.zeros((n, 3, 3))
    ot = m.get("offset_terms") or [[], [], []]
    gt = m.get("gain_terms") or [[], [], []]
    cr = m.get("cross") or [[], [], []]
    for i in range(3):
        for fi, c in ot[i]:
            dO[:, i] += c * F[:, int(fi)]
        for fi, g in gt[i]:
            e[:, i] += g * F[:, int(fi)]
        for k, k0, k1 in cr[i]:
            K[:, i, int(k)] = k0 + k1 * dT
    return dO, e, K


def _base(m, T):
    d = T - m.get("t0", 25.0)
    o = np.column_stack([np.polyval(list(reversed(m["offset"][i])), d) for i in range(3)])
    s = np.column_stack([np.polyval(list(reversed(m["sensitivity"][i])), d) for i in range(3)])
    return o, s


def predict(m, inp, ref, F=None):
    """Forward model: raw output (out units) for true input ref (N,3)."""
    F = features(m, inp) if F is None else F
    T = temperature(m, inp["t"].astype(float))
    o, s = _base(m, T)
    dO, e, K = _terms(m, F, T - t0_aligned(m))
    cross = np.einsum("nik,nk->ni", K, ref)
    s0 = np.array([m["sensitivity"][i][0] for i in range(3)])
    return o + dO + s * ref + s0 * (e * ref + cross)


def compensate(m, inp, F=None):
    """Exact inverse in float64: the input (ref units) that explains the raw codes."""
    F = features(m, inp) if F is None else F
    T = temperature(m, inp["t"].astype(float))
    o, s = _base(m, T)
    dO, e, K = _terms(m, F, T - t0_aligned(m))
    out = inp["raw"] * m.get("raw_lsb", 1.0)
    y0 = (out - o - dO) / s
    s0 = np.array([m["sensitivity"][i][0] for i in range(3)])
    A = K.copy()
    A[:, [0, 1, 2], [0, 1, 2]] += e
    A *= (s0 / s)[:, :, None]
    A[:, [0, 1, 2], [0, 1, 2]] += 1
    return np.linalg.solve(A, y0[:, :, None])[:, :, 0]
