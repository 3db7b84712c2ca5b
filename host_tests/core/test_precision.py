"""Precision of the fixed-point core against float64 over random and extreme legal coefficient
sets: the bound README states is the one asserted here, on CPython over 300 + 100 sets per seed
(seeds drawn per run, host_tests/helpers/seeds.py) and on every real interpreter over a subset
(the device's own set-up, its own integer path, integers equal to CPython's).

The bound is |error| <= 0.7 + |y| * 2**-24 output LSB, y the output, for every set the set-up
accepts. The flat part is the final rounding (0.5) and the core's truncations (a few units of
2**-S, S >= 5 fraction bits: up to 0.17 at S = 5, the largest gains); the relative part is the
scale's evaluation to about 27 bits, which only outputs near 2**23 (output units finer than a
30th of a raw LSB) make visible.
Measured over seeds 1..300 (random, 90,000 sets) and 1..500 (extreme, 50,000 sets): worst
|error| 0.773 and 1.084 LSB, at outputs of 1.3e7 and 1.6e7 LSB (seeds 102 and 173); worst
|error| - |y| * 2**-24 0.598 and 0.666 (seeds 265 and 445, both at S = 5). The flat bound
before, 0.55 on random sets and 0.75 on extreme ones, failed on 89 of 300 and 113 of 500 seeds.

Random sets: offset and scale polynomials of degree 0..3 over random temperature spans, a few %
of scale drift, offsets near the raw range's middle, output units 1/10/1000, four raw ranges,
both temperature policies. Extreme sets: the largest gain the set-up accepts (S at its floor of
5 fraction bits), the scale varying towards its 2x limit, offsets at 80..95 % of the raw
half-span. Coefficients are float32 values, so every interpreter (single-precision firmware too)
is given exactly the numbers the float64 reference uses (built on the device by exact doublings:
a single-precision decimal parser can land 1 ulp off)."""

import random
import re

import numpy as np
import pytest
import seeds

from tempcomp import fixedpoint as fp

# |error| <= FLAT + |y| * REL output LSB at every set, temperature and raw code tried (README)
FLAT = 0.7
REL = 2.0**-24
REFUSALS = ("output unit too fine", "varies more than", "outside the raw range", "must be positive")
RAW_RANGES = [(-32768, 32767), (0, 65535), (0, 4095), (-8192, 8191)]


def _f32(x):
    return float(np.float32(x))


def _mant_exp(x):
    # (m, e) with x == m * 2**e, |m| < 2**24 for a float32 value
    m, e = np.frexp(x)
    m, e = float(m), int(e)
    while m != int(m):
        m *= 2.0
        e -= 1
    assert abs(m) < 2**24 and m * 2.0**e == x
    return (int(m), e)


def make_set(rng, extreme):
    """One legal-looking set: (offset coeffs, scale coeffs, t_cal, out_scale, raw_range, policy, t_ref)."""
    rr = rng.choice(RAW_RANGES)
    lo, hi = rr
    mid = (lo + hi + 1) // 2
    half = (hi - lo) / 2
    t_lo = rng.randint(-20000, 20000)
    span = rng.randint(50, 30000)
    t_ref = t_lo + span // 2
    do, ds = rng.randint(0, 3), rng.randint(0, 3)
    out_scale = rng.choice([1.0, 10.0, 1000.0])
    if extreme:
        k = 15 if mid == 0 else int(np.ceil(np.log2(half)))
        gain = 2.0 ** (28 - k - 5) * 0.99 / rng.uniform(1.0, 1.05)  # just inside S = 5
        s0 = out_scale / gain
        drift, oreach = 0.3, 0.05 * 0.95 * half
        o0 = mid + rng.choice([-1, 1]) * half * rng.uniform(0.8, 0.95)
    else:
        s0 = rng.choice([131.0, 65.5, 16384.0, 2048.0, 12.8, 2.5, 0.5])
        drift, oreach = 0.05, 400.0
        o0 = mid + rng.uniform(-0.1, 0.1) * half
    off = [o0] + [rng.uniform(-1, 1) * oreach / (span / 2) ** d for d in range(1, do + 1)]
    sc = [s0] + [rng.uniform(-1, 1) * drift * s0 / (span / 2) ** d for d in range(1, ds + 1)]
    policy = rng.choice([fp.CLAMP, fp.EXTRAPOLATE])
    return [_f32(c) for c in off], [_f32(c) for c in sc], (t_lo, t_lo + span), out_scale, rr, policy, t_ref


def legal_sets(seed, n, extreme):
    """The first n sets the set-up accepts (others raise its documented ValueError)."""
    rng = random.Random(seed)
    out = []
    while len(out) < n:
        s = make_set(rng, extreme)
        off, sc, t_cal, osc, rr, pol, t_ref = s
        try:
            fp.Compensator([off], [sc], t_cal, out_scale=osc, raw_range=rr, policy=pol, t_ref=t_ref)
        except ValueError as e:
            assert any(m in str(e) for m in REFUSALS), e
            continue
        out.append(s)
    return out


def probe_points(comp, rr, n_raw):
    ts = [int(t) for t in np.linspace(comp.t_in[0], comp.t_in[1], 7)]
    raws = sorted(set([int(r) for r in np.linspace(rr[0], rr[1], n_raw)] + [rr[0], rr[1], rr[0] + 1, rr[1] - 1]))
    return ts, raws


def reference(s, t, raws):
    off, sc, t_cal, osc, rr, pol, t_ref = s
    lo, hi = t_cal
    if pol == fp.EXTRAPOLATE:
        w = (hi - lo) // 2
        lo, hi = lo - w, hi + w
    u = float(min(max(t, lo), hi)) - t_ref
    o = sum(c * u**i for i, c in enumerate(off))
    g = sum(c * u**i for i, c in enumerate(sc))
    return osc * (np.asarray(raws, dtype=float) - o) / g


def excess(ys, ref, flat):
    """How far each output is beyond the bound (positive: outside), and |error|."""
    err = np.abs(ys - ref)
    return err - (flat + np.abs(ref) * REL), err


def worst_error(sets, flat, n_raw=300):
    """(largest excess over the bound, worst |error|, its output) over the sets."""
    over, worst, at = -np.inf, 0.0, 0.0
    for s in sets:
        off, sc, t_cal, osc, rr, pol, t_ref = s
        comp = fp.Compensator([off], [sc], t_cal, out_scale=osc, raw_range=rr, policy=pol, t_ref=t_ref)
        ts, raws = probe_points(comp, rr, n_raw)
        for t in ts:
            comp.update(t)
            ys = np.array([comp.apply(r) for r in raws], dtype=float)
            ref = reference(s, t, raws)
            x, err = excess(ys, ref, flat)
            over = max(over, float(x.max()))
            if err.max() > worst:
                worst, at = float(err.max()), float(ref[int(err.argmax())])
    return over, worst, at


@pytest.mark.parametrize("seed", seeds.seeds("precision_random", 2))
def test_random_sets_within_the_documented_bound(seed):
    over, worst, at = worst_error(legal_sets(seed, 300, False), FLAT)
    print("seed %d: worst %.4f LSB at output %.4g" % (seed, worst, at))
    assert over <= 0, (seed, over, worst, at)


@pytest.mark.parametrize("seed", seeds.seeds("precision_extreme", 4))
def test_extreme_sets_within_the_documented_bound(seed):
    over, worst, at = worst_error(legal_sets(seed, 100, True), FLAT)
    print("seed %d: worst %.4f LSB at output %.4g" % (seed, worst, at))
    assert over <= 0, (seed, over, worst, at)


def test_the_bound_is_not_loose():
    # the bound must be able to fail: the correctly rounded result alone is 0.5 LSB off somewhere,
    # a flat bound without the relative term fails at large outputs (seed 102's random sets reach
    # 0.773 LSB at 1.3e7), and a one-unit-of-S error in the gain (what 27-bit scales did) breaks
    # the extreme bound
    sets = legal_sets(2, 20, True)
    assert worst_error(sets, FLAT, n_raw=100)[1] > 0.5
    big = legal_sets(102, 300, False)
    over, worst, at = worst_error(big, FLAT)
    assert over <= 0 and worst > FLAT and abs(at) > 2**23
    off, sc, t_cal, osc, rr, pol, t_ref = sets[0]
    comp = fp.Compensator([off], [sc], t_cal, out_scale=osc, raw_range=rr, policy=pol, t_ref=t_ref)
    comp.update(t_cal[1])
    comp._gh[0] += 1  # one unit more of gh: 2**K units of G
    ref = reference(sets[0], t_cal[1], [rr[0], rr[1]])
    ys = np.array([comp.apply(rr[0]), comp.apply(rr[1])], dtype=float)
    assert excess(ys, ref, FLAT)[0].max() > 0


# --- the same on every interpreter: its own set-up (single precision on the M3), its own path --

DEVICE = r"""
from tempcomp import fixedpoint as fp
def exact(me):
    # m * 2**e built by exact doublings: a single-precision parser may round a decimal 1 ulp off
    m, e = me
    v = float(m)
    while e > 0:
        v *= 2.0
        e -= 1
    while e < 0:
        v *= 0.5
        e += 1
    return v
SETS = SETS_
for si in range(len(SETS)):
    off, sc, t_cal, osc, rr, pol, t_ref, ts, raws = SETS[si]
    off = [exact(c) for c in off]
    sc = [exact(c) for c in sc]
    c = fp.Compensator([off], [sc], t_cal, out_scale=osc, raw_range=rr, policy=pol, t_ref=t_ref)
    for t in ts:
        c.update(t)
        print("Y %d %d %s" % (si, t, ",".join(str(c.apply(r)) for r in raws)))
"""


@pytest.mark.parametrize("kind", ["random", "extreme"])
def test_precision_on_every_interpreter(interp, kind):
    extreme = kind == "extreme"
    seed = seeds.seed("precision_interp_" + kind)
    sets = legal_sets(seed, 24 if not extreme else 16, extreme)
    payload = []
    cpython = []
    for s in sets:
        off, sc, t_cal, osc, rr, pol, t_ref = s
        comp = fp.Compensator([off], [sc], t_cal, out_scale=osc, raw_range=rr, policy=pol, t_ref=t_ref)
        ts, raws = probe_points(comp, rr, 40)
        payload.append(([_mant_exp(c) for c in off], [_mant_exp(c) for c in sc], t_cal, osc, rr, pol, t_ref, ts, raws))
        for t in ts:
            comp.update(t)
            cpython.append([comp.apply(r) for r in raws])
    out = interp.run(DEVICE.replace("SETS_", repr(payload)), timeout=600)
    flat = FLAT
    over, worst, n = -np.inf, 0.0, 0
    for m in re.finditer(r"^Y (\d+) (-?\d+) (\S+)$", out, re.M):
        si, t = int(m.group(1)), int(m.group(2))
        got = [int(v) for v in m.group(3).split(",")]
        # single-precision firmware too: the set-up takes each float as the exact binary fraction
        # it is (fixedpoint._exact_mid), so it computes CPython's integers
        assert got == cpython[n], (interp.name, kind, seed, si, t)
        x, err = excess(np.array(got, dtype=float), reference(sets[si], t, payload[si][8]), flat)
        over, worst = max(over, float(x.max())), max(worst, float(err.max()))
        n += 1
    assert n == 7 * len(sets)
    assert over <= 0, (interp.name, kind, seed, over)
    print("%s %s seed %d: worst %.4f LSB" % (interp.name, kind, seed, worst))
