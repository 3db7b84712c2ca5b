"""Small synthetic logs for the gap-tool unit tests, built here with plain numpy so the
expected answers come from how the data was made, not from the code under test. `make` has no
default seed: callers pass one of the run's (host_tests/helpers/seeds.py)."""
import numpy as np

from tools.simgap.logio import Log


def profile(n=3000, dt=2.0):
    """Two temperature cycles with soaks: heating and cooling both cover 0..50 degC."""
    t = np.arange(n) * dt
    knots_t = np.array([0, 0.08, 0.25, 0.33, 0.5, 0.58, 0.75, 0.83, 1.0]) * t[-1]
    knots_T = np.array([25, 25, 50, 50, 0, 0, 45, 45, 10.0])
    T = np.interp(t, knots_t, knots_T)
    return t, T


def make(effect=None, n=3000, sigma=2.0, *, seed, **kw):
    rng = np.random.default_rng(seed)
    t, T = profile(n)
    ref = np.zeros((n, 3))
    levels = np.array([-100, -40, 0, 40, 100.0])
    for a in range(3):
        ref[:, a] = np.repeat(rng.choice(levels, n // 50 + 1), 50)[:n]
    dT = T - 25
    out = np.column_stack([50 + 4 * dT - 0.02 * dT ** 2 + 16 * (1 + 1e-4 * dT) * ref[:, a]
                           for a in range(3)])
    extra = np.zeros(n) if effect is None else effect(t, T, ref)
    out[:, 0] += extra
    out += rng.normal(0, sigma, (n, 3))
    return Log("synthetic", t, T, out, ref, {"sensor": "gyro"}, **kw)


def play(T, w):
    """Reference play operator (backlash of width w) written plainly, independent of the tool."""
    v, out = T[0], []
    for x in T:
        v = min(max(v, x - w / 2), x + w / 2)
        out.append(v)
    return np.array(out)
