"""Blind-benchmark generator for the sim-to-real gap tool (tools/simgap).

Written apart from the diagnosis on purpose, and sharing no code with it: it simulates a gyro
with the app-note model (offset quadratic, sensitivity linear in temperature) and adds the
catalogue's effects in shapes the tool's families do NOT contain:
  - temp_rate: a physical two-node thermal network (the MEMS structure lags the temperature
    sensor through two RC stages), offset evaluated at the lagged temperature;
  - hysteresis: a Duhem-type exponential relaxation toward +/-H as temperature moves;
  - drift: settling as a sum of two exponentials after each power-on;
  - offset_temperature: a Gaussian band plus a cubic; sensitivity_temperature: a cosh bowl;
  - nonlinearity: tanh compression plus an even term; cross_axis: a small rotation;
  - g_sensitivity: a full 3x3 g-matrix; supply: linear+quadratic offset and ratiometric gain;
  - turn_on_bias: a random offset per power-on; temp_quantization: a 1 degC reading.
Every log carries all optional columns, so the tool always has every effect to choose from.

`python -m tools.gapbench.gen OUTDIR [--seed N]` writes one case per effect, the pairs, the no-effect
cases and outlier cases, with the labels in OUTDIR/labels.json, which the tool never reads.
"""
import argparse
import json
import os

import numpy as np

EFFECT_NAMES = ("offset_temperature", "sensitivity_temperature", "hysteresis", "temp_rate",
                "cross_axis", "nonlinearity", "g_sensitivity", "supply", "drift",
                "turn_on_bias", "temp_quantization")
PAIRS = (("hysteresis", "temp_rate"), ("offset_temperature", "drift"),
         ("cross_axis", "g_sensitivity"), ("nonlinearity", "sensitivity_temperature"),
         ("supply", "turn_on_bias"), ("temp_quantization", "hysteresis"),
         ("drift", "turn_on_bias"), ("cross_axis", "nonlinearity"),
         ("offset_temperature", "sensitivity_temperature"), ("temp_rate", "supply"))
PAIRS_SMALL = (("hysteresis", "temp_rate"), ("cross_axis", "g_sensitivity"),
               ("drift", "turn_on_bias"))

DT = 1.5              # s between samples
NOISE = 3.0           # LSB white noise per axis (before rounding to whole LSB)
SENS = 16.4           # LSB per dps (a +/-2000 dps MEMS gyro)
FULL_SCALE = 150.0    # dps, the largest rate the table applies


def chamber_program(rng, n, kind):
    """Chamber air temperature: soaks and ramps at two rates, a few cycles. The train and
    withheld programmes differ in targets and rates so the withheld log is not a replay."""
    if kind == "train":
        legs = [(25.3, 0, 8), (60.4, 2.0, 10), (-9.7, 4.0, 12), (40.2, 2.0, 8), (5.6, 1.0, 10),
                (55.1, 4.0, 10), (15.8, 2.0, 10)]
    else:
        legs = [(20.7, 0, 6), (-4.6, 3.0, 10), (50.3, 1.5, 10), (10.4, 3.0, 8), (45.9, 3.0, 8)]
    t_end = n * DT
    ts, vs = [0.0], [legs[0][0]]
    t = legs[0][2] * 60.0
    ts.append(t)
    vs.append(legs[0][0])
    for target, rate, soak in legs[1:] * 3:
        t += abs(target - vs[-1]) / rate * 60.0
        ts.append(t)
        vs.append(target)
        t += soak * 60.0
        ts.append(t)
        vs.append(target)
        if t > t_end:
            break
    tt = np.arange(n) * DT
    return tt, np.interp(tt, ts, vs)


def rc(x, tau):
    """Physical first-order RC node driven by x (explicit exact step)."""
    a = 1.0 - np.exp(-DT / tau)
    y = np.empty_like(x)
    v = x[0]
    for i, xi in enumerate(x):
        v += a * (xi - v)
        y[i] = v
    return y


def piecewise(rng, n, levels, hold_s):
    """Random piecewise-constant signal: each level is held hold_s[0]..hold_s[1] seconds."""
    out = np.empty(n)
    i = 0
    while i < n:
        k = int(rng.uniform(*hold_s) / DT)
        out[i:i + k] = rng.choice(levels)
        i += k
    return out


def duhem(T, H, Tc):
    """Hysteresis state relaxing exponentially (in temperature travelled) toward +H while
    heating and -H while cooling; frozen when temperature stands still."""
    h = np.zeros_like(T)
    v = 0.0
    for i in range(1, len(T)):
        d = T[i] - T[i - 1]
        if d:
            v += (np.sign(d) * H - v) * (1.0 - np.exp(-abs(d) / Tc))
        h[i] = v
    return h


def make_log(rng, params, effects, n, kind, runs, outliers):
    tt, chamber = chamber_program(rng, n, kind)
    T_part = rc(chamber, 60.0)                            # package follows the air
    T_mems = rc(rc(T_part, 50.0), 120.0) if "temp_rate" in effects else T_part
    reading = T_part + rng.normal(0, 0.02, n)
    step = 1.0 if "temp_quantization" in effects else 1 / 256
    reading = np.round(reading / step) * step
    rate_levels = [-150, -75, -25, 0, 0, 0, 25, 75, 150]
    ref = np.column_stack([piecewise(rng, n, rate_levels, (20, 60)) for _ in range(3)])
    faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    face_idx = piecewise(rng, n, list(range(6)), (200, 400)).astype(int)
    acc = faces[face_idx]
    supply = piecewise(rng, n, [3.0, 3.15, 3.3, 3.45, 3.6], (120, 300)) + rng.normal(0, 0.002, n)
    run = np.repeat(np.arange(runs), int(np.ceil(n / runs)))[:n]
    ton = tt - tt[np.searchsorted(run, run)]
    dT = T_mems - 25.0
    out = np.zeros((n, 3))
    rin = ref.copy()
    if "cross_axis" in effects:
        rin = ref @ params["rotation"].T
    for a in range(3):
        o0, o1, o2 = params["offset"][a]
        s0, s1 = params["sens"][a]
        offset = o0 + o1 * dT + o2 * dT ** 2
        sens = s0 * (1 + s1 * (T_mems - 25.0))
        x = rin[:, a]
        if "nonlinearity" in effects:
            b, c = params["nl"][a]
            x = x + b * (FULL_SCALE * np.tanh(x / FULL_SCALE) - x) + c * x * np.abs(x) / FULL_SCALE
        if "offset_temperature" in effects:
            A, Tb, w, c3 = params["band"][a]
            offset = offset + A * np.exp(-((T_mems - Tb) / w) ** 2) + c3 * dT ** 3
        if "sensitivity_temperature" in effects:
            sens = sens * (1 + params["bowl"][a] * (np.cosh((T_mems - 25.0) / 22.0) - 1))
        if "hysteresis" in effects:
            offset = offset + duhem(T_mems, params["hyst"][a], 6.0)
        if "g_sensitivity" in effects:
            offset = offset + acc @ params["gmat"][a]
        if "supply" in effects:
            k1, k2, kr = params["supply"][a]
            v = supply - 3.3
            offset = offset + k1 * v + k2 * v ** 2
            sens = sens * (1 + kr * v)
        if "drift" in effects:
            A1, t1, A2, t2 = params["drift"][a]
            offset = offset + A1 * np.exp(-ton / t1) + A2 * np.exp(-ton / t2)
        if "turn_on_bias" in effects:
            offset = offset + rng.normal(0, params["tob"][a], runs)[run]
        out[:, a] = offset + sens * x
    out += rng.normal(0, NOISE, (n, 3))
    if outliers:
        k = max(3, n // 200)
        rows = rng.choice(np.arange(1, n), k, replace=False)
        axes = rng.integers(0, 3, k)
        out[rows, axes] += rng.choice([-1, 1], k) * rng.uniform(30, 100, k) * NOISE
    out = np.round(out)
    cols = {"time_s": tt, "temp_c": reading, "out_x": out[:, 0], "out_y": out[:, 1],
            "out_z": out[:, 2], "ref_x": ref[:, 0], "ref_y": ref[:, 1], "ref_z": ref[:, 2],
            "supply_v": supply, "acc_x": acc[:, 0], "acc_y": acc[:, 1], "acc_z": acc[:, 2],
            "chamber_c": chamber, "run": run}
    return cols


def draw_params(rng):
    def sgn():
        return rng.choice([-1.0, 1.0])

    p = {
        "offset": [(rng.uniform(-200, 200), sgn() * rng.uniform(3, 8), sgn() * rng.uniform(0.01, 0.03))
                   for _ in range(3)],
        "sens": [(SENS * rng.uniform(0.98, 1.02), sgn() * rng.uniform(1e-4, 3e-4)) for _ in range(3)],
        "band": [(sgn() * rng.uniform(20, 30), rng.uniform(10, 40), rng.uniform(4, 7),
                  sgn() * rng.uniform(3e-4, 6e-4)) for _ in range(3)],
        "bowl": [sgn() * rng.uniform(0.006, 0.01) for _ in range(3)],
        "hyst": [sgn() * rng.uniform(10, 18) for _ in range(3)],
        "gmat": [rng.uniform(10, 25, 3) * rng.choice([-1, 1], 3) for _ in range(3)],
        "supply": [(sgn() * rng.uniform(50, 70), sgn() * rng.uniform(60, 100), sgn() * rng.uniform(0.01, 0.02))
                   for _ in range(3)],
        "drift": [(sgn() * rng.uniform(25, 40), rng.uniform(100, 200), sgn() * rng.uniform(12, 20),
                   rng.uniform(700, 1200)) for _ in range(3)],
        "tob": [rng.uniform(15, 25) for _ in range(3)],
        "nl": [(rng.uniform(0.04, 0.06), sgn() * rng.uniform(0.003, 0.006)) for _ in range(3)],
    }
    ang = np.radians(rng.uniform(0.4, 0.8, 3) * rng.choice([-1, 1], 3))
    # Small rotation (misaligned sense axes), exact rather than its linearisation.
    ax, ay, az = ang
    Rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    Ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    Rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    p["rotation"] = Rz @ Ry @ Rx
    return p


def make_case(effects, seed, n_train=6000, n_withheld=4000, outliers=False):
    """Training and withheld column dicts for one labelled case."""
    rng = np.random.default_rng(seed)
    params = draw_params(rng)
    train = make_log(rng, params, set(effects), n_train, "train", 3, outliers)
    withheld = make_log(rng, params, set(effects), n_withheld, "withheld", 2, outliers)
    return train, withheld


def cases(full=True):
    """(case id, effects, outliers) in the benchmark; full=False is the reduced test set."""
    out = [(f"single-{e}", (e,), False) for e in EFFECT_NAMES]
    for a, b in (PAIRS if full else PAIRS_SMALL):
        out.append((f"pair-{a}+{b}", (a, b), False))
    for k in range(3 if full else 2):
        out.append((f"none-{k}", (), False))
    out.append(("none-outliers", (), True))
    if full:
        out.append(("outliers-hysteresis", ("hysteresis",), True))
        out.append(("outliers-drift", ("drift",), True))
    return out


def write_csv(path, cols, meta):
    names = list(cols)
    arr = np.column_stack([np.asarray(cols[c], float) for c in names])
    with open(path, "w") as f:
        for k, v in meta.items():
            f.write(f"# {k}: {v}\n")
        f.write(",".join(names) + "\n")
        for row in arr:
            f.write(",".join(f"{v:.10g}" for v in row) + "\n")


META = {"sensor": "gyro", "ref_unit": "dps", "out_unit": "LSB"}
TRUE_FLOOR = float(np.sqrt(NOISE ** 2 + 1 / 12))  # white noise plus rounding to whole LSB


def write_benchmark(outdir, seed=1, full=True):
    """Write every case's two logs (named by an opaque index) and labels.json beside them."""
    os.makedirs(outdir, exist_ok=True)
    labels = []
    for i, (cid, effects, outl) in enumerate(cases(full)):
        train, withheld = make_case(effects, seed * 1000 + i, outliers=outl)
        tp = os.path.join(outdir, f"case{i:02d}_train.csv")
        wp = os.path.join(outdir, f"case{i:02d}_withheld.csv")
        write_csv(tp, train, META)
        write_csv(wp, withheld, META)
        labels.append({"case": cid, "train": tp, "withheld": wp, "effects": list(effects),
                       "outliers": outl, "true_noise": TRUE_FLOOR})
    with open(os.path.join(outdir, "labels.json"), "w") as f:
        json.dump(labels, f, indent=1)
    return labels


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m tools.gapbench.gen")
    ap.add_argument("outdir")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--small", action="store_true", help="the reduced set the tests use")
    a = ap.parse_args(argv)
    labels = write_benchmark(a.outdir, a.seed, not a.small)
    print(f"wrote {len(labels)} cases to {a.outdir}")


if __name__ == "__main__":
    main()
