"""Shared input checks for the host fitters: temperature grouping, bad-input errors (the CSV
reader is tools.fit.fastcsv).

Every problem in the data is a ``FitError`` (a ValueError) whose message names the row (CSV
line, header = line 1), the column or the temperature at fault and says what to do.
"""

import numpy as np


class FitError(ValueError):
    """The data cannot support the requested fit; the message names the problem."""


def check_finite(name, arr, lines=None):
    """FitError naming the first NaN/inf element of arr."""
    arr = np.asarray(arr, dtype=float)
    bad = ~np.isfinite(arr)
    if bad.any():
        idx = np.argwhere(bad)[0]
        where = "line %d" % lines[idx[0]] if lines is not None else "index %s" % (tuple(int(i) for i in idx),)
        raise FitError("%s at %s is %r: NaN/inf in the data" % (name, where, float(arr[tuple(idx)])))
    return arr


def group_temperatures(temp_c, lines=None, tol=1.0):
    """Cluster row temperatures into chamber set points.

    Rows within ``tol`` degC of their sorted neighbour form one temperature. The rows must come
    in blocks, one per temperature, in ascending order (a chamber sweep): a temperature that
    comes back after others is a duplicate, a block colder than the one before is unsorted;
    both raise FitError naming the rows. Returns (centres, index) with index[i] the row's
    temperature number in ascending order.
    """
    t = np.asarray(temp_c, dtype=float)
    if lines is None:
        lines = np.arange(len(t))
        what = "row"
    else:
        what = "line"
    order = np.argsort(t, kind="stable")
    ts = t[order]
    new = np.concatenate(([True], np.diff(ts) > tol))
    cid_sorted = np.cumsum(new) - 1
    idx = np.empty(len(t), dtype=int)
    idx[order] = cid_sorted
    n = int(cid_sorted[-1]) + 1 if len(t) else 0
    centres = np.array([t[idx == k].mean() for k in range(n)])
    # blocks along the rows
    starts = np.concatenate(([0], np.nonzero(np.diff(idx))[0] + 1))
    ends = np.concatenate((starts[1:], [len(t)]))
    seen = {}
    for s, e in zip(starts, ends):
        k = int(idx[s])
        if k in seen:
            ps, pe = seen[k]
            raise FitError(
                "duplicate temperature: %.2f degC appears in two separate blocks (%ss %d-%d and %d-%d); "
                "merge or drop one of them" % (centres[k], what, lines[ps], lines[pe - 1], lines[s], lines[e - 1])
            )
        seen[k] = (s, e)
    for a in range(1, len(starts)):
        k0 = int(idx[starts[a - 1]])
        k1 = int(idx[starts[a]])
        if k1 < k0:
            raise FitError(
                "temperatures are not sorted: %ss %d-%d at %.2f degC follow %ss %d-%d at %.2f degC; "
                "sort the rows by ascending temperature"
                % (what, lines[starts[a]], lines[ends[a] - 1], centres[k1], what,
                   lines[starts[a - 1]], lines[ends[a - 1] - 1], centres[k0])
            )
    return centres, idx


def check_temperatures(centres, order, what="fit", min_gap=5.0, min_span=20.0, warn_exact=True):
    """FitError when there are too few temperatures for ``order``; warnings when marginal."""
    warnings = []
    n = len(centres)
    if n < 2:
        raise FitError(
            "only one temperature (%.2f degC): a temperature coefficient needs at least 2 "
            "temperatures (order %d needs %d)" % (centres[0], order, order + 1)
        )
    if n < order + 1:
        raise FitError(
            "order %d %s needs at least %d temperatures, the data has %d (%s degC); "
            "use --order %d or measure more temperatures"
            % (order, what, order + 1, n, ", ".join("%.1f" % c for c in centres), n - 1)
        )
    if n == order + 1 and order > 1 and warn_exact:
        warnings.append(
            "%d temperatures for an order-%d law: the fit passes through every point and "
            "nothing checks it; measure more temperatures" % (n, order)
        )
    gaps = np.diff(centres)
    if len(gaps) and gaps.min() < min_gap:
        k = int(np.argmin(gaps))
        warnings.append(
            "temperatures %.2f and %.2f degC are only %.2f degC apart: the coefficients are "
            "poorly conditioned" % (centres[k], centres[k + 1], gaps[k])
        )
    if centres[-1] - centres[0] < min_span:
        warnings.append(
            "the temperatures span only %.1f degC: coefficients will extrapolate poorly"
            % (centres[-1] - centres[0])
        )
    return warnings


def poly_fit_weighted(x, y, deg):
    """Least-squares polynomial coefficients (ascending powers) and their covariance."""
    V = np.vander(x, deg + 1, increasing=True)
    coef, _, rank, _ = np.linalg.lstsq(V, y, rcond=None)
    dof = len(x) - (deg + 1)
    cov = None
    if dof > 0:
        r = y - V @ coef
        s2 = float(r @ r) / dof
        cov = s2 * np.linalg.pinv(V.T @ V)
    return coef, cov
