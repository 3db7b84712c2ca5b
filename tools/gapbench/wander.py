"""A second blind-log generator for the gap diagnosis, written from sensor physics and the public
CSV schema (docs/simgap.md) only: it shares no code with tools/simgap nor with gen.py, and imports
nothing from tools (host_tests/test_layout.py).

Each case is a training log and a withheld log of a stationary (optionally turntable-driven) MEMS
gyro in a temperature chamber, each from its own power-on, with the gyro's noise as IEEE Std 952 /
1293 characterise it - white rate noise, a bias instability (a first-order Gauss-Markov bias), a
rate random walk - and whole-LSB output, plus at most one planted effect in physical form:

  lag_rw        the MEMS structure lags the logged (ASIC) temperature: the offset law is evaluated
                at T_die = first-order lag of the logged temperature (temp_rate), random walk on
                every axis
  hyst_rw       a branch-dependent offset relaxing exponentially with the temperature travelled
                (Duhem-type hysteresis), random walk on every axis
  lag_heavy     a thermal-gradient bias: weight on (T - T_die) 3-8x the offset's static slope
                (temp_rate), no random walk
  aging         a linear drift with time since power-on (drift), no random walk
  rw_drift      an exponential warm-up settling after power-on (drift) under a random walk
  rw_alone      a random walk and nothing else: no verdict expected
  off_catalogue a humidity-like first-order step response of the offset at an unlogged time (no
                column for its cause) under a random walk: no verdict expected
  white         control: white noise and quantisation only, no effect

Truth per case (``truth``): the planted effects per axis in the catalogue's names, whether a
verdict is expected, every drawn parameter, and the oracle floor per axis: the RMS a perfect
model would leave on the withheld log - the exact noise realisation there (white + Gauss-Markov +
random walk + quantisation error) minus its mean (the diagnosis may remove one constant for a
withheld log from its own power-on; a perfect model can do no better than the mean).

Units: output in LSB (a ``# out_unit: LSB`` log), rates in dps, time in s, temperatures in degC.
The ranges below are stated with why; everything else is drawn inside them per log.
"""
import json
import os

import numpy as np
from scipy import signal

AXES = ("x", "y", "z")
T0 = 25.0  # the sim's reference temperature (docs/simgap.md)

# --- ranges (dps, s, degC), each with its reason ----------------------------------------------
# Full-scale choices of an MPU-6050/6500 class gyro: 131, 65.5, 32.8 LSB/dps (+-250/500/1000 dps).
SCALES = (131.0, 65.5, 32.8)
# Rate noise density 0.004-0.010 dps/sqrt(Hz) (datasheets: ICM-20602 0.004, MPU-6050 0.005,
# BMI160 0.007, MPU-9250 0.01) behind a 5-10 Hz digital low-pass: one decimated sample per row has
# sigma = density * sqrt(1.57 * bandwidth) (equivalent noise bandwidth of the filter) = 0.011-0.040 dps.
NOISE_DENSITY = (0.004, 0.010)
BANDWIDTH_HZ = (5.0, 10.0)
# Bias instability: Allan-deviation floors of consumer MEMS gyros are 0.001-0.003 dps (a measured
# MPU-6050: 0.0012 dps); a first-order Gauss-Markov bias of sigma s and correlation time tc has its
# Allan peak about 0.62 s near 1.9 tc, so s = 0.002-0.005 dps, tc = 100-600 s.
GM_SIGMA = (0.002, 0.005)
GM_TAU = (100.0, 600.0)
# Rate random walk K (Allan deviation K sqrt(tau/3) on its +1/2 slope): 1e-4 to 4e-4 dps/sqrt(s)
# (about 20-90 deg/h/sqrt(h)), which consumer MEMS gyros show on their Allan plots beyond
# 10^3 s. Over a 4-h log (sqrt(14400) = 120) that is 0.012-0.048 dps standard deviation: about the
# white noise of one sample - a "modest" random walk, the normal state of such a part over hours.
RRW = (1e-4, 4e-4)
# Offset law: zero-rate offset up to 3 dps (datasheets allow +-20), slope 0.005-0.05 dps/degC,
# a small curvature; sensitivity tolerance +-3 %, its temperature coefficient up to 0.04 %/degC.
O0 = 3.0
O1 = (0.005, 0.05)
O2 = 2e-4
S_TOL = 0.03
S_TC = 4e-4
# Temperature reading: MPU-6050 scale 1/340 degC per LSB, reading noise 0.01 degC; the package
# lags the chamber by 60-240 s and self-heats 1-4 degC.
T_LSB = 1.0 / 340.0
T_NOISE = 0.01
PKG_TAU = (60.0, 240.0)
SELF_HEAT = (1.0, 4.0)
# Planted effects.
LAG_TAU = (30.0, 180.0)           # MEMS structure vs the ASIC sensor in one mould: 0.5-3 min
LAG_SLOPE = (0.02, 0.06)          # lag_rw: the static slope the lag delays, dps/degC
HEAVY_SLOPE = (0.005, 0.02)       # lag_heavy: a small static slope ...
HEAVY_RATIO = (3.0, 8.0)          # ... and a gradient weight 3-8x it (no physics bounds the ratio)
HYST_H = (0.04, 0.15)             # half the branch gap, dps (package stress, solder creep)
HYST_W = (2.0, 8.0)               # degC of travel to relax 63 % of the way to a branch
DRIFT_SLOPE = (0.03, 0.12)        # linear drift since power-on, dps per hour
WARMUP_A = (0.1, 0.8)             # warm-up settling after power-on, dps ...
WARMUP_TAU = (300.0, 1800.0)      # ... over 5-30 minutes
HUMID_A = (0.03, 0.12)            # humidity step response of the offset, dps ...
HUMID_TAU = (900.0, 3600.0)       # ... moisture diffuses into the package over 15-60 min
# An effect a calibration must care about: what the sim's own terms cannot absorb of it is at
# least MIN_EFFECT white sigmas in RMS over the training log (else parameters are redrawn).
MIN_EFFECT = 2.0
ROW_S = 3.0  # seconds per row (one decimated sample)

SITUATIONS = ("rw_alone", "off_catalogue", "lag_rw", "hyst_rw", "lag_heavy", "aging", "rw_drift", "white")
# situation: (catalogue effect planted or None, random walk, Gauss-Markov, effect in the catalogue)
_PLAN = {
    "rw_alone": (None, True, True, True),
    "off_catalogue": (None, True, True, False),
    "lag_rw": ("temp_rate", True, True, True),
    "hyst_rw": ("hysteresis", True, True, True),
    "lag_heavy": ("temp_rate", False, True, True),
    "aging": ("drift", False, True, True),
    "rw_drift": ("drift", True, True, True),
    "white": (None, False, False, True),
}


def _u(rng, lo_hi):
    return float(rng.uniform(*lo_hi))


def _logu(rng, lo_hi):
    return float(np.exp(rng.uniform(np.log(lo_hi[0]), np.log(lo_hi[1]))))


def _sign(rng):
    return 1.0 if rng.random() < 0.5 else -1.0


# --- physics ------------------------------------------------------------------------------------

def first_order_lag(u, dt, tau):
    """Output of tau dy/dt = u - y for u linear between samples (exact first-order hold), starting
    at equilibrium y[0] = u[0]: y[k] = a y[k-1] + b0 u[k] + b1 u[k-1], a = exp(-dt/tau)."""
    a = np.exp(-dt / tau)
    b0 = 1.0 - tau * (1.0 - a) / dt
    b1 = (1.0 - a) - b0
    zi = np.array([u[0] * (1.0 - b0)])  # y[-1] = u[-1] = u[0]: a*u0 + b1*u0 carried in
    y, _ = signal.lfilter([b0, b1], [1.0, -a], u, zi=zi)
    return y


def duhem(temp, h, w):
    """Rate-independent relaxation hysteresis: on each temperature step dT the state moves towards
    +h (heating) or -h (cooling) by the fraction 1 - exp(-|dT|/w) of the way; starts at 0."""
    z = np.zeros_like(temp)
    d = np.diff(temp)
    frac = 1.0 - np.exp(-np.abs(d) / w)
    target = np.sign(d) * h
    s = 0.0
    for i in range(len(d)):
        s += (target[i] - s) * frac[i]
        z[i + 1] = s
    return z


def chamber(rng, legs, t_start, dt):
    """Piecewise-linear chamber programme: start soak, then (target, rate degC/min, soak s) legs."""
    pts_t, pts_c = [0.0], [t_start]
    soak0 = rng.uniform(600, 1200)
    pts_t.append(soak0)
    pts_c.append(t_start)
    for target, rate, soak in legs:
        ramp = abs(target - pts_c[-1]) / (rate / 60.0)
        pts_t.append(pts_t[-1] + ramp)
        pts_c.append(target)
        pts_t.append(pts_t[-1] + soak)
        pts_c.append(target)
    t = np.arange(0.0, pts_t[-1], dt)
    return t, np.interp(t, pts_t, pts_c)


def programmes(rng):
    """Training: two heating and two cooling ramps at a slow and a fast rate each, soaks reached
    from above and below, -20..75 degC. Withheld: one cycle 8-20 degC inside those extremes."""
    slow = lambda: rng.uniform(0.5, 1.0)  # noqa: E731
    fast = lambda: rng.uniform(1.5, 3.0)  # noqa: E731
    soak = lambda: rng.uniform(600, 1200)  # noqa: E731
    hi, lo = rng.uniform(55, 75), rng.uniform(-20, -5)
    hi2 = rng.uniform(hi - 15, hi - 3)
    train = ([(hi, slow(), soak()), (lo, fast(), soak()), (hi2, fast(), soak()),
              (rng.uniform(20, 30), slow(), soak())], rng.uniform(20, 30))
    held = ([(rng.uniform(hi - 20, hi - 8), rng.uniform(0.7, 2.5), soak()),
             (rng.uniform(lo + 8, lo + 20), rng.uniform(0.7, 2.5), soak()),
             (rng.uniform(20, 30), rng.uniform(0.7, 2.5), soak())], rng.uniform(20, 30))
    return train, held


def turntable(rng, n):
    """Rate-table steps (dps) held 2-5 min, levels up to the smallest full scale's 200 dps."""
    levels = np.array([0.0, 20.0, -20.0, 60.0, -60.0, 150.0, -150.0])
    out = np.zeros(n)
    i = 0
    while i < n:
        hold = int(rng.uniform(120, 300) / ROW_S)
        out[i:i + hold] = rng.choice(levels)
        i += hold
    return out


def noise_parts(rng, n, sig_w, gm, rrw):
    """White, Gauss-Markov and random-walk parts (dps) of one axis for one power-on."""
    white = sig_w * rng.standard_normal(n)
    if gm:
        s, tc = gm
        phi = np.exp(-ROW_S / tc)
        e = s * np.sqrt(1.0 - phi * phi) * rng.standard_normal(n)
        e[0] = s * rng.standard_normal()  # stationary start
        gmk = signal.lfilter([1.0], [1.0, -phi], e)
    else:
        gmk = np.zeros(n)
    if rrw:
        # the bias at power-on is the trimmed one; it wanders from there
        rw = np.concatenate([[0.0], np.cumsum(rrw * np.sqrt(ROW_S) * rng.standard_normal(n - 1))])
    else:
        rw = np.zeros(n)
    return {"white": white, "gm": gmk, "rw": rw}


def _sim_basis(temp, ref):
    d = temp - T0
    return np.column_stack([np.ones_like(d), d, d * d, ref, ref * d])


def unabsorbed_rms(effect, temp, ref):
    """RMS of what the sim's own terms cannot fit of an effect signal."""
    A = _sim_basis(temp, ref)
    coef, *_ = np.linalg.lstsq(A, effect, rcond=None)
    return float(np.sqrt(np.mean((effect - A @ coef) ** 2)))


def draw_effect(kind, rng):
    """Parameters of one planted effect, inside the ranges above."""
    if kind == "temp_rate_lag":
        return {"tau_s": _u(rng, LAG_TAU)}
    if kind == "temp_rate_heavy":
        return {"tau_s": _u(rng, LAG_TAU), "ratio": _u(rng, HEAVY_RATIO), "sign": _sign(rng)}
    if kind == "hysteresis":
        return {"h_dps": _u(rng, HYST_H), "w_c": _u(rng, HYST_W), "sign": _sign(rng)}
    if kind == "drift_linear":
        return {"slope_dps_per_h": _sign(rng) * _u(rng, DRIFT_SLOPE)}
    if kind == "drift_warmup":
        return {"amplitude_dps": _sign(rng) * _u(rng, WARMUP_A), "tau_s": _u(rng, WARMUP_TAU)}
    if kind == "humidity":
        return {"amplitude_dps": _sign(rng) * _u(rng, HUMID_A), "tau_s": _u(rng, HUMID_TAU)}
    raise ValueError(kind)


def effect_signal(kind, p, log, offset):
    """The effect's contribution (dps) over one log, from the part's true temperature; ``offset``
    is the axis' static offset law (dps) for the lag, which delays it."""
    t, temp = log["t"], log["temp_true"]
    if kind == "temp_rate_lag":
        # the offset law holds at the lagging structure's temperature: f(T_die) - f(T)
        die = first_order_lag(temp, ROW_S, p["tau_s"])
        return offset(die) - offset(temp)
    if kind == "temp_rate_heavy":
        # a thermal-gradient bias proportional to T - T_die (weight = ratio x the static slope)
        die = first_order_lag(temp, ROW_S, p["tau_s"])
        return p["weight_dps_per_c"] * (temp - die)
    if kind == "hysteresis":
        return p["sign"] * duhem(temp, p["h_dps"], p["w_c"])
    if kind == "drift_linear":
        return p["slope_dps_per_h"] * t / 3600.0
    if kind == "drift_warmup":
        return p["amplitude_dps"] * np.exp(-t / p["tau_s"])
    if kind == "humidity":
        # the unlogged cause steps at its own time in each log
        rise = 1.0 - np.exp(-np.clip(t - log["humid_step_s"], 0.0, None) / p["tau_s"])
        return p["amplitude_dps"] * rise
    raise ValueError(kind)


# --- one case -----------------------------------------------------------------------------------

def _log(rng, prog, table_axis):
    legs, t_start = prog
    t, ch = chamber(rng, legs, t_start, ROW_S)
    return {"t": t, "chamber": ch, "table_axis": table_axis}


def make_case(situation, seed, index=0, reading_lsb=None):
    """One labelled case: {"train": log, "withheld": log, "truth": {...}} (logs as arrays).
    reading_lsb: the temperature reading's step in degC (default T_LSB, an MPU-6050's; 1.0 a
    whole-degree reading, as a temperature register that counts whole degrees gives). Every
    random draw is the same for any step, so a coarse case is the fine case read coarsely."""
    if situation not in _PLAN:
        raise ValueError("unknown situation %r (one of %s)" % (situation, ", ".join(SITUATIONS)))
    effect, has_rw, has_gm, in_cat = _PLAN[situation]
    rng = np.random.default_rng([int(seed), SITUATIONS.index(situation), int(index)])
    scale = float(rng.choice(SCALES))
    pkg_tau, heat = _u(rng, PKG_TAU), _u(rng, SELF_HEAT)
    table_axis = AXES[rng.integers(3)] if rng.random() < 0.5 else None
    prog_train, prog_held = programmes(rng)
    logs = {"train": _log(rng, prog_train, table_axis), "withheld": _log(rng, prog_held, table_axis)}
    for lg in logs.values():
        n = len(lg["t"])
        # the part's own temperature, read by its sensor (the logged column)
        lg["temp_true"] = first_order_lag(lg["chamber"], ROW_S, pkg_tau) + heat
        step = T_LSB if reading_lsb is None else float(reading_lsb)
        lg["temp_c"] = np.round((lg["temp_true"] + T_NOISE * rng.standard_normal(n)) / step) * step
        lg["ref"] = {a: (turntable(rng, n) if a == table_axis else np.zeros(n)) for a in AXES}
        lg["humid_step_s"] = lg["t"][-1] * rng.uniform(0.2, 0.6)
    lo_tr, hi_tr = logs["train"]["temp_c"].min(), logs["train"]["temp_c"].max()
    lo_w, hi_w = logs["withheld"]["temp_c"].min(), logs["withheld"]["temp_c"].max()
    assert lo_tr + 3 < lo_w and hi_w < hi_tr - 3, "withheld programme outside training"

    effect_axes = []
    if effect is not None:
        k = 1 if effect in ("temp_rate", "hysteresis") else int(rng.integers(1, 4))
        effect_axes = sorted(rng.choice(AXES, size=k, replace=False).tolist())
    humid_axes = AXES if situation == "off_catalogue" else ()

    truth = {"situation": situation, "seed": int(seed), "index": int(index), "scale_lsb_per_dps": scale,
             "row_s": ROW_S, "package_tau_s": pkg_tau, "self_heat_c": heat, "table_axis": table_axis,
             "effects": {a: ([effect] if a in effect_axes else []) for a in AXES},
             "verdict_expected": [effect] if effect else [],
             # off-catalogue and pure-noise logs: nothing in the catalogue is there to be named
             "no_verdict_expected": effect is None,
             "off_catalogue_effects": {a: (["humidity_step"] if a in humid_axes else []) for a in AXES},
             "in_catalogue": in_cat, "axes": {}}
    truth["reading_lsb_c"] = T_LSB if reading_lsb is None else float(reading_lsb)
    truth["rows"] = {k: len(v["t"]) for k, v in logs.items()}
    truth["temp_range_c"] = {k: [float(v["temp_c"].min()), float(v["temp_c"].max())] for k, v in logs.items()}
    for a in AXES:
        ax = {}
        ax["white_dps"] = _u(rng, NOISE_DENSITY) * np.sqrt(1.57 * _u(rng, BANDWIDTH_HZ))
        ax["gm"] = [_u(rng, GM_SIGMA), _u(rng, GM_TAU)] if has_gm else None
        ax["rrw_dps_per_sqrt_s"] = _logu(rng, RRW) if has_rw else 0.0
        slope_range = O1
        if a in effect_axes and effect == "temp_rate":
            slope_range = LAG_SLOPE if situation == "lag_rw" else HEAVY_SLOPE
        ax["offset_dps"] = [_u(rng, (-O0, O0)), _sign(rng) * _u(rng, slope_range), _u(rng, (-O2, O2))]
        s0 = scale * (1.0 + _u(rng, (-S_TOL, S_TOL)))
        ax["sensitivity_lsb_per_dps"] = [s0, s0 * _u(rng, (-S_TC, S_TC))]
        kind = None
        if a in effect_axes:
            kind = {"lag_rw": "temp_rate_lag", "lag_heavy": "temp_rate_heavy", "hyst_rw": "hysteresis",
                    "aging": "drift_linear", "rw_drift": "drift_warmup"}[situation]
        elif a in humid_axes:
            kind = "humidity"
        _plant(rng, a, ax, kind, logs, scale, slope_range)
        truth["axes"][a] = ax
    truth["oracle_floor_lsb"] = {a: truth["axes"][a]["oracle_floor_lsb"]["withheld"] for a in AXES}
    return {"train": logs["train"], "withheld": logs["withheld"], "truth": truth}


def _offset(ax, temp):
    o0, o1, o2 = ax["offset_dps"]
    d = temp - T0
    return o0 + o1 * d + o2 * d * d


def _plant(rng, a, ax, kind, logs, scale, slope_range):
    """Draw this axis' effect (redrawn until it is one a calibration must care about) and noise;
    write out_<a> (LSB) with its clean signal, effect and noise parts into each log. A lag's size
    is the static slope it delays times the temperature's lag: when no time constant reaches
    MIN_EFFECT with the slope drawn (a slow programme, a noisy part), the slope is redrawn with it
    (only then, so every case that drew one in the first 200 tries stays the same)."""
    def offset(temp):
        return _offset(ax, temp)

    sig = {name: np.zeros(len(lg["t"])) for name, lg in logs.items()}
    p = None
    if kind is not None:
        tr = logs["train"]
        for i in range(400):
            if i >= 200 and kind in ("temp_rate_lag", "temp_rate_heavy"):
                ax["offset_dps"][1] = _sign(rng) * _u(rng, slope_range)
            p = draw_effect(kind, rng)
            if kind == "temp_rate_heavy":
                p["weight_dps_per_c"] = p["sign"] * p["ratio"] * abs(ax["offset_dps"][1])
            sig = {name: effect_signal(kind, p, lg, offset) for name, lg in logs.items()}
            if kind == "humidity" or unabsorbed_rms(sig["train"], tr["temp_c"], tr["ref"][a]) \
                    >= MIN_EFFECT * ax["white_dps"]:
                break
        else:
            raise RuntimeError("no %s inside the stated ranges reaches %g white sigmas on this log"
                               % (kind, MIN_EFFECT))
        if kind == "humidity":
            p["step_s"] = {name: float(lg["humid_step_s"]) for name, lg in logs.items()}
    ax["effect"] = None if kind is None else dict(kind=kind, **p)
    ax["oracle_floor_lsb"] = {}
    for name, lg in logs.items():
        temp = lg["temp_true"]
        s0, s1 = ax["sensitivity_lsb_per_dps"]
        clean = scale * (offset(temp) + sig[name]) + (s0 + s1 * (temp - T0)) * lg["ref"][a]
        parts = noise_parts(rng, len(temp), ax["white_dps"], ax["gm"], ax["rrw_dps_per_sqrt_s"])
        noisy = clean + scale * (parts["white"] + parts["gm"] + parts["rw"])
        out = np.rint(noisy)
        lg.setdefault("out", {})[a] = out
        lg.setdefault("clean", {})[a] = clean
        lg.setdefault("effect", {})[a] = scale * sig[name]
        lg.setdefault("noise", {})[a] = {k: scale * v for k, v in parts.items()}
        lg["noise"][a]["quantisation"] = out - noisy
        e = out - clean  # the realisation a perfect model leaves, less the constant it may remove
        ax["oracle_floor_lsb"][name] = float(np.sqrt(np.mean((e - e.mean()) ** 2)))


# --- files --------------------------------------------------------------------------------------

def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return x


def write_log(path, log):
    """The diagnosis' CSV schema: metadata lines, then time_s,temp_c,out_*,ref_*."""
    cols = [log["t"], log["temp_c"]] + [log["out"][a] for a in AXES] + [log["ref"][a] for a in AXES]
    with open(path, "w") as f:
        f.write("# sensor: gyro\n# ref_unit: dps\n# out_unit: LSB\n")
        f.write("time_s,temp_c,out_x,out_y,out_z,ref_x,ref_y,ref_z\n")
        np.savetxt(f, np.column_stack(cols), fmt=["%.1f", "%.4f"] + ["%d"] * 3 + ["%g"] * 3, delimiter=",")


def write_case(case, outdir, name, truth_dir=None):
    """Write NAME_a.csv (training) and NAME_b.csv (withheld) in outdir and NAME.truth.json in
    truth_dir (default outdir); return the three paths."""
    truth_dir = truth_dir or outdir
    for d in (outdir, truth_dir):
        os.makedirs(d, exist_ok=True)
    paths = {"train": os.path.join(outdir, name + "_a.csv"), "withheld": os.path.join(outdir, name + "_b.csv"),
             "truth": os.path.join(truth_dir, name + ".truth.json")}
    write_log(paths["train"], case["train"])
    write_log(paths["withheld"], case["withheld"])
    with open(paths["truth"], "w") as f:
        json.dump(_jsonable(case["truth"]), f, indent=1)
    return paths
