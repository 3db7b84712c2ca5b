"""Six-position / multi-orientation accelerometer calibration at each temperature, vectorised.

Model at one temperature, for orientation o with known specific force g_o (in g)::

    raw_o = b + M g_o + noise,     M = diag(s) (I + N)

b: offset (counts), s: scale (counts per g), N: cross-axis terms (N_ij, i != j: axis i's
response to acceleration along j relative to its own). N's symmetric part is the sensor's
cross-axis sensitivity (non-orthogonality); its antisymmetric part is a small rotation
(misalignment between the sensor and the fixture). With six or more known orientations this
is linear least squares with one design shared by every unit (one pseudo-inverse for
10,000 units). With 9..12 *unknown* orientations (``ellipsoid=True``) |M^-1 (raw - b)| = 1 g
is fitted as a quadric; M is then the symmetric one, so misalignment is not observable. How well
the orientations cover the sphere is checked from the directions found (``check_coverage``):
the fit warns, or refuses, naming face/edge/corner attitudes to add.

Each coefficient's temperature dependence is a polynomial in T - t_room (order <= number of
temperatures - 1), fitted per unit. The device applies the per-axis part as AN12760 (offset,
TCO, SENtol, TCS) and the cross-axis part as ``tempcomp.crossaxis``.
"""

import numpy as np

from tools.fit.common import FitError, check_temperatures, group_temperatures

# +x: the sensor's +x axis points up and reads +1 g
LABELS = {
    "+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0),
    "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1),
}
_OFFDIAG = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]


def _check_temps(temps, tol):
    # per unit: strictly ascending, distinct by more than tol
    d = np.diff(temps, axis=1)
    if d.size and (d <= tol).any():
        u, k = (int(i) for i in np.argwhere(d <= tol)[0])
        a, b = temps[u, k], temps[u, k + 1]
        if abs(b - a) <= tol:
            raise FitError("duplicate temperature: unit %d has %.2f and %.2f degC (temperature %d and %d); "
                           "each temperature must appear once" % (u, a, b, k, k + 1))
        raise FitError("temperatures are not sorted: unit %d has %.2f degC after %.2f degC; "
                       "give them in ascending order" % (u, b, a))


def reduce_samples(raw, raw_range=(-32768, 32767)):
    """Means and standard errors over samples of raw (U, T, O, N, 3); saturation -> FitError."""
    raw = np.asarray(raw)
    if raw.ndim != 5 or raw.shape[-1] != 3:
        raise FitError("raw must have shape (units, temperatures, orientations, samples, 3), got %s" % (raw.shape,))
    if raw.dtype.kind == "f":
        bad = ~np.isfinite(raw)
        if bad.any():
            u, t, o, n, a = (int(i) for i in np.argwhere(bad)[0])
            raise FitError("NaN/inf in the data: unit %d, temperature %d, orientation %d, sample %d, axis %s"
                           % (u, t, o, n, "xyz"[a]))
    lo, hi = raw_range
    sat = (raw <= lo) | (raw >= hi)
    if sat.any():
        u, t, o, n, a = (int(i) for i in np.argwhere(sat)[0])
        raise FitError("saturated axis: unit %d, temperature %d, orientation %d, axis %s reads %d, at the "
                       "range limit %d..%d; use a wider range" % (u, t, o, "xyz"[a], raw[u, t, o, n, a], lo, hi))
    n = raw.shape[3]
    s1 = raw.sum(axis=3, dtype=np.float64)
    mean = s1 / n
    se = None
    if n > 1:
        sq = np.square(raw, dtype=np.float64).sum(axis=3)
        var = np.clip(sq - s1 * mean, 0.0, None) / (n - 1)
        se = np.sqrt(var / n)
    return mean, se


def fit_means(mean, temps, counts_per_g, g_dirs=None, se=None, order=1, t_room=25.0, temp_tol=1.0,
              ellipsoid=False):
    """Fit every unit; mean (U, T, O, 3) counts, temps (T,) or (U, T) degC, g_dirs (O, 3) g.

    Returns a dict of numpy arrays (see keys) and the warnings list.
    """
    mean = np.asarray(mean, dtype=np.float64)
    if mean.ndim != 4 or mean.shape[-1] != 3:
        raise FitError("means must have shape (units, temperatures, orientations, 3)")
    U, T, NO, _ = mean.shape
    if not np.isfinite(mean).all():
        u, t, o, a = (int(i) for i in np.argwhere(~np.isfinite(mean))[0])
        raise FitError("NaN/inf in the data: unit %d, temperature %d, orientation %d, axis %s" % (u, t, o, "xyz"[a]))
    temps = np.asarray(temps, dtype=np.float64)
    if temps.ndim == 1:
        temps = np.broadcast_to(temps, (U, T))
    if temps.shape != (U, T) or not np.isfinite(temps).all():
        raise FitError("temperatures must be finite, shape (T,) or (units, T)")
    _check_temps(temps, temp_tol)
    warnings = check_temperatures(temps.mean(axis=0), order, "temperature law")
    cpg = float(counts_per_g)
    x = mean / cpg  # in g, keeps every matrix near unit size
    se_x = se / cpg if se is not None else None
    if ellipsoid:
        b, M, res, dirs = _ellipsoid(x)
        warnings = warnings + check_coverage(dirs, temps)
        dof = NO - 9
        misalign = None
        se_b = se_M = None
    else:
        if g_dirs is None:
            raise FitError("known orientations (g_dirs) are needed unless ellipsoid=True")
        G = np.asarray(g_dirs, dtype=np.float64)
        if G.shape != (NO, 3):
            raise FitError("g_dirs must have one 3-vector per orientation (%d), got %s" % (NO, G.shape))
        for a in range(3):
            if G[:, a].max() < 0.5 or G[:, a].min() > -0.5:
                raise FitError("missing orientation: no orientation points axis %s %s (each axis needs one "
                               "near +1 g and one near -1 g)" % ("xyz"[a], "up" if G[:, a].max() < 0.5 else "down"))
        D = np.hstack([np.ones((NO, 1)), G])
        if np.linalg.matrix_rank(D) < 4:
            raise FitError("missing orientation: the %d orientations do not point every axis both up and "
                           "down (the design has rank %d of 4); add the missing ones" % (NO, np.linalg.matrix_rank(D)))
        Pinv = np.linalg.pinv(D)  # (4, O)
        par = np.einsum("ko,utoa->utka", Pinv, x)
        b = par[:, :, 0, :]
        M = np.swapaxes(par[:, :, 1:, :], 2, 3)  # M[a, j] = par[1 + j, a]
        res = x - np.einsum("ok,utka->utoa", D, par)
        dof = NO - 4
        cov = np.linalg.inv(D.T @ D)
        # noise of the means: from the samples if given, else from the residuals
        if se_x is not None:
            sig = np.sqrt(np.mean(se_x ** 2, axis=2))  # (U, T, 3)
        elif dof > 0:
            sig = np.sqrt(np.sum(res ** 2, axis=2) / dof)
        else:
            sig = np.full((U, T, 3), np.nan)
        se_b = sig * np.sqrt(cov[0, 0])
        se_M = sig[:, :, :, None] * np.sqrt(np.diag(cov)[1:])[None, None, None, :]
        misalign = None
    s = np.einsum("utaa->uta", M)
    N = M / s[:, :, :, None] - np.eye(3)
    if not ellipsoid:
        A = 0.5 * (N - np.swapaxes(N, 2, 3))
        misalign = np.stack([A[:, :, 2, 1], A[:, :, 0, 2], A[:, :, 1, 0]], axis=-1)  # rad about x, y, z
    rms = np.sqrt(np.mean(res ** 2, axis=2)) * 1000.0  # mg, (U, T, 3)
    # temperature laws: coefficient k of (T - t_room)^k per unit, per coefficient
    deg = min(order, T - 1)
    V = np.power((temps - t_room)[:, :, None], np.arange(deg + 1))  # (U, T, d+1)
    Vt = np.swapaxes(V, 1, 2)
    P = np.linalg.solve(Vt @ V, Vt)  # (U, d+1, T)
    off_mg = b * 1000.0
    cross = np.stack([N[:, :, i, j] for i, j in _OFFDIAG], axis=-1)  # (U, T, 6)
    law_off = np.einsum("ukt,uta->uka", P, off_mg)
    law_s = np.einsum("ukt,uta->uka", P, s)
    law_cross = np.einsum("ukt,utc->ukc", P, cross)
    out = {
        "temps": temps, "offset_mg": off_mg, "scale": s * cpg, "cross": N, "misalign_rad": misalign,
        "rms_mg": rms, "dof": dof, "law_offset_mg": law_off, "law_scale_rel": law_s, "law_cross": law_cross,
        "law_degree": deg,
    }
    if se_b is not None:
        out["se_offset_mg"] = se_b * 1000.0
        out["se_scale"] = np.einsum("utaa->uta", se_M) * cpg
        se_N = se_M / s[:, :, :, None]  # first order, |N| << 1
        out["se_cross"] = se_N
        out["se_law_offset_mg"] = np.sqrt(np.einsum("ukt,uta->uka", P ** 2, (se_b * 1000.0) ** 2))
        out["se_law_scale_rel"] = np.sqrt(np.einsum("ukt,uta->uka", P ** 2, np.einsum("utaa->uta", se_M) ** 2))
    # AN12760 form per axis: offset/TCO from the offset law, SENtol/TCS from the scale law
    out["sen_tol"] = law_s[:, 0, :] - 1.0
    out["tcs"] = law_s[:, 1:, :] / law_s[:, :1, :]
    out["tco"] = law_off[:, 1:, :]
    # cross-axis correction the device applies after per-axis compensation: (I + N(t_room))^-1 - I
    n_room = np.zeros((U, 3, 3))
    for c, (i, j) in enumerate(_OFFDIAG):
        n_room[:, i, j] = law_cross[:, 0, c]
    out["cross_correction"] = np.linalg.inv(np.eye(3) + n_room) - np.eye(3)
    out["cross_correction_law"] = _correction_law(law_cross, temps, t_room)
    return out, warnings


def _correction_law(law_cross, temps, t_room):
    """E(T) = (I + N(T))^-1 - I as a polynomial in T - t_room, (U, e+1, 3, 3), e = min(2 d, 3).

    N(T) is the fitted cross-axis law of degree d; E = -N + N^2 - N^3 ... is not a polynomial,
    so E's law is the least-squares polynomial through E on a fine grid over each unit's span.
    Its degree holds N^2 exactly (a linear N gives a quadratic E: a 3e-4/degC drift makes
    N1^2 dT^2 = 4e-4 at 65 degC, 0.4 mg at 1 g, if the law kept degree 1); what is left is of
    order |N(T) - N(t_room)|^3, 1e-5 for that drift (0.01 mg at 1 g).
    """
    U, D, _ = law_cross.shape
    DE = min(2 * (D - 1), 3) + 1
    grid = np.linspace(0.0, 1.0, 4 * DE + 1)
    dT = temps.min(axis=1)[:, None] + (temps.max(axis=1) - temps.min(axis=1))[:, None] * grid - t_room  # (U, G)
    V = np.power(dT[:, :, None], np.arange(D))  # (U, G, D)
    n = np.zeros((U, len(grid), 3, 3))
    for c, (i, j) in enumerate(_OFFDIAG):
        n[:, :, i, j] = np.einsum("ugk,uk->ug", V, law_cross[:, :, c])
    E = np.linalg.inv(np.eye(3) + n) - np.eye(3)  # (U, G, 3, 3)
    # scaled columns keep the normal equations well conditioned over +-65 degC
    s = np.maximum(np.abs(dT).max(axis=1), 1.0)[:, None]
    Vs = np.power((dT / s)[:, :, None], np.arange(DE))
    Vt = np.swapaxes(Vs, 1, 2)
    coef = np.linalg.solve(Vt @ Vs, Vt @ E.reshape(U, len(grid), 9))  # (U, DE, 9)
    coef = coef / np.power(s, np.arange(DE))[:, :, None]
    return coef.reshape(U, DE, 3, 3)


def _ellipsoid(x):
    """Quadric fit per (unit, temperature): x (U, T, O, 3) in g -> b (U,T,3), symmetric M, residuals."""
    U, T, NO, _ = x.shape
    if NO < 9:
        raise FitError("ellipsoid fit needs at least 9 orientations, the data has %d; use known orientations "
                       "(six-position) or measure more" % NO)
    X, Y, Z = x[..., 0], x[..., 1], x[..., 2]
    H = np.stack([X * X, Y * Y, Z * Z, 2 * X * Y, 2 * X * Z, 2 * Y * Z, 2 * X, 2 * Y, 2 * Z], axis=-1)
    Ht = np.swapaxes(H, 2, 3)
    HtH = Ht @ H
    rank = np.linalg.matrix_rank(HtH)
    if (rank < 9).any():
        u, t = (int(i) for i in np.argwhere(rank < 9)[0])
        raise FitError("ellipsoid fit: unit %d temperature %d: the orientations do not cover the sphere "
                       "(rank %d of 9); add orientations" % (u, t, rank[u, t]))
    p = np.linalg.solve(HtH, Ht @ np.ones((U, T, NO, 1)))[..., 0]
    Q = np.empty((U, T, 3, 3))
    Q[..., 0, 0], Q[..., 1, 1], Q[..., 2, 2] = p[..., 0], p[..., 1], p[..., 2]
    Q[..., 0, 1] = Q[..., 1, 0] = p[..., 3]
    Q[..., 0, 2] = Q[..., 2, 0] = p[..., 4]
    Q[..., 1, 2] = Q[..., 2, 1] = p[..., 5]
    v = p[..., 6:9]
    c = -np.linalg.solve(Q, v[..., None])[..., 0]
    k = 1.0 + np.einsum("uta,utab,utb->ut", c, Q, c)
    W = Q / k[..., None, None]
    lam, vec = np.linalg.eigh(W)
    if (lam <= 0).any():
        raise FitError("ellipsoid fit: the data is not an ellipsoid (a non-positive axis); check the data")
    Minv = np.einsum("utab,utb,utcb->utac", vec, np.sqrt(lam), vec)
    M = np.einsum("utab,utb,utcb->utac", vec, 1.0 / np.sqrt(lam), vec)
    a = np.einsum("utab,utob->utoa", Minv, x - c[:, :, None, :])
    norm = np.linalg.norm(a, axis=-1, keepdims=True)
    res = a - a / norm  # radial misfit, in g
    return c, M, res, a / norm


# Orientation coverage of the ellipsoid fit. Linearised about a sphere, a radial error e_o in
# orientation o (unit gravity direction u_o in the sensor frame) moves the fit by
# J^+ e with J's row o = [-u_o, u_x^2, u_y^2, u_z^2, 2 u_x u_y, 2 u_x u_z, 2 u_y u_z] (offset,
# then the symmetric matrix); sqrt(diag((J^T J)^-1)) is how many times a reading's noise (or
# rounding) reaches each coefficient. Evenly spread orientations give 0.5 (offsets) and 0.71
# (scales) with 12 of them. Random ones that crowd one hemisphere reach 3..30. No value of it
# separates the fits that miss the test's bounds from those that meet them: in 300 random sets
# of 12 at 3 counts of noise (seeds 0..299 of host_tests/fit/test_sixpos.py's case, the refusal
# lifted to measure), 140 were above 2.6, of which 93 missed and 47 met the bounds (up to 5.6),
# and 1 of the 160 at or below 2.6 missed (at 2.58). What the two thresholds hold there: every
# set that missed was above 2 (a warning, naming orientations to add), and every set above 6
# missed (22 of 22: refused).
COVERAGE_WARN = 2.0  # about 3x evenly spread: still usable, say which orientations to add
COVERAGE_REFUSE = 6.0  # errors 8x or more those of a good set: refuse
_COEFF = ["x offset", "y offset", "z offset", "x scale", "y scale", "z scale", "xy cross-axis term",
          "xz cross-axis term", "yz cross-axis term"]


def _design(u):
    x, y, z = u[..., 0], u[..., 1], u[..., 2]
    return np.stack([-x, -y, -z, x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z], axis=-1)


def amplification(u):
    """Noise amplification of each ellipsoid coefficient, (..., 9), for unit directions u (..., O, 3)."""
    J = _design(np.asarray(u, dtype=np.float64))
    JtJ = np.swapaxes(J, -1, -2) @ J
    out = np.full(JtJ.shape[:-1], np.inf)
    ok = np.linalg.matrix_rank(JtJ) == 9
    if ok.any():
        out[ok] = np.sqrt(np.clip(np.einsum("...ii->...i", np.linalg.inv(JtJ[ok])), 0.0, None))
    return out


def _candidates():
    # faces, edges (45 deg between two faces) and corners: the attitudes a box or a jig gives
    out = []
    for v in np.array(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij")).reshape(3, -1).T:
        if v.any():
            lab = "".join(("+" if c > 0 else "-") + "xyz"[i] for i, c in enumerate(v) if c)
            out.append((lab, v / np.linalg.norm(v)))
    return out


def orientations_to_add(u, target=COVERAGE_WARN, most=6):
    """Labels of face/edge/corner attitudes that bring the worst amplification to <= target (greedy)."""
    u = np.asarray(u, dtype=np.float64)
    cands = _candidates()
    added = []
    while amplification(u).max() > target and len(added) < most:
        best = min(cands, key=lambda c: amplification(np.vstack([u, c[1]])).max())
        added.append(best[0])
        u = np.vstack([u, best[1]])
    return added


def check_coverage(dirs, temps):
    """Warnings (and FitError) for orientation sets that cover the sphere poorly; dirs (U, T, O, 3)."""
    amp = amplification(dirs)  # (U, T, 9)
    worst = amp.max(axis=-1)
    u, t = (int(i) for i in np.unravel_index(np.argmax(worst), worst.shape))
    w = float(worst[u, t])
    if w <= COVERAGE_WARN:
        return []
    coeff = _COEFF[int(np.argmax(amp[u, t]))]
    add = orientations_to_add(dirs[u, t])
    what = ("add orientations with %s up (a label names the axes pointing up together: +x-y is +x and -y "
            "up at 45 deg)" % ", ".join(add)) if add else "add orientations on the side of the sphere the data lacks"
    n_bad = int((worst > COVERAGE_WARN).sum())
    msg = ("orientation coverage: unit %d at %.1f degC (%d unit-temperature(s) in all): the orientations crowd "
           "one side of the sphere, so a reading's noise reaches the %s %.1f times (evenly spread: 0.5..0.7); %s"
           % (u, temps[u, t], n_bad, coeff, w, what))
    if w > COVERAGE_REFUSE or not np.isfinite(w):
        raise FitError("ellipsoid fit refused: " + msg)
    return [msg]


def fit_csv(path, counts_per_g, order=1, t_room=25.0, ellipsoid=False, raw_range=(-32768, 32767), temp_tol=1.0):
    """One unit from a CSV ``temp_c,orient,ax,ay,az`` (optional gx,gy,gz); a result dict for JSON."""
    from tools.fit.fastcsv import read_table

    cols = read_table(path, COLUMNS, optional=OPTIONAL, text_cols=("orient",))
    return fit_table(cols, path, counts_per_g, order, t_room, ellipsoid, raw_range, temp_tol)


COLUMNS = ("temp_c", "orient", "ax", "ay", "az")
OPTIONAL = ("gx", "gy", "gz")


def fit_table(cols, path, counts_per_g, order=1, t_room=25.0, ellipsoid=False, raw_range=(-32768, 32767),
              temp_tol=1.0):
    """One unit from columns (as tools.fit.fastcsv.read_table returns); path names it in errors."""
    if not counts_per_g > 0:
        raise FitError("counts per g must be positive, got %r" % (counts_per_g,))
    lines = cols["_line"]
    T = np.asarray(cols["temp_c"], dtype=float)
    raw = np.stack([np.asarray(cols[c], dtype=float) for c in ("ax", "ay", "az")], axis=1)
    lo, hi = raw_range
    sat = (raw <= lo) | (raw >= hi)
    if sat.any():
        i, a = (int(v) for v in np.argwhere(sat)[0])
        raise FitError("saturated axis: %s line %d axis %s reads %d, at the range limit %d..%d; use a wider "
                       "range or drop that orientation" % (path, lines[i], "xyz"[a], raw[i, a], lo, hi))
    labels = [s.strip() for s in cols["orient"]]
    orients, first, inv = np.unique(np.array(labels, dtype=object).astype(str), return_index=True,
                                    return_inverse=True)
    orients = [str(o) for o in orients]
    have_g = all(c in cols for c in ("gx", "gy", "gz"))
    gvec = {}
    for j, lab in enumerate(orients):
        i = int(first[j])
        if have_g:
            g = tuple(float(cols[c][i]) for c in ("gx", "gy", "gz"))
        elif ellipsoid:
            g = (0.0, 0.0, 0.0)
        elif lab in LABELS:
            g = LABELS[lab]
        else:
            raise FitError("%s line %d: orientation %r is not one of %s (or give gx,gy,gz columns)"
                           % (path, lines[i], lab, " ".join(LABELS)))
        gvec[lab] = g
    centres, idx = group_temperatures(T, lines, temp_tol)
    if len(centres) < 2:
        raise FitError("only one temperature (%.2f degC): temperature laws need at least 2" % centres[0])
    NO = len(orients)
    NT = len(centres)
    cell = idx * NO + inv  # (temperature, orientation) of each row
    count = np.bincount(cell, minlength=NT * NO)
    if (count == 0).any():
        k, j = divmod(int(np.argmin(count)), NO)
        raise FitError("missing orientation: %.2f degC has no rows for orientation %r, which other "
                       "temperatures have" % (centres[k], orients[j]))
    s1 = np.stack([np.bincount(cell, raw[:, a], NT * NO) for a in range(3)], axis=1)
    mean = (s1 / count[:, None]).reshape(1, NT, NO, 3)
    se = np.zeros((1, NT, NO, 3))
    multi = count > 1
    if multi.any():
        dev = raw - mean.reshape(NT * NO, 3)[cell]
        ss = np.stack([np.bincount(cell, dev[:, a] ** 2, NT * NO) for a in range(3)], axis=1)
        var = np.where(multi[:, None], ss / np.maximum(count - 1, 1)[:, None], 0.0)
        se = np.sqrt(var / count[:, None]).reshape(1, NT, NO, 3)
    temps = (np.bincount(idx, T, NT) / np.bincount(idx, minlength=NT))
    G = np.array([gvec[lab] for lab in orients], dtype=float)
    have_se = bool((se > 0).any())
    out, warnings = fit_means(mean, temps, counts_per_g, None if ellipsoid else G, se if have_se else None,
                              order=order, t_room=t_room, temp_tol=temp_tol, ellipsoid=ellipsoid)
    return summarise(out, 0, counts_per_g, t_room, warnings, orients)


def summarise(out, u, counts_per_g, t_room, warnings, orients=None):
    """Readable dict of one unit's results (JSON)."""
    def f(a):
        return None if a is None else np.asarray(a).tolist()

    temps = out["temps"][u]
    per_t = []
    for k, t in enumerate(temps):
        d = {
            "temp_c": float(t),
            "offset_mg": f(out["offset_mg"][u, k]),
            "scale_counts_per_g": f(out["scale"][u, k]),
            "cross_axis": f(out["cross"][u, k]),
            "residual_rms_mg": f(out["rms_mg"][u, k]),
        }
        if out["misalign_rad"] is not None:
            d["misalignment_mrad"] = f(out["misalign_rad"][u, k] * 1000.0)
        if "se_offset_mg" in out:
            d["stderr_offset_mg"] = f(out["se_offset_mg"][u, k])
            d["stderr_scale_counts_per_g"] = f(out["se_scale"][u, k])
        per_t.append(d)
    axes = []
    for a in range(3):
        axes.append({
            "axis": "xyz"[a],
            "offset_mg": float(out["law_offset_mg"][u, 0, a]),
            "tco": f(out["tco"][u, :, a]),
            "sen_tol": float(out["sen_tol"][u, a]),
            "tcs": f(out["tcs"][u, :, a]),
        })
    return {
        "model": "sixpos" if out["misalign_rad"] is not None else "ellipsoid",
        "counts_per_g": float(counts_per_g),
        "t_room_c": float(t_room),
        "law_degree": int(out["law_degree"]),
        "orientations": orients,
        "temperatures": per_t,
        "axes": axes,
        "law_cross": {"terms": ["%s<-%s" % ("xyz"[i], "xyz"[j]) for i, j in _OFFDIAG],
                      "coeffs": f(out["law_cross"][u])},
        "cross_correction": f(out["cross_correction"][u]),
        "cross_correction_law": {
            "t_room_c": float(t_room),
            "t_span_c": [float(temps.min()), float(temps.max())],
            "coeffs": f(out["cross_correction_law"][u]),
        },
        "misalignment_observable": out["misalign_rad"] is not None,
        "warnings": warnings,
    }


def record_ints(res):
    """AN12760 record of the three axes; the cross-axis record goes to res['cross_record']."""
    from tempcomp import record

    t = [d["temp_c"] for d in res["temperatures"]]
    vals = [res["t_room_c"], t[0], t[-1], 3.0]
    for ax in res["axes"]:
        vals += [ax["offset_mg"]] + (ax["tco"] + [0.0] * 3)[:3] + [ax["sen_tol"]] + (ax["tcs"] + [0.0] * 3)[:3]
    res["cross_record"] = cross_axis(res).to_record()
    return record.pack(record.KIND_AN12760, vals)


def cross_axis(res, **kw):
    """The device's CrossAxis for a result dict: E(T) with its temperature law (kw: t_scale, t_offset).

    A result without a law (law degree 0, or a JSON written before the law existed) gives the
    constant matrix at t_room.
    """
    from tempcomp.crossaxis import CrossAxis

    law = res.get("cross_correction_law")
    if not law or len(law["coeffs"]) < 2:
        return CrossAxis(res["cross_correction"])
    return CrossAxis(law["coeffs"][0], law=law["coeffs"][1:], t_room=law["t_room_c"],
                     t_span_c=law["t_span_c"], **kw)
