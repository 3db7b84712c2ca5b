"""Intervals that count the correlated noise: a stationary block bootstrap (arch) of the rows,
with the block length from the axis's noise model, for every shrink and the final RMS."""
import numpy as np
from arch.bootstrap import StationaryBootstrap

from . import noise as N

REPS = 300
SEED = 20261127       # fixed: the same log gives the same interval


def block_length(model, r):
    """Rows per block: long enough to hold what the noise model correlates (the random walk
    overtakes the white noise after s2/q rows; a Gauss-Markov term forgets after a few Tc),
    and never shorter than the residual's own integrated autocorrelation time."""
    n = len(r)
    L = N.autocorr_time(np.asarray(r) - np.mean(r))
    if model is not None and model.q > 0:
        L = max(L, model.s2 / model.q)
    if model is not None and model.g2 > 0:
        L = max(L, 3 * (-1.0 / np.log(model.phi)))
    return float(np.clip(L, 1.0, max(1.0, n / 8)))


def _ci(stat, data, L, reps):
    bs = StationaryBootstrap(L, *data, seed=np.random.default_rng(SEED))
    vals = np.array([stat(*pos) for pos, _ in bs.bootstrap(reps)])
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return [None, None]
    lo, hi = np.percentile(vals, [5, 95])
    return [float(lo), float(hi)]


def shrink_interval(before, after, L, reps=REPS):
    """90 % interval of 1 - RMS(after)/RMS(before), rows (n,) or (n, axes) resampled together."""
    b = np.asarray(before, float).reshape(len(before), -1)
    a = np.asarray(after, float).reshape(len(after), -1)
    if len(b) < 10:
        return [None, None]

    def stat(bb, aa):
        sb = float(np.sum(bb * bb))
        return 1 - np.sqrt(float(np.sum(aa * aa)) / sb) if sb > 0 else np.nan

    return _ci(stat, (b, a), L, reps)


def rms_interval(r, L, reps=REPS):
    r = np.asarray(r, float)
    if len(r) < 10:
        return [None, None]
    return _ci(lambda x: float(np.sqrt(np.mean(x * x))), (r,), L, reps)
