"""Physical plausibility of a fitted effect: its size against the range datasheets and
application notes give for the sensor kind (docs/simgap.md, "Plausible sizes"). A fit outside
it is reported (`implausible_coefficient`). Only a bound on one coefficient that a datasheet
states (VETO) keeps the effect out of the verdict; a rule of thumb only warns, and no bound is
a ratio to another fitted coefficient (a lag's weight follows thermal gradients across the
package and die, which the static slope does not limit).

Sizes are in the input's units (dps for a gyro, g for an accelerometer): the effect's
contribution divided by the axis sensitivity when the log identifies it, else converted from a
physical out_unit (mdps, dps, mg, g). A log in LSB on a stationary axis cannot be checked."""
import numpy as np

# kind -> effect -> (measure, limit, what the limit is based on)
#   "p2p": peak-to-peak contribution (0.5 .. 99.5 percentile) in input units
#   "per_g": largest coefficient per g, in input units per g
#   "relative": largest contribution over (sensitivity x |input|), i.e. a fraction of the reading
# VETO: effects whose limit is a datasheet bound on that coefficient alone (cited in
# docs/simgap.md); the others warn only.
VETO = {"g_sensitivity"}
TABLE = {
    "gyro": {
        "g_sensitivity": ("per_g", 3.0, "linear-acceleration sensitivity per axis of g: 0.01-0.1 "
                          "dps/g typical (ADXRS450 0.03, MPU-6050 0.1), 0.3 for old parts; "
                          "limit 3 dps/g, 10x the worst datasheet"),
        "offset_temperature": ("p2p", 10.0, "zero-rate change beyond the quadratic: a few dps"),
        "hysteresis": ("p2p", 10.0, "thermal hysteresis of the zero rate: < 1 dps typical"),
        "temp_rate": ("p2p", 10.0, "zero-rate change while the temperature moves: a few dps"),
        "drift": ("p2p", 10.0, "turn-on settling and aging: < a few dps"),
        "supply": ("p2p", 10.0, "supply sensitivity: < 1 dps/V typical over the supply range"),
        "temp_quantization": ("p2p", 10.0, "error of a coarse temperature reading: slope x step"),
        "turn_on_bias": ("p2p", 10.0, "turn-on to turn-on bias repeatability: < 1 dps typical"),
        "cross_axis": ("relative", 0.05, "cross-axis sensitivity / misalignment: 1-3 %"),
        "nonlinearity": ("relative", 0.03, "nonlinearity: 0.1-1 % of full scale (limit 3 % of the "
                         "largest input logged)"),
        "sensitivity_temperature": ("relative", 0.1, "sensitivity change beyond linear: < a few %"),
    },
    "accel": {
        "offset_temperature": ("p2p", 0.15, "zero-g change beyond the quadratic: tens of mg"),
        "hysteresis": ("p2p", 0.15, "thermal hysteresis of zero-g: a few mg"),
        "temp_rate": ("p2p", 0.15, "zero-g change while the temperature moves: tens of mg"),
        "drift": ("p2p", 0.15, "turn-on settling: a few mg"),
        "supply": ("p2p", 0.15, "supply sensitivity: a few mg/V"),
        "temp_quantization": ("p2p", 0.15, "error of a coarse temperature reading: slope x step"),
        "turn_on_bias": ("p2p", 0.15, "turn-on to turn-on zero-g repeatability: a few mg"),
        "cross_axis": ("relative", 0.05, "cross-axis sensitivity / misalignment: 1-3 %"),
        "nonlinearity": ("relative", 0.03, "nonlinearity: 0.1-1 % of full scale (limit 3 % of the "
                         "largest input logged)"),
        "sensitivity_temperature": ("relative", 0.1, "sensitivity change beyond linear: < a few %"),
    },
}
UNIT = {"mdps": 1e-3, "dps": 1.0, "mg": 1e-3, "g": 1.0}


def to_input(prob, base, axis):
    """Factor from out units to input units for this axis, or None when unknown."""
    keep = prob.ctx.base[axis][0] if prob.model is None else [True] * 5
    if base is not None and keep[3] and abs(base[3]) > 0:
        return 1.0 / abs(base[3])
    if prob.model is not None:
        return 1.0 / abs(prob.model.coef["xyz"[axis]][1][0] or np.inf)
    return UNIT.get(prob.train.log.unit)


def check(prob, axis, blocks):
    """[(effect, size, limit, unit text, basis, veto)] for every block of this axis that is
    outside the table (empty when all are plausible or cannot be checked); veto is True only
    for a datasheet bound (VETO)."""
    kind = prob.ctx.sensor if prob.ctx.sensor in TABLE else "gyro"
    base, parts, _ = prob.coefficients(axis, blocks)
    k = to_input(prob, base, axis)
    if k is None:
        k = float("nan")     # sizes in input units cannot be checked; ratios still can
    iu = prob.train.log.meta.get("ref_unit", "dps" if kind == "gyro" else "g")
    m = prob.train.mask
    bad = []
    names = [n for n, _ in blocks]
    for name in names:
        if name not in TABLE[kind]:
            continue
        measure, limit, basis = TABLE[kind][name]
        # What the effect changes in the prediction: the fit with it minus the fit without
        # it, so a part the fit could equally give the base model (a spline spans the
        # quadratic; one-hot orientations or runs sum to the constant) is not counted.
        without = [(n, sh) for n, sh in blocks if n != name]
        c = (prob.full_residual(prob.train, axis, without)
             - prob.full_residual(prob.train, axis, blocks))[m]
        if measure == "per_g":
            if prob.train.log.acc is None:
                continue
            size = _per_g(c, prob.train.log.acc[m]) * k
            unit = f"{iu}/g"
        elif measure == "p2p":
            size = float(np.percentile(c, 99.5) - np.percentile(c, 0.5)) * k
            unit = iu
        elif name == "cross_axis":
            # The other axes' inputs are not collinear with the base columns, so the fitted
            # coefficients themselves are the cross-axis sensitivities (x dT within the span).
            coef = next(cf for n, _, cf in parts if n == name)
            size = float(np.max(np.abs(coef[:2]))) * k
            unit = "of the other axis' reading"
        else:
            ref = prob.train.log.ref[m]
            r = np.abs(ref[:, axis]) if name != "cross_axis" else \
                np.max(np.abs(np.delete(ref, axis, axis=1)), axis=1)
            big = r > 0.2 * max(float(np.max(r)), 1e-300)
            if not np.any(big):
                continue
            if name == "nonlinearity":
                # Deviation from a straight line in the input: a linear part is sensitivity.
                X = np.column_stack([np.ones_like(r), ref[:, axis]])
                cc = c - X @ np.linalg.lstsq(X, c, rcond=None)[0]
            else:
                cc = c - np.median(c[~big]) if np.any(~big) else c
            if name == "nonlinearity":     # datasheets state it as a fraction of full scale
                size = float(np.percentile(np.abs(cc), 99.5)) * k / float(np.max(r))
                unit = "of full scale"
            else:
                size = float(np.percentile(np.abs(cc[big]) * k / r[big], 99.5))
                unit = "of the reading"
        if size > limit:     # (False for NaN: an unknown unit is not a finding)
            bad.append((name, size, limit, unit, basis, name in VETO))
    return bad


def _per_g(c, acc):
    """Largest component of the linear g-sensitivity vector k in c ~ k . acc + constant,
    fitted over the mean contribution of each orientation in the log (rounded to 0.1 g)."""
    key = np.round(acc, 1)
    u, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    if len(u) < 2:
        return 0.0
    means = np.array([c[inv == i].mean() for i in range(len(u))])
    X = np.column_stack([u, np.ones(len(u))])
    k = np.linalg.lstsq(X, means, rcond=None)[0][:3]
    return float(np.max(np.abs(k)))
