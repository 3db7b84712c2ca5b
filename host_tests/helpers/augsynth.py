"""Logs with one known effect each, for the device-vs-host shrink tests of the augmented model.
Written here from the physics (a lagging die temperature, a backlash, a settling exponential, a
supply, gravity, a tilted axis), independently of tools/simgap and tools/gapbench, so neither
the diagnosis nor its benchmark generator decides what the data holds."""
import numpy as np

from tools.simgap import devmodel
from tools.simgap.logio import Log

EFFECTS = ("temp_rate", "hysteresis", "drift", "supply", "g_sensitivity", "cross_axis")
NONE = "none"  # make(NONE): the same sensor and programme with no effect at all
SENS = np.array([16.4, 16.0, 16.2])  # LSB per dps at 25 degC


def _profile(n, dt, seed, withheld):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    # ramps of different rates both ways, with soaks; the withheld programme is another one
    if withheld:
        kt = np.array([0, 0.1, 0.3, 0.4, 0.62, 0.7, 0.9, 1.0])
        kT = np.array([20, 20, 45, 45, 5, 5, 30, 30.0])
    else:
        kt = np.array([0, 0.06, 0.22, 0.3, 0.5, 0.56, 0.72, 0.8, 0.92, 1.0])
        kT = np.array([25, 25, 50, 50, 0, 0, 40, 40, 15, 15.0])
    T = np.interp(t, kt * t[-1], kT) + rng.normal(0, 0.02, n)
    return t, T


def _lowpass(x, dt, tau):
    a = 1 - np.exp(-dt / tau)
    y = np.empty_like(x)
    v = x[0]
    for i, xi in enumerate(x):
        v += a * (xi - v) if i else 0.0
        y[i] = v
    return y


def _play(x, w):
    v, out = x[0], np.empty_like(x)
    for i, xi in enumerate(x):
        v = min(max(v, xi - w / 2), xi + w / 2)
        out[i] = v
    return out


def make(effect, withheld=False, n=3000, dt=2.0, seed=0, sigma=1.5, still=None):
    """A Log with the effect on axis x (and on the others where it is a cross effect), or none
    (effect NONE); still=k holds axis k's input at -60 dps throughout (like gravity on an
    accelerometer's axis)."""
    seed = seed * 2 + int(withheld) + 10 * (EFFECTS + (NONE,)).index(effect)
    rng = np.random.default_rng(seed)
    t, T = _profile(n, dt, seed, withheld)
    levels = np.array([-200, -60, 0, 60, 200.0])
    ref = np.column_stack([np.repeat(rng.choice(levels, n // 40 + 1), 40)[:n] for _ in range(3)])
    if still is not None:
        ref[:, still] = -60.0
    Tc = T
    if effect == "temp_rate":
        Tc = _lowpass(T, dt, 150.0)  # the die lags the reading
    d = Tc - 25
    off = np.array([40.0, -25.0, 12.0])
    o1 = np.array([3.0, -2.0, 1.5])
    o2 = np.array([-0.02, 0.015, 0.01])
    s1 = np.array([1e-3, -8e-4, 5e-4])
    out = off + o1 * d[:, None] + o2 * d[:, None] ** 2 + SENS * (1 + s1 * d[:, None]) * ref
    extra = {}
    if effect == "hysteresis":
        out[:, 0] += 12.0 * (_play(T, 4.0) - T)
    elif effect == "drift":
        out[:, 0] += 80.0 * np.exp(-t / 400.0)
    elif effect == "supply":
        v = 3.3 + np.repeat(rng.uniform(-0.25, 0.25, n // 60 + 1), 60)[:n]
        out[:, 0] += 120.0 * (v - 3.3)
        extra["supply"] = v
    elif effect == "g_sensitivity":
        g = rng.normal(size=(n // 60 + 1, 3))
        g /= np.linalg.norm(g, axis=1)[:, None]
        acc = np.repeat(g, 60, axis=0)[:n]
        out[:, 0] += acc @ np.array([25.0, -15.0, 10.0])
        extra["acc"] = acc
    elif effect == "cross_axis":
        out[:, 0] += SENS[0] * (0.012 * ref[:, 1] - 0.008 * ref[:, 2])  # within 1-3 %, datasheet-typical
    out += rng.normal(0, sigma, out.shape)
    out = np.round(out)
    meta = {"sensor": "gyro", "ref_unit": "dps", "out_unit": "LSB", "power_on_s": "0"}
    return Log("%s_%s" % (effect, "withheld" if withheld else "train"), t, T, out, ref, meta, **extra)


# A device model with every kind of term on every axis, and board inputs for it (the device
# tests' fixture): the raw codes come from the float64 forward model of known inputs.
OUT_SCALE = 100.0


def every_term_model():
    return {"t_lsb": 0.01, "t_off": 0.0, "raw_lsb": 1.0, "raw_range": [-32768, 32767],
            "out_scale": OUT_SCALE, "t0": 25.0, "t_cal": [0.0, 50.0], "supply_lsb": 0.001,
            "supply0": 3.3, "acc_lsb": 0.001,
            "offset": [[50, 4, -0.02], [-30, 2, 0.01], [10, -3, 0.015]],
            "sensitivity": [[16.4, 0.002], [16.0, -0.003], [16.2, 0.001]],
            "features": [{"kind": "dT"}, {"kind": "lag", "tau": 60.0, "bound": 10.0},
                         {"kind": "play", "width": 2.0}, {"kind": "play", "width": 1.0, "lag": 60.0},
                         {"kind": "drift_exp", "tau": 300.0}, {"kind": "drift_hyp", "tau": 200.0},
                         {"kind": "uptime", "bound": 20000.0}, {"kind": "supply", "bound": 0.5},
                         {"kind": "acc", "axis": 0, "bound": 2.0}, {"kind": "acc", "axis": 2, "bound": 2.0},
                         {"kind": "prod", "a": 1, "b": 0}, {"kind": "prod", "a": 1, "b": 1, "bound": 100.0},
                         {"kind": "prod", "a": 8, "b": 0}, {"kind": "lag", "tau": 900.0, "bound": 40.0}],
            "offset_terms": [[[1, 5.0], [2, 3.0], [4, 20.0], [6, 0.001], [10, 0.05], [11, 0.2]],
                             [[3, -4.0], [5, 8.0], [7, 30.0], [8, 2.0], [13, 1.5]],
                             [[9, -1.5], [12, 0.03]]],
            "gain_terms": [[[1, 0.002]], [[7, 0.01]], [[13, -0.001]]],
            "cross": [[[1, 0.01, 0.0001]], [[0, -0.005, 0.0]], [[0, 0.003, 0.0], [1, 0.002, -0.00005]]]}


def inputs(m, n=3000, seed=1, jitter=3):
    rng = np.random.default_rng(seed)
    t_s = np.arange(n) * 1.0
    T = 25 + 20 * np.sin(t_s / 400) + rng.normal(0, 0.05, n)
    ref = rng.uniform(-1500, 1500, (n, 3))
    inp = {"t": np.round(T / 0.01).astype(np.int64),
           "dt_ms": np.r_[0, np.full(n - 1, 1000) + rng.integers(-jitter, jitter + 1, n - 1)],
           "supply": np.round((3.3 + 0.2 * np.sin(t_s / 90)) / 0.001).astype(np.int64),
           "acc": np.round(rng.uniform(-1, 1, (n, 3)) / 0.001).astype(np.int64), "uptime0_ms": 0}
    F = devmodel.features(m, inp)
    inp["raw"] = np.round(devmodel.predict(m, inp, ref, F)).astype(np.int64)
    return inp, F
