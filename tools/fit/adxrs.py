"""ADI three-point calibration of an analog gyro (AN-1049): null V0 and scale S quadratic in VT.

CSV columns ``temp_c,vt_mv,rate_dps,out_mv``: at each chamber temperature, rows at rest
(rate 0) and at one or more known rates, with the temperature output VT and the rate output,
both sensor-side millivolts. Per temperature, V0 and S are the least-squares line
out = V0 + S * rate; VT is the mean reading. Across temperatures, V0(VT) and S(VT) are the
quadratics through the three points (exactly three temperatures, the note's method) or the
least-squares quadratics (more than three).
"""

import numpy as np

from tools.fit.common import FitError, check_temperatures, group_temperatures

MIN_SCALE = 0.01  # mV per dps


def points_from_rows(temp_c, vt_mv, rate_dps, out_mv, lines=None, temp_tol=1.0):
    """Per-temperature (temp_c, VT mV, V0 mV, S mV/dps, rms mV) rows and the warnings."""
    centres, idx = group_temperatures(temp_c, lines, temp_tol)
    warnings = check_temperatures(centres, 2, "three-point quadratic", warn_exact=False)
    rates_all = np.unique(np.round(rate_dps, 6))
    pts = []
    for k, c in enumerate(centres):
        m = idx == k
        r = rate_dps[m]
        rs = np.unique(np.round(r, 6))
        if len(rs) < 2:
            raise FitError(
                "missing rate: at %.2f degC every row has rate_dps = %g; the scale factor needs a "
                "rest reading and a known rate at each temperature" % (c, rs[0])
            )
        lack = np.setdiff1d(rates_all, rs)
        if len(lack):
            raise FitError("missing rate: %.2f degC has no row at %s dps, which other temperatures have"
                           % (c, ", ".join("%g" % v for v in lack)))
        A = np.stack([np.ones(m.sum()), r], axis=1)
        (v0, s), *_ = np.linalg.lstsq(A, out_mv[m], rcond=None)
        res = out_mv[m] - A @ np.array([v0, s])
        rms = float(np.sqrt(np.mean(res ** 2)))
        swing = abs(s) * float(rs[-1] - rs[0])
        # the slowest ADXRS (ADXRS649, +-20000 dps) still gives 0.1 mV/dps
        if abs(s) < MIN_SCALE or swing <= 3.0 * rms:
            raise FitError(
                "stuck rate output: at %.2f degC the output moves %.3g mV over %g..%g dps (scale %.3g mV/dps, "
                "noise %.3g mV rms); a rate output that does not follow the rate cannot be calibrated: "
                "check the wiring and the rate column" % (c, swing, rs[0], rs[-1], s, rms))
        pts.append((float(c), float(vt_mv[m].mean()), float(v0), float(s), rms))
    signs = {p[3] > 0 for p in pts}
    if len(signs) > 1:
        raise FitError("the scale factor changes sign between temperatures (%s mV/dps at %s degC): "
                       "check the rate column's sign" % (", ".join("%.3g" % p[3] for p in pts),
                                                         ", ".join("%.1f" % p[0] for p in pts)))
    vts = [p[1] for p in pts]
    if np.any(np.diff(vts) <= 0):
        raise FitError("the temperature output VT does not rise with temperature (%s mV at %s degC): "
                       "check the VT wiring/column" % (", ".join("%.1f" % v for v in vts),
                                                       ", ".join("%.1f" % p[0] for p in pts)))
    return pts, warnings


def fit_points(pts, warnings=None):
    """V0/S quadratics in VT from per-temperature points (see points_from_rows)."""
    from tempcomp.fixedpoint import quadratic_through

    warnings = list(warnings or [])
    vt = np.array([p[1] for p in pts])
    v0 = np.array([p[2] for p in pts])
    s = np.array([p[3] for p in pts])
    if len(pts) < 3:
        raise FitError("three-point calibration needs 3 temperatures, got %d" % len(pts))
    # reference: the point nearest 25 degC (the note's ambient V_T0)
    k0 = int(np.argmin([abs(p[0] - 25.0) for p in pts]))
    ref = float(vt[k0])
    if len(pts) == 3:
        c_v0 = list(quadratic_through((vt[0], v0[0]), (vt[1], v0[1]), (vt[2], v0[2]), ref))
        c_s = list(quadratic_through((vt[0], s[0]), (vt[1], s[1]), (vt[2], s[2]), ref))
        method = "three-point"
    else:
        V = np.vander(vt - ref, 3, increasing=True)
        c_v0 = [float(c) for c in np.linalg.lstsq(V, v0, rcond=None)[0]]
        c_s = [float(c) for c in np.linalg.lstsq(V, s, rcond=None)[0]]
        method = "least-squares quadratic (%d temperatures)" % len(pts)
    u = vt - ref
    fit_v0 = c_v0[0] + c_v0[1] * u + c_v0[2] * u * u
    fit_s = c_s[0] + c_s[1] * u + c_s[2] * u * u
    rows = []
    for i, p in enumerate(pts):
        rows.append({"temp_c": p[0], "vt_mv": p[1], "v0_mv": p[2], "s_mv_per_dps": p[3], "line_rms_mv": p[4],
                     "v0_residual_mv": float(v0[i] - fit_v0[i]),
                     "null_error_dps": float((v0[i] - fit_v0[i]) / fit_s[i]),
                     "s_residual": float(s[i] / fit_s[i] - 1.0)})
    return {
        "model": "adxrs",
        "method": method,
        "vt_ref_mv": ref,
        "vt_span_mv": [float(vt[0]), float(vt[-1])],
        "v0_mv": [float(c) for c in c_v0],
        "s_mv_per_dps": [float(c) for c in c_s],
        "points": rows,
        "warnings": warnings,
    }


def fit_rows(temp_c, vt_mv, rate_dps, out_mv, lines=None, temp_tol=1.0):
    """Fit from per-row measurements (arrays); see the module docstring."""
    pts, w = points_from_rows(np.asarray(temp_c, float), np.asarray(vt_mv, float),
                              np.asarray(rate_dps, float), np.asarray(out_mv, float), lines, temp_tol)
    return fit_points(pts, w)


COLUMNS = ("temp_c", "vt_mv", "rate_dps", "out_mv")


def fit_csv(path, temp_tol=1.0):
    from tools.fit.fastcsv import read_table

    return fit_table(read_table(path, COLUMNS), temp_tol)


def fit_table(cols, temp_tol=1.0):
    """Fit from columns (as tools.fit.fastcsv.read_table returns)."""
    return fit_rows(*(cols[c] for c in COLUMNS), lines=cols["_line"], temp_tol=temp_tol)


def record_ints(res):
    """The device record (tempcomp.adxrs KIND_ADXRS layout)."""
    from tempcomp import record

    return record.pack(record.KIND_ADXRS, [res["vt_ref_mv"]] + res["vt_span_mv"] + res["v0_mv"] + res["s_mv_per_dps"])
