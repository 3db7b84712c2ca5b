"""Statistics under correlated noise: the integrated autocorrelation time of a residual (how
many samples make one independent one), a block t-test whose block length comes from it, and
an Allan-deviation reading of what the residual's slow part is (random walk, flicker)."""
import numpy as np
from scipy import stats

MIN_BLOCKS = 8        # fewer independent blocks than this cannot support a finding


def autocorr_time(x, c=5.0, max_frac=0.25):
    """Integrated autocorrelation time tau = 1 + 2 sum rho(k), summed over lags up to the
    first window W >= c tau(W) (Sokal's rule); 1 for white noise, n/... for a random walk."""
    x = np.asarray(x, float)
    n = x.size
    if n < 16:
        return 1.0
    x = x - x.mean()
    v = float(np.dot(x, x))
    if v == 0:
        return 1.0
    m = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfft(x, m)
    acf = np.fft.irfft(f * np.conj(f), m)[:n] / v
    tau = np.cumsum(2 * acf) - 1.0
    kmax = int(max_frac * n)
    for w in range(1, kmax):
        if w >= c * tau[w]:
            return float(max(1.0, tau[w]))
    return float(max(1.0, tau[kmax - 1]))


def block_test(d, tau):
    """One-sided test that mean(d) > 0 with blocks of ceil(tau) samples (their means are
    close to independent). Returns (t, number of blocks, p-value); fewer than MIN_BLOCKS
    blocks give p = 1."""
    n = len(d)
    L = max(1, int(np.ceil(tau)))
    B = n // L
    if B < MIN_BLOCKS:
        return 0.0, B, 1.0
    means = d[:B * L].reshape(B, L).mean(axis=1)
    s = means.std(ddof=1)
    if s == 0:
        return (np.inf, B, 0.0) if means.mean() > 0 else (0.0, B, 1.0)
    t = float(means.mean() / (s / np.sqrt(B)))
    return t, B, float(stats.t.sf(t, B - 1))


def allan(x, dt=1.0):
    """Overlapping Allan deviation at octave cluster sizes m (>= 10 clusters): [(m, adev)]."""
    x = np.asarray(x, float)
    n = x.size
    c = np.r_[0.0, np.cumsum(x)]
    out = []
    m = 1
    while n // m >= 10:
        avg = (c[m:] - c[:-m]) / m              # every m-sample mean
        d = avg[m:] - avg[:-m]
        out.append((m, float(np.sqrt(0.5 * np.mean(d * d)))))
        m *= 2
    return out


def classify(x, sigma):
    """What the residual's slow part is: ('white', ratio), or ('flicker' | 'random walk' |
    'correlated', ratio) where ratio = Allan deviation at the longest cluster over what white
    noise of sigma would give there (sigma / sqrt(m))."""
    ad = allan(x)
    if len(ad) < 4 or sigma <= 0:
        return "white", 1.0
    m, a = ad[-1]
    ratio = a / (sigma / np.sqrt(m))
    if ratio < 2.0:
        return "white", float(ratio)
    # Log-log slope of the Allan deviation over the long-cluster half: +1/2 random walk,
    # 0 flicker (bias instability), -1/2 white.
    tail = ad[len(ad) // 2:]
    ms = np.log([p[0] for p in tail])
    vs = np.log([max(p[1], 1e-300) for p in tail])
    slope = float(np.polyfit(ms, vs, 1)[0]) if len(tail) >= 2 else 0.0
    kind = "random walk" if slope > 0.25 else ("flicker" if slope > -0.25 else "correlated")
    return kind, float(ratio)
