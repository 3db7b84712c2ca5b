"""Chamber data of simulated accelerometers (numpy, host): truth and raw samples for tests/bench.

Each unit has, per axis a, offset(T) = off0 + tco1 dT + tco2 dT^2 (mg), scale(T) =
cpg (1 + sen_tol)(1 + tcs1 dT) counts per g, and a fixed cross-axis matrix
N = S + R (S symmetric off-diagonal cross-axis sensitivity, R a small rotation).
raw = round(offset*cpg/1000 + diag(scale) (I + N) g + noise), int16.
"""

import numpy as np

SIX = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)


def truth(units, rng, cross=0.01, rot=0.01):
    """Random per-unit true coefficients (dict of arrays, leading axis = unit)."""
    U = units
    S = rng.normal(0, cross, (U, 3, 3))
    S = np.triu(S, 1)
    S = S + np.swapaxes(S, 1, 2)
    w = rng.normal(0, rot, (U, 3))
    R = np.zeros((U, 3, 3))
    R[:, 2, 1], R[:, 1, 2] = w[:, 0], -w[:, 0]
    R[:, 0, 2], R[:, 2, 0] = w[:, 1], -w[:, 1]
    R[:, 1, 0], R[:, 0, 1] = w[:, 2], -w[:, 2]
    return {
        "off0": rng.normal(0, 40, (U, 3)),
        "tco1": rng.normal(0, 0.5, (U, 3)),
        "tco2": rng.normal(0, 0.002, (U, 3)),
        "sen_tol": rng.normal(0, 0.02, (U, 3)),
        "tcs1": rng.normal(0, 2e-4, (U, 3)),
        "N": S + R,
        "rot": w,
    }


def chamber(tr, temps, g_dirs, samples, cpg, rng, noise_counts=8.0, t_room=25.0, dtype=np.int16):
    """Raw samples (U, T, O, samples, 3) for truth ``tr`` at temps (T,) with orientations (O, 3)."""
    U = tr["off0"].shape[0]
    dT = np.asarray(temps, dtype=float) - t_room  # (T,)
    off = (tr["off0"][:, None, :] + tr["tco1"][:, None, :] * dT[None, :, None]
           + tr["tco2"][:, None, :] * dT[None, :, None] ** 2) * cpg / 1000.0  # (U,T,3) counts
    sc = cpg * (1 + tr["sen_tol"][:, None, :]) * (1 + tr["tcs1"][:, None, :] * dT[None, :, None])  # (U,T,3)
    M = sc[:, :, :, None] * (np.eye(3) + tr["N"])[:, None, :, :]  # (U,T,3,3)
    clean = off[:, :, None, :] + np.einsum("utaj,oj->utoa", M, g_dirs)  # (U,T,O,3)
    noise = rng.normal(0, noise_counts, (U, len(dT), len(g_dirs), samples, 3))
    return np.rint(clean[:, :, :, None, :] + noise).astype(dtype)
