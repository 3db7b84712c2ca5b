"""The sim under test: per axis, offset quadratic in temperature and sensitivity linear in it
(NXP AN12760 / ADI AN-1049 model), either fitted on the training log or given as JSON.

JSON form (`--model`):
  {"t0_c": 25.0, "axes": {"x": {"offset": [o0, o1, o2], "sensitivity": [s0, s1]}, ...}}
meaning out = o0 + o1*dT + o2*dT^2 + (s0 + s1*dT) * ref with dT = temp - t0_c, in out units per
ref unit.
"""
import numpy as np

from tools.hostio import HostError, load_json

from .logio import AXES, LogError


class FixedModel:
    def __init__(self, t0, coef):
        self.t0 = t0
        self.coef = coef  # {axis: (offset[3], sensitivity[2])}

    @classmethod
    def load(cls, path):
        try:
            d = load_json(path)
        except HostError as e:
            raise LogError(str(e)) from None
        try:
            t0 = float(d.get("t0_c", 25.0))
            coef = {}
            for a in AXES:
                ax = d["axes"][a]
                off = [float(v) for v in ax["offset"]]
                sen = [float(v) for v in ax["sensitivity"]]
                if len(off) != 3 or len(sen) != 2:
                    raise ValueError(f"axis {a}: need 3 offset and 2 sensitivity coefficients")
                coef[a] = (off, sen)
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise LogError(f"{path}: bad model: {e}") from None
        return cls(t0, coef)

    def predict(self, log):
        d = log.temp - self.t0
        cols = []
        for i, a in enumerate(AXES):
            (o0, o1, o2), (s0, s1) = self.coef[a]
            cols.append(o0 + o1 * d + o2 * d * d + (s0 + s1 * d) * log.ref[:, i])
        return np.column_stack(cols)


def base_columns(ctx, log, axis):
    """Regressors of the fitted sim for one axis in physical units (degC from t0, ref units);
    the solver scales each column, so its coefficients are the model's as they stand."""
    d = log.temp - ctx.t0
    r = log.ref[:, axis]
    cols = np.column_stack([np.ones_like(d), d, d * d, r, r * d])
    keep = getattr(ctx, "base", None)
    return cols[:, keep[axis][0]] if keep is not None else cols
