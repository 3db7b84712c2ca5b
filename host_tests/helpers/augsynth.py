"""Logs with one known effect each, for the device-vs-host shrink tests of the augmented model.
Written here from the physics (a lagging die temperature, a backlash, a settling exponential, a
supply, gravity, a tilted axis), independently of tools/simgap and tools/gapbench, so neither
the diagnosis nor its benchmark generator decides what the data holds."""
import numpy as np

from tools.simgap.logio import Log

EFFECTS = ("temp_rate", "hysteresis", "drift", "supply", "g_sensitivity", "cross_axis")
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


def make(effect, withheld=False, n=3000, dt=2.0, seed=0, sigma=1.5):
    """(Log, truth) with the effect on axis x (and on the others where it is a cross effect)."""
    seed = seed * 2 + int(withheld) + 10 * EFFECTS.index(effect)
    rng = np.random.default_rng(seed)
    t, T = _profile(n, dt, seed, withheld)
    levels = np.array([-200, -60, 0, 60, 200.0])
    ref = np.column_stack([np.repeat(rng.choice(levels, n // 40 + 1), 40)[:n] for _ in range(3)])
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
        out[:, 0] += SENS[0] * (0.02 * ref[:, 1] - 0.015 * ref[:, 2])
    out += rng.normal(0, sigma, out.shape)
    out = np.round(out)
    meta = {"sensor": "gyro", "ref_unit": "dps", "out_unit": "LSB", "power_on_s": "0"}
    return Log("%s_%s" % (effect, "withheld" if withheld else "train"), t, T, out, ref, meta, **extra)
