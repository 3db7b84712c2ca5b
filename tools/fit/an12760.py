"""NXP AN12760 offset/TCO/SENtol/TCS: the note's forward model, eq. 11 in float, and the fit.

Model for one axis (AN12760 §2.2-2.4, Table 9 parameters), dT = T - Troom::

    out_mg = Off + sum TCO_k dT^k + ref_g * 1000 * (1 + SENtol) * (1 + sum TCS_k dT^k)

It is linear in a_k (Off, TCO_k) and b_k = 1000 (1 + SENtol) * (1, TCS_1, ...), so one
least-squares solve over every row fits it; SENtol = b_0/1000 - 1 and TCS_k = b_k/b_0.
With order 1 and the three temperatures x (-1, 0, +1) g of the note this is eq. 3/4/8/9.
"""

import numpy as np

from tools.fit.common import FitError, check_finite, check_temperatures, group_temperatures


def _terms(v, order=3):
    v = [float(x) for x in np.atleast_1d(v)]
    return v + [0.0] * (order - len(v))


def simulate_mg(temp_c, ref_g, offset_mg, tco, sen_tol, tcs, t_room=25.0):
    """Raw output (mg) of an axis with the injected errors (AN12760 §3, Table 9)."""
    dT = np.asarray(temp_c, dtype=float) - t_room
    off = offset_mg + sum(c * dT ** (k + 1) for k, c in enumerate(_terms(tco)))
    sens = (1.0 + sen_tol) * (1.0 + sum(c * dT ** (k + 1) for k, c in enumerate(_terms(tcs))))
    return off + np.asarray(ref_g, dtype=float) * 1000.0 * sens


def acc_tco(raw_mg, temp_c, offset_mg, tco, t_room=25.0):
    """AccTCO (mg): raw minus the offset at temperature (eq. 5, cubic form)."""
    dT = np.asarray(temp_c, dtype=float) - t_room
    return raw_mg - (offset_mg + sum(c * dT ** (k + 1) for k, c in enumerate(_terms(tco))))


def correct_mg(raw_mg, temp_c, offset_mg, tco, sen_tol, tcs, t_room=25.0):
    """AccTCOTCS (mg), AN12760 eq. 11 and its cubic form, in float64."""
    dT = np.asarray(temp_c, dtype=float) - t_room
    den = (1.0 + sen_tol) * (1.0 + sum(c * dT ** (k + 1) for k, c in enumerate(_terms(tcs))))
    return acc_tco(raw_mg, temp_c, offset_mg, tco, t_room) / den


def fit(temp_c, ref_g, out_mg, order=1, t_room=25.0, temp_tol=1.0, full_scale_mg=None, lines=None):
    """Fit Off, TCO_1..order, SENtol, TCS_1..order of one axis; returns a result dict.

    temp_c, ref_g, out_mg: one value per row (degC, true input in g, raw output in mg).
    Rows come in ascending temperature blocks; each temperature needs the same set of at
    least two distinct ref_g values. full_scale_mg: the range limit; a reading at or beyond
    it is a saturated axis (FitError).
    """
    if order not in (1, 2, 3):
        raise FitError("order must be 1, 2 or 3 (AN12760 allows up to a 3rd-order law), got %r" % (order,))
    T = check_finite("temp_c", temp_c, lines)
    g = check_finite("ref_g", ref_g, lines)
    y = check_finite("out_mg", out_mg, lines)
    if not (len(T) == len(g) == len(y)):
        raise FitError("temp_c, ref_g and out_mg have different lengths")
    if lines is None:
        lines = np.arange(len(T))
    if full_scale_mg is not None:
        sat = np.abs(y) >= full_scale_mg
        if sat.any():
            i = int(np.argmax(sat))
            raise FitError(
                "saturated axis: line %d reads %.1f mg, at the +-%.1f mg full-scale limit; "
                "use a wider range or drop that orientation" % (lines[i], y[i], full_scale_mg)
            )
    centres, idx = group_temperatures(T, lines, temp_tol)
    warnings = check_temperatures(centres, order, "TCO/TCS law")
    refs_all = np.unique(np.round(g, 6))
    for k, c in enumerate(centres):
        refs = np.unique(np.round(g[idx == k], 6))
        if len(refs) < 2:
            raise FitError(
                "missing orientation: at %.2f degC every row has ref_g = %g; sensitivity needs "
                "at least two orientations (e.g. +1 g and -1 g) at each temperature" % (c, refs[0])
            )
        lack = np.setdiff1d(refs_all, refs)
        if len(lack):
            raise FitError(
                "missing orientation: %.2f degC has no row with ref_g = %s, which other "
                "temperatures have" % (c, ", ".join("%g" % v for v in lack))
            )
    if not (centres[0] - temp_tol <= t_room <= centres[-1] + temp_tol):
        warnings.append(
            "Troom %.1f degC is outside the measured %.1f..%.1f degC: Offset and SENtol are "
            "extrapolated" % (t_room, centres[0], centres[-1])
        )
    # columns scaled by 50 degC per unit keep the normal matrix well conditioned
    u = (T - t_room) / 50.0
    P = np.vander(u, order + 1, increasing=True)
    X = np.hstack([P, P * g[:, None]])
    coef, _, rank, sv = np.linalg.lstsq(X, y, rcond=None)
    if rank < X.shape[1]:
        raise FitError("the data cannot separate offset and sensitivity terms (rank %d of %d)" % (rank, X.shape[1]))
    resid = y - X @ coef
    dof = len(y) - X.shape[1]
    scale = 50.0 ** -np.arange(order + 1)
    a = coef[: order + 1] * scale
    b = coef[order + 1 :] * scale
    offset = a[0]
    tco = a[1:]
    sen_tol = b[0] / 1000.0 - 1.0
    tcs = b[1:] / b[0]
    # standard errors (delta method for the ratios); none when the fit is exact
    err = None
    if dof > 0:
        s2 = float(resid @ resid) / dof
        cov = s2 * np.linalg.pinv(X.T @ X)
        S = np.concatenate([scale, scale])
        cov = cov * np.outer(S, S)
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
        n1 = order + 1
        tcs_sd = []
        for k in range(1, n1):
            J = np.zeros(2 * n1)
            J[n1 + k] = 1.0 / b[0]
            J[n1] = -b[k] / b[0] ** 2
            tcs_sd.append(float(np.sqrt(max(J @ cov @ J, 0.0))))
        err = {
            "offset_mg": float(sd[0]),
            "tco": [float(v) for v in sd[1:n1]],
            "sen_tol": float(sd[n1] / 1000.0),
            "tcs": tcs_sd,
        }
    per_t = []
    for k, c in enumerate(centres):
        r = resid[idx == k]
        per_t.append({"temp_c": float(c), "rows": int(r.size), "rms_mg": float(np.sqrt(np.mean(r * r))),
                      "max_abs_mg": float(np.max(np.abs(r)))})
    res = {
        "model": "an12760",
        "order": order,
        "t_room_c": float(t_room),
        "offset_mg": float(offset),
        "tco_mg_per_c": float(tco[0]),
        "sen_tol": float(sen_tol),
        "tcs_per_c": float(tcs[0]),
        "temperatures_c": [float(c) for c in centres],
        "residuals": per_t,
        "stderr": err,
        "warnings": warnings,
    }
    if order > 1:
        res["tco"] = [float(v) for v in tco]
        res["tcs"] = [float(v) for v in tcs]
    return res


def axis_tuple(res):
    """(offset_mg, tco terms, sen_tol, tcs terms) for tempcomp.an12760.AN12760."""
    tco = res.get("tco", [res["tco_mg_per_c"]])
    tcs = res.get("tcs", [res["tcs_per_c"]])
    return (res["offset_mg"], list(tco), res["sen_tol"], list(tcs))
