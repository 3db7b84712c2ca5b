"""Per-log quantities every stage needs: run segments, temperature rate and branch,
spike outliers, the noise floor, and the held-out segments of the training log."""
import numpy as np
from scipy.ndimage import median_filter

SOAK_RATE = 0.05   # degC/min below which the part counts as soaking
SPIKE_K = 12.0     # a sample this many robust noise sigmas off its local median is an outlier
                   # (12, not 8: Student-t tails are noise the RMS must count, not spikes)


def segments(log):
    """Start indices of contiguous stretches: a new run, or a time gap much longer than the
    usual sample step (the PAN log is 25 bursts; filters must not run across the gaps)."""
    return stretches(log.t, log.run)


def stretches(t, run=None):
    """segments() of any rows: times t (and run ids, or None), e.g. a subset of a log's rows,
    whose own gaps (rows left out) count as the log's do."""
    n = len(t)
    brk = np.zeros(n, bool)
    brk[0] = True
    if run is not None:
        brk[1:] |= np.diff(run) != 0
    dt = np.diff(t)
    pos = dt[dt > 0]
    if pos.size:
        brk[1:] |= dt > 20 * np.median(pos)
    return np.flatnonzero(brk)


def run_starts(log):
    """Index of the power-on sample each row belongs to (0 for a single run)."""
    n = len(log)
    if log.run is None:
        return np.zeros(n, int)
    brk = np.r_[True, np.diff(log.run) != 0]
    return np.maximum.accumulate(np.where(brk, np.arange(n), 0))


def temp_rate(log, window_s=None):
    """dT/dt in degC/min, from a least-squares slope over a centred window so a quantised or
    noisy reading does not flip the branch sample by sample."""
    t, T = log.t, log.temp
    n = len(t)
    if window_s is None:
        span = t[-1] - t[0]
        dt = np.diff(t)
        # Wide enough to reach across the gaps of a burst log (PAN: 5 s bursts every 305 s),
        # where the slope inside one burst is all noise.
        window_s = max(span / 200.0, 5 * np.median(dt), 2.5 * np.max(dt)) if n > 1 else 1.0
    rate = np.zeros(n)
    brk = np.r_[True, np.diff(t) <= 0]
    if log.run is not None:
        brk[1:] |= np.diff(log.run) != 0
    starts = list(np.flatnonzero(brk)) + [n]
    for a, b in zip(starts[:-1], starts[1:]):
        ts, Ts = t[a:b], T[a:b]
        if b - a < 3:
            continue
        # Running sums give every window's slope in O(n).
        lo = np.searchsorted(ts, ts - window_s / 2)
        hi = np.searchsorted(ts, ts + window_s / 2, side="right")
        def c(v):
            return np.r_[0.0, np.cumsum(v)]

        t0 = ts[0]
        S1, St, ST = c(np.ones_like(ts)), c(ts - t0), c(Ts)
        Stt, StT = c((ts - t0) ** 2), c((ts - t0) * Ts)
        m = S1[hi] - S1[lo]
        st, sT = St[hi] - St[lo], ST[hi] - ST[lo]
        den = m * (Stt[hi] - Stt[lo]) - st ** 2
        num = m * (StT[hi] - StT[lo]) - st * sT
        with np.errstate(invalid="ignore", divide="ignore"):
            r = np.where(den > 1e-12 * np.maximum(m, 1) ** 2, num / den, 0.0)
        rate[a:b] = r * 60.0
    return rate


def branch(rate):
    """'heating' / 'soak' / 'cooling' per sample."""
    thr = max(SOAK_RATE, 0.1 * np.percentile(np.abs(rate), 90))
    return np.where(rate > thr, "heating", np.where(rate < -thr, "cooling", "soak"))


def _robust_sigma(v):
    v = v[np.isfinite(v)]
    if v.size < 3:
        return 0.0
    return 1.4826 * np.median(np.abs(v - np.median(v)))


def output_step(log):
    """Per axis, the output's quantisation step q (0 when the output is not on a grid): the
    smallest spacing between distinct values, accepted when nearly every value is a whole
    multiple of it (a log of 4 mg steps, or whole LSB)."""
    q = np.zeros(3)
    for a in range(3):
        v = log.out[:, a]
        u = np.unique(v)
        if u.size < 3:
            continue
        gaps = np.diff(u)
        step = float(np.percentile(gaps, 5))
        if step <= 0 or step < 1e-9 * max(1.0, float(np.max(np.abs(u)))):
            continue
        k = (v - u[0]) / step
        if np.mean(np.abs(k - np.round(k)) < 0.02) > 0.98:
            q[a] = step
    return q


def steady_pairs(log, mask):
    """Consecutive row pairs inside one contiguous stretch, both rows kept by the outlier rule,
    with no change of any input (ref, acc, supply) between them: differences over these
    pairs hold the noise and not the jumps a misfit makes at an input step."""
    n = len(log)
    ok = np.ones(n - 1, bool)
    seg = segments(log)
    ok[seg[1:] - 1] = False
    if mask is not None:
        ok &= mask[1:] & mask[:-1]
    for v in (log.ref, log.acc):
        if v is not None:
            ok &= ~np.any(np.diff(v, axis=0) != 0, axis=1)
    if log.supply is not None:
        dv = np.abs(np.diff(log.supply))
        ok &= dv <= 5 * max(float(np.median(dv)), 1e-12)
    if ok.sum() < 0.2 * (n - 1):
        # Inputs change at almost every sample (a sweep): fall back to all pairs.
        ok = np.ones(n - 1, bool)
        ok[seg[1:] - 1] = False
        if mask is not None:
            ok &= mask[1:] & mask[:-1]
    return ok


def difference_sigma(resid, pairs):
    """Per-axis sqrt(mean(d^2) / 2), d the residual's first differences over the steady pairs
    (steady_pairs): the white-noise sigma the differences read, before any quantisation floor.
    0 for an axis without a pair."""
    out = np.zeros(resid.shape[1])
    for a in range(resid.shape[1]):
        d = np.diff(resid[:, a])[pairs]
        out[a] = float(np.sqrt(np.mean(d * d) / 2)) if d.size else 0.0
    return out


def noise_floor(resid, log, mask=None, q=None):
    """Per-axis white-noise sigma: RMS of first differences of a residual / sqrt 2, over the
    rows the outlier rule keeps (the same rows the residual RMS uses, so a perfect model reads
    1.0x) and only between samples with the same inputs.

    Differencing removes whatever slow structure the model misses, so this is what a perfect
    model could reach if the noise is white. An RMS, not a median, so heavy tails count as the
    residual's RMS counts them; the outlier rule (spikes) has already taken the spikes out.
    Never below q/sqrt(12) for an output quantised in steps of q."""
    q = output_step(log) if q is None else q
    s = difference_sigma(resid, steady_pairs(log, mask))
    return np.array([max(s[a], q[a] / np.sqrt(12)) for a in range(3)])


def spikes(log, q=None):
    """Rows where any axis jumps far from its local median (isolated outliers): more than
    SPIKE_K robust noise sigmas, that sigma never below the quantisation floor q/sqrt(12) so a
    quantised output (whose differences are mostly zero) does not lose half its rows."""
    n = len(log)
    q = output_step(log) if q is None else q
    bad = np.zeros(n, bool)
    starts = list(segments(log)) + [n]
    d = log.temp - np.mean(log.temp)
    for a in range(3):
        # Remove the input and a rough temperature trend first: a spike sitting on a step
        # of the applied rate would otherwise look like part of the step to the median.
        r = log.ref[:, a]
        X = np.column_stack([np.ones(n), d, d * d, r, r * d])
        y = log.out[:, a] - X @ np.linalg.lstsq(X, log.out[:, a], rcond=None)[0]
        local = np.empty(n)
        for s, e in zip(starts[:-1], starts[1:]):
            local[s:e] = median_filter(y[s:e], size=min(9, max(1, e - s)), mode="mirror")
        dev = y - local
        sig = max(_robust_sigma(np.diff(y)) / np.sqrt(2), q[a] / np.sqrt(12))
        if sig > 0:
            bad |= np.abs(dev) > SPIKE_K * sig
    return bad


def folds(log, k=6):
    """Held-out segments of one log: k contiguous blocks whose edges are moved to the nearest
    branch or run change, so each block is whole ramps/soaks rather than a slice of one."""
    n = len(log)
    k = max(2, min(k, n // 50))
    br = branch(temp_rate(log))
    change = np.flatnonzero(np.r_[False, br[1:] != br[:-1]])
    change = np.union1d(change, segments(log)[1:])
    edges = [0]
    for j in range(1, k):
        target = j * n // k
        if change.size:
            c = change[np.argmin(np.abs(change - target))]
            if abs(c - target) < 0.5 * n / k and c > edges[-1] + 10:
                target = c
        edges.append(max(target, edges[-1] + 1))
    edges.append(n)
    fold = np.zeros(n, int)
    for j in range(k):
        fold[edges[j]:edges[j + 1]] = j
    return fold
