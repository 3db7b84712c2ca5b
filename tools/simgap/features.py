"""Derived signals shared by the effect families: a prepared log (scaled temperature and input,
time since power-on) and the filters (first-order low pass, play operator, staircase undo)."""
import numpy as np
from scipy.signal import lfilter

from . import prep


class Context:
    """Scales and grids fixed from the training log and reused unchanged on withheld logs,
    so a withheld log is predicted with exactly the columns the fit saw."""

    def __init__(self, train):
        T = train.temp
        self.tmin, self.tmax = float(np.min(T)), float(np.max(T))
        self.t0 = 25.0
        self.tscale = max(1.0, (self.tmax - self.tmin) / 2)
        self.ref_scale = np.maximum(np.max(np.abs(train.ref), axis=0), 1e-12)
        dt = np.diff(train.t)
        self.dt = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 1.0
        self.span = max(float(train.t[-1] - train.t[0]), 10 * self.dt)
        self.t_first = float(train.t[0])
        if train.run is not None:
            on = prep.run_starts(train)
            self.run_span = max(float(np.max(train.t - train.t[on])), 10 * self.dt)
        else:
            self.run_span = self.span
        self.runs = int(len(np.unique(train.run))) if train.run is not None else 1
        self.supply_mean = self.supply_std = None
        if train.supply is not None:
            self.supply_mean = float(np.mean(train.supply))
            self.supply_std = float(np.std(train.supply)) or 1.0
        self.sensor = train.meta.get("sensor", "gyro").strip().lower()
        self.quantised = quant_step(train) is not None
        # A coarse reading with soaks (unstair: a step held far longer than a ramp crosses one)
        self.soaks = self.quantised and bool(np.any(soak_weight(Prepared(train, self, None)) > 0))
        from .coverage import SPAN_SLOPE, base_identified
        self.base = base_identified(train)      # axis -> ([5 flags], [reasons])
        self.temp_law = (self.tmax - self.tmin) >= SPAN_SLOPE


class Prepared:
    """A log plus the signals computed from it once; `cache` holds filter outputs."""

    def __init__(self, log, ctx, mask):
        self.log = log
        self.mask = mask                      # rows used (spikes excluded)
        # Physical units (degC from t0, the input in ref units): the solver scales every
        # column by its RMS, so the fit is the same and coefficients export as they stand.
        self.d = log.temp - ctx.t0
        self.r = log.ref
        self.run_start = prep.run_starts(log)
        self.ton = log.t - log.t[self.run_start]
        if log.run is None and "power_on_s" in log.meta:
            # A log cut from a longer run (a withheld segment) says when power came on.
            try:
                self.ton = log.t - float(log.meta["power_on_s"])
            except ValueError:
                pass
        # Thermal lag and package hysteresis are physical states that survive a power cycle,
        # so the filters run straight through run changes; they restart only where the clock
        # does (a file whose runs each start at time 0), since the history is unknown there.
        seg = np.r_[True, np.diff(log.t) <= 0]
        self.restart = seg
        self.cache = {}

    def __len__(self):
        return len(self.log)


def _restart_ranges(restart):
    starts = np.flatnonzero(restart)
    return zip(starts, list(starts[1:]) + [len(restart)])


def temperature(p, tau=0.0, destair=False, reading=None):
    """The temperature an effect acts on: the reading (or `reading` given), or its
    staircase-free estimate (destair, on a coarse reading: unstair), low-passed with time
    constant tau (s) when tau > 0 (a lagging internal temperature)."""
    if tau:
        return lowpass(p, tau, destair)
    if destair:
        return unstair(p, 0.0)
    return p.log.temp if reading is None else reading


def lowpass(p, tau, destair=False):
    """First-order low pass of the temperature reading with time constant tau (s), exact for
    any sample spacing. destair=True filters the staircase-free estimate instead (unstair)."""
    key = ("lp", tau, destair)
    if key in p.cache:
        return p.cache[key]
    t = p.log.t
    x = temperature(p, 0.0, destair)
    y = np.empty_like(x)
    for a, b in _restart_ranges(p.restart):
        dt = np.diff(t[a:b])
        if b - a > 1 and np.ptp(dt) <= 1e-6 * max(np.median(dt), 1e-12):
            al = 1.0 - np.exp(-np.median(dt) / tau)   # uniform steps: use the fast IIR
            y[a:b], _ = lfilter([al], [1, al - 1], x[a:b], zi=[(1 - al) * x[a]])
        else:
            al = 1.0 - np.exp(-np.r_[0.0, dt] / tau)
            v = x[a]
            out = y[a:b]
            xs = x[a:b]
            for i in range(b - a):
                v += al[i] * (xs[i] - v)
                out[i] = v
    p.cache[key] = y
    return y


def play(p, width, tau=0.0, destair=False):
    """Play (backlash) operator on the temperature reading, or with tau > 0 on its first-order
    low pass lowpass(p, tau) (hysteresis acting on a lagging internal temperature): the state
    only moves once the input has moved more than width/2 away from it, so it remembers the
    last reversal."""
    key = ("play", width, tau, destair)
    if key in p.cache:
        return p.cache[key]
    x = temperature(p, tau, destair)
    y = np.empty_like(x)
    h = width / 2
    for a, b in _restart_ranges(p.restart):
        v = x[a]
        xs = x[a:b].tolist()
        ys = [0.0] * (b - a)
        for i, xi in enumerate(xs):
            if xi - h > v:
                v = xi - h
            elif xi + h < v:
                v = xi + h
            ys[i] = v
        y[a:b] = ys
    p.cache[key] = y
    return y


def quant_step(log):
    """The temperature reading's step if it looks quantised (most samples repeat the previous
    value), else None."""
    d = np.abs(np.diff(log.temp))
    if d.size == 0 or np.mean(d == 0) < 0.3:
        return None
    nz = d[d > 0]
    return float(np.median(nz)) if nz.size else None


def unstair(p, smooth):
    """Estimate the true temperature behind a staircase reading: the true value crosses the
    midpoint between two steps when the reading changes, so interpolate those crossings in
    time; `smooth` (in units of the typical time between steps) adds a moving average."""
    key = ("unstair", smooth)
    if key in p.cache:
        return p.cache[key]
    t, T = p.log.t, p.log.temp
    est = T.astype(float).copy()
    soak = np.zeros(len(T))
    gaps = []
    for a, b in _restart_ranges(p.restart):
        Ts, ts = T[a:b], t[a:b]
        ch = np.flatnonzero(np.diff(Ts) != 0) + 1
        if ch.size >= 2:
            tc = 0.5 * (ts[ch] + ts[ch - 1])
            vc = 0.5 * (Ts[ch] + Ts[ch - 1])
            est[a:b] = np.interp(ts, tc, vc)
            # Outside the first/last crossing the interpolation would hold a midpoint; the
            # reading itself is the better guess there.
            est[a:b][ts < tc[0]] = Ts[ts < tc[0]]
            est[a:b][ts > tc[-1]] = Ts[ts > tc[-1]]
            g = np.diff(tc)
            g0 = float(np.median(g))
            # A soak between two crossings: the true value sat somewhere inside one step for
            # far longer than a ramp takes to cross it, so a straight line from crossing to
            # crossing is wrong; hold the reading, easing from each crossing over one
            # typical ramp gap. Where a ramp changes the reading every sample, the reading
            # resolves the ramps and a held value is a constant temperature, not an unknown
            # place inside a step (an exact synthetic soak, or a fine reading on a fast ramp):
            # no soak weight then.
            stairs = g0 > 1.5 * float(np.median(np.diff(ts)))
            for k in np.flatnonzero(g > 4 * g0):
                sel = (ts > tc[k]) & (ts < tc[k + 1])
                tt = ts[sel]
                rd = Ts[sel]
                w0 = np.clip(1 - (tt - tc[k]) / g0, 0, 1)
                w1 = np.clip(1 - (tc[k + 1] - tt) / g0, 0, 1)
                est[a:b][sel] = rd + (vc[k] - rd) * w0 + (vc[k + 1] - rd) * w1
                if stairs:
                    soak[a:b][sel] = np.clip(1 - w0 - w1, 0, 1)
            gaps.append(g0)
    if smooth > 0 and gaps:
        dt = np.median(np.diff(t)) if len(t) > 1 else 1.0
        w = int(round(smooth * np.median(gaps) / max(dt, 1e-12)))
        if w >= 3:
            for a, b in _restart_ranges(p.restart):
                if b - a > w:
                    k = np.ones(w) / w
                    pad = np.r_[np.full(w // 2, est[a]), est[a:b], np.full(w - 1 - w // 2, est[b - 1])]
                    est[a:b] = np.convolve(pad, k, mode="valid")
    p.cache[key] = est
    p.cache[("soak",)] = soak
    return est


def soak_weight(p):
    """1 where unstair held the reading through a soak (the true value's place inside the
    step unknown), easing to 0 over one ramp gap at each end; 0 on ramps."""
    if ("soak",) not in p.cache:
        unstair(p, 0.0)
    return p.cache[("soak",)]
