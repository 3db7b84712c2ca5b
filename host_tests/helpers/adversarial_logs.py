"""Adversarial logs for the gap diagnosis, written for the tests apart from the blind benchmark's
generator (tools/gapbench/gen.py) and from the tool: plain numpy physics, each knob one of the
situations in issue 15 that once fooled the diagnosis.

    log = make(sensor="gyro", profile="cycle", noise="gauss", sigma=..., q=..., effect=..., ...)

returns a tools.simgap.logio.Log (seed is required: the tests pass one of the run's,
host_tests/helpers/seeds.py). Every expectation in the tests comes from how the log was made
(the true sigma, the true effect and its axis), never from the tool's output.
"""
import numpy as np

from tools.simgap.logio import Log

DT = 2.0   # s between samples


def temperature(profile, n, seed, lo=-10.0, hi=60.0, plateau=25.0):
    """The part's temperature reading: 'cycle' (heat and cool over lo..hi with soaks, two ramp
    rates), 'plateau' (a soak at `plateau` with +/-0.05 degC wander), 'cooling' (monotonic)."""
    rng = np.random.default_rng(seed + 101)
    t = np.arange(n) * DT
    if profile == "plateau":
        T = plateau + 0.05 * np.sin(t / 900.0) + rng.normal(0, 0.01, n)
    elif profile == "cooling":
        T = hi - (hi - lo) * t / t[-1]
    else:
        f = np.array([0, .07, .22, .30, .45, .52, .70, .77, .90, 1.0])
        v = np.array([25, 25, hi, hi, lo, lo, hi - 10, hi - 10, lo + 15, lo + 15])
        T = np.interp(t, f * t[-1], v)
    return t, T


def inputs(sensor, n, seed, axes_moving=(0, 1, 2)):
    """True input: a gyro's rate table steps (dps) on the moving axes; an accelerometer turned
    through the six faces (g)."""
    rng = np.random.default_rng(seed + 202)
    ref = np.zeros((n, 3))
    if sensor == "gyro":
        levels = np.array([-200, -80, -20, 0, 20, 80, 200.0])
        for a in axes_moving:
            ref[:, a] = np.repeat(rng.choice(levels, n // 40 + 1), 40)[:n]
        acc = np.tile([0.0, 0.0, 1.0], (n, 1))
        return ref, acc
    faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]])
    # Each face in as many 150-row stints as the others, shuffled: drawn independently, a 3000-row
    # log missed +z at TEMPCOMP_SEED=10, and a withheld log with it was an extrapolation.
    k = np.repeat(rng.permutation(np.arange(n // 150 + 1) % 6), 150)[:n]
    ref = faces[k]
    return ref, ref.copy()


def noise(kind, sigma, n, seed, walk=0.0):
    """(n, 3) noise with true standard deviation sigma: 'gauss', or 'student' (t, 3 degrees of
    freedom, scaled to std sigma); plus a bias random walk of `walk` per sqrt(sample)."""
    rng = np.random.default_rng(seed + 303)
    if kind == "student":
        e = rng.standard_t(3, (n, 3)) * sigma / np.sqrt(3.0)
    else:
        e = rng.normal(0, sigma, (n, 3))
    if walk:
        e += np.cumsum(rng.normal(0, walk, (n, 3)), axis=0)
    return e


def make(sensor="gyro", profile="cycle", n=3000, sigma=2.0, noise_kind="gauss", q=0.0,
         walk=0.0, effect=None, effect_axis=0, shift=None, spikes=0, *, seed, name="adv",
         plateau=25.0, unit=None, axes_moving=(0, 1, 2), extra_cols=None):
    """One log. effect(t, T, ref, acc) -> extra output on `effect_axis` (out units);
    shift: constant per-axis offset (a separate power-on); spikes: that many isolated spikes;
    q: output quantisation step (0: none)."""
    t, T = temperature(profile, n, seed, plateau=plateau)
    ref, acc = inputs(sensor, n, seed, axes_moving)
    dT = T - 25.0
    if sensor == "gyro":
        sens, off = np.array([1000.0, 1000.0, 1000.0]), np.array([120.0, -80.0, 40.0])   # mdps
        slope, curv, s1 = np.array([3.0, -2.0, 1.5]), np.array([0.02, -0.01, 0.015]), 2e-4
    else:
        sens, off = np.array([1000.0, 1000.0, 1000.0]), np.array([15.0, -20.0, 30.0])    # mg
        slope, curv, s1 = np.array([0.3, -0.2, 0.25]), np.array([0.002, -0.001, 0.0015]), 1e-4
    out = np.empty((n, 3))
    for a in range(3):
        out[:, a] = off[a] + slope[a] * dT + curv[a] * dT ** 2 + sens[a] * (1 + s1 * dT) * ref[:, a]
    if effect is not None:
        out[:, effect_axis] += effect(t, T, ref, acc)
    out += noise(noise_kind, sigma, n, seed, walk)
    if shift is not None:
        out += np.asarray(shift, float)
    rng = np.random.default_rng(seed + 404)
    if spikes:
        rows = rng.choice(np.arange(1, n - 1), spikes, replace=False)
        out[rows, rng.integers(0, 3, spikes)] += rng.choice([-1, 1], spikes) * 60 * sigma
    if q:
        out = np.round(out / q) * q
    unit = unit or ("mdps" if sensor == "gyro" else "mg")
    meta = {"sensor": sensor, "out_unit": unit, "ref_unit": "dps" if sensor == "gyro" else "g"}
    kw = dict(extra_cols or {})
    return Log(name, t, T, out, ref, meta, acc=acc if sensor == "gyro" else None, **kw)


def humidity(t):
    """An out-of-catalogue driver: relative humidity soaking in and out over hours, unrelated to
    the temperature programme and absent from the log's columns."""
    return 40 + 25 * np.tanh((t - 0.35 * t[-1]) / (0.05 * t[-1])) - 20 * np.tanh((t - 0.75 * t[-1]) / (0.04 * t[-1]))
