"""Chamber data of simulated accelerometers (numpy, host): truth and raw samples for tests/bench.

Each unit has, per axis a, offset(T) = off0 + tco1 dT + tco2 dT^2 (mg), scale(T) =
cpg (1 + sen_tol)(1 + tcs1 dT) counts per g, and a cross-axis matrix
N(T) = S + R + N1 dT (S symmetric off-diagonal cross-axis sensitivity, R a small rotation,
N1 the symmetric cross-axis drift per degC: 0 unless ``cross_tc`` is given; MEMS datasheets bound
the cross-axis sensitivity, +-2 % on the MPU-6050/6500, not its drift).
raw = round(offset*cpg/1000 + diag(scale) (I + N(T)) g + noise), int16.
"""

import numpy as np

SIX = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)


def truth(units, rng, cross=0.01, rot=0.01, cross_tc=0.0):
    """Random per-unit true coefficients (dict of arrays, leading axis = unit).

    cross_tc: standard deviation of the cross-axis drift N1 (per degC); 0 keeps N constant
    and draws nothing extra from rng, so existing seeds give the same units.
    """
    U = units
    S = rng.normal(0, cross, (U, 3, 3))
    S = np.triu(S, 1)
    S = S + np.swapaxes(S, 1, 2)
    w = rng.normal(0, rot, (U, 3))
    R = np.zeros((U, 3, 3))
    R[:, 2, 1], R[:, 1, 2] = w[:, 0], -w[:, 0]
    R[:, 0, 2], R[:, 2, 0] = w[:, 1], -w[:, 1]
    R[:, 1, 0], R[:, 0, 1] = w[:, 2], -w[:, 2]
    N1 = np.zeros((U, 3, 3))
    if cross_tc:
        D = np.triu(rng.normal(0, cross_tc, (U, 3, 3)), 1)
        N1 = D + np.swapaxes(D, 1, 2)
    return {
        "off0": rng.normal(0, 40, (U, 3)),
        "tco1": rng.normal(0, 0.5, (U, 3)),
        "tco2": rng.normal(0, 0.002, (U, 3)),
        "sen_tol": rng.normal(0, 0.02, (U, 3)),
        "tcs1": rng.normal(0, 2e-4, (U, 3)),
        "N": S + R,
        "rot": w,
        "N1": N1,
    }


def chamber(tr, temps, g_dirs, samples, cpg, rng, noise_counts=8.0, t_room=25.0, dtype=np.int16):
    """Raw samples (U, T, O, samples, 3) for truth ``tr`` at temps (T,) with orientations (O, 3)."""
    U = tr["off0"].shape[0]
    dT = np.asarray(temps, dtype=float) - t_room  # (T,)
    off = (tr["off0"][:, None, :] + tr["tco1"][:, None, :] * dT[None, :, None]
           + tr["tco2"][:, None, :] * dT[None, :, None] ** 2) * cpg / 1000.0  # (U,T,3) counts
    sc = cpg * (1 + tr["sen_tol"][:, None, :]) * (1 + tr["tcs1"][:, None, :] * dT[None, :, None])  # (U,T,3)
    N = tr["N"][:, None, :, :] + tr.get("N1", np.zeros_like(tr["N"]))[:, None, :, :] * dT[None, :, None, None]
    M = sc[:, :, :, None] * (np.eye(3) + N)  # (U,T,3,3)
    clean = off[:, :, None, :] + np.einsum("utaj,oj->utoa", M, g_dirs)  # (U,T,O,3)
    noise = rng.normal(0, noise_counts, (U, len(dT), len(g_dirs), samples, 3))
    return np.rint(clean[:, :, :, None, :] + noise).astype(dtype)


def fleet_files(out, units, rng, samples=20, cpg=16384.0, temps=(-40.0, 25.0, 85.0), one_csv=False,
                outliers=()):
    """Write a fleet of simulated six-position units: one CSV per unit in directory ``out``
    (unit-00000.csv...) or, with one_csv, one CSV with a ``unit`` column. Units listed in
    ``outliers`` get a 40x noisier chamber (a loose fixture). Returns the truth dict."""
    import os

    tr = truth(units, rng)
    labels = ["+x", "-x", "+y", "-y", "+z", "-z"]
    temps = np.asarray(temps, dtype=float)
    bad = set(outliers)
    chunk = 500
    if one_csv:
        f = open(out, "w")
        f.write("unit,temp_c,orient,ax,ay,az\n")
    else:
        os.makedirs(out, exist_ok=True)
    # the row prefix of each (temperature, orientation) block; samples follow as integers
    pre = ["%g,%s," % (t, lab) for t in temps for lab in labels]
    for start in range(0, units, chunk):
        n = min(chunk, units - start)
        sub = {k: v[start:start + n] for k, v in tr.items()}
        raw = chamber(sub, temps, SIX, samples, cpg, rng)
        for i in range(n):
            u = start + i
            r = raw[i]
            if u in bad:
                noisy = chamber({k: v[u:u + 1] for k, v in tr.items()}, temps, SIX, samples, cpg, rng,
                                noise_counts=320.0)
                r = noisy[0]
            r = r.reshape(len(pre), samples, 3)
            name = "unit-%05d" % u
            body = "".join(pre[b] + "%d,%d,%d\n" % tuple(s) for b in range(len(pre)) for s in r[b].tolist())
            if one_csv:
                f.write("".join(name + "," + line + "\n" for line in body.splitlines()))
            else:
                with open(os.path.join(out, name + ".csv"), "w") as g:
                    g.write("temp_c,orient,ax,ay,az\n" + body)
    if one_csv:
        f.close()
    return tr


def _main(argv=None):
    """Write a simulated chamber CSV (for trying the tools without a chamber)."""
    import argparse
    import csv
    import os
    import sys

    p = argparse.ArgumentParser(prog="python -m tools.fit.simulate", description=_main.__doc__)
    p.add_argument("kind", choices=["sixpos", "adxrs", "sixpos-fleet"])
    p.add_argument("out", help="CSV file to write (sixpos-fleet: a directory, one CSV per unit)")
    p.add_argument("--units", type=int, default=100, help="sixpos-fleet: how many units")
    p.add_argument("--one-csv", action="store_true", help="sixpos-fleet: one CSV with a unit column")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--counts-per-g", type=float, default=16384.0)
    p.add_argument("--samples", type=int, default=20)
    p.add_argument("--cross-tc", type=float, default=0.0,
                   help="sixpos: cross-axis drift, standard deviation per degC (e.g. 1e-4); default 0")
    p.add_argument("--temps", default="-40,25,85", help="chamber temperatures, degC, comma separated")
    a = p.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    temps = [float(t) for t in a.temps.split(",")]
    if a.kind == "sixpos-fleet":
        fleet_files(a.out, a.units, rng, a.samples, a.counts_per_g, temps, one_csv=a.one_csv)
        return 0
    with open(a.out, "w", newline="") as f:
        w = csv.writer(f)
        if a.kind == "sixpos":
            raw = chamber(truth(1, rng, cross_tc=a.cross_tc), temps, SIX, a.samples, a.counts_per_g, rng)
            labels = ["+x", "-x", "+y", "-y", "+z", "-z"]
            w.writerow(["temp_c", "orient", "ax", "ay", "az"])
            for k, t in enumerate(temps):
                for o, lab in enumerate(labels):
                    for s in raw[0, k, o]:
                        w.writerow([t, lab] + [int(v) for v in s])
        else:
            sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "lib"))
            from tools.sim.analog_gyro_sim import AnalogGyroSim

            sim = AnalogGyroSim(vref_mv=3300, divider=2.0, noise_mv=0.5, t_noise_mv=0.3, seed=a.seed)
            q = 3300.0 * 2.0 / 65535
            w.writerow(["temp_c", "vt_mv", "rate_dps", "out_mv"])
            for t in temps:
                sim.temp_c = t
                for r in (0.0, 200.0, -200.0):
                    sim.rate_dps = r
                    for _ in range(a.samples):
                        w.writerow([t, round(sim.temp.read_u16() * q, 2), r, round(sim.rate.read_u16() * q, 2)])
    return 0


if __name__ == "__main__":
    raise SystemExit(_main())
