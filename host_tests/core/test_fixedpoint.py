"""Fixed-point core: exactness of the primitives, bounds at the corners, precision against a
float64 reference, temperature policy, set-up errors, and the same code in the MicroPython VM."""

import random

import interps
import numpy as np
import pytest
import seeds
from bounded import BInt, BoundError, bind

from tempcomp import fixedpoint as fp
from tools.firmware import mpvm as vm


def _f64(coeffs, t, t_ref=0.0):
    u = np.asarray(t, dtype=float) - t_ref
    return sum(c * u**i for i, c in enumerate(coeffs))


def reference(off, sc, t, raw, out_scale, t_ref=0.0):
    """float64 evaluation of out_scale * (raw - offset(t)) / scale(t)."""
    return out_scale * (np.asarray(raw, dtype=float) - _f64(off, t, t_ref)) / _f64(sc, t, t_ref)


# --- primitives, against Python's exact big-int arithmetic -------------------------------------


def test_mul_shift_is_exact_floor_including_corners():
    rng = random.Random(seeds.seed("fixedpoint/mul_shift"))
    cases = []
    for h in range(0, 16):
        xm = min(1 << h, 1 << 15)
        for a in (-(1 << 28), (1 << 28), -(1 << 28) + 1, 0, 1, -1, 12345):
            for x in (-xm, xm, 0, 1, -1, xm - 1):
                cases.append((a, x, h))
        for _ in range(300):
            cases.append((rng.randint(-(1 << 28), 1 << 28), rng.randint(-xm, xm), h))
    for a, x, h in cases:
        assert fp.mul_shift(BInt(a), BInt(x), h) == (a * x) >> h, (a, x, h)


def test_div_pow2_is_exact_floor_within_bounds():
    rng = random.Random(seeds.seed("fixedpoint/div_pow2"))
    for _ in range(3000):
        d = rng.randint(1, (1 << 27) - 1)
        num = rng.randint(-(1 << 28), 1 << 28)
        # largest e keeping the quotient below 2**29
        e = 0
        while abs(num) * (1 << (e + 1)) // d < (1 << 29) and e < 60:
            e += 1
        got = fp.div_pow2(BInt(num), e, BInt(d))
        assert got == (num << e) // d


def test_quick_division_is_exact_floor_within_bounds():
    # update()'s 10-bit-step division by the scale's top 20 bits, and its fraction correction
    rng = random.Random(seeds.seed("fixedpoint/quick_division"))
    for _ in range(3000):
        d = rng.randint(1 << 17, (1 << 20) - 1)
        num = rng.randint(-(1 << 28), 1 << 28)
        e = 0
        while abs(num) * (1 << (e + 1)) // d < (1 << 29) and e < 60:
            e += 1
        q = fp._div_wide(BInt(num), e, BInt(d))
        assert q == (num << e) // d
        f = rng.randint(0, (1 << 21) - 1)
        c = fp._corr21(BInt(q), BInt(f), BInt(d))
        assert abs(int(c) - (int(q) * f / 2.0**21) / d) <= 2.0 / d + 1.0


# --- bounds: every intermediate of set-up's integer stage and of apply() at the corners --------


def _bounded(comp):
    bind(comp, ["_gh", "_gl", "_b", "_s", "_half", "_mid", "_eo", "_eg", "_k", "_kmask", "_fq", "_fs", "_wg"])
    if comp.burst3 is not None:
        bind(comp, ["burst3"])
    if comp._q0 is not None:
        bind(comp, ["_q0", "_q1", "_q2"])  # the pure 3-axis path's numbers per axis
    for p in comp._sc + comp._off:
        bind(p, ["_a", "_a0", "_a0h", "_a0l", "_vm", "_mid", "_h", "_vs", "_vr"])
    comp._t = None
    return comp


CONFIGS = [
    # (name, offsets, scales, t_cal, out_scale, raw_range, policy): realistic drifts of a few %
    ("gyro_mdps", [[-35.0, 0.009, -2e-7]], [[131.0, 4e-4, -3e-8]], (-4000, 9000), 1000.0, (-32768, 32767), fp.CLAMP),
    ("mlx_code", [[1008.0, 0.05, 1e-5]], [[12.8, -1e-4, 2e-8]], (300, 1700), 1000.0, (0, 2047), fp.EXTRAPOLATE),
    ("adc_u16", [[31000.0, 0.1, 1e-6, -1e-11]], [[520.0, 1e-3, 1e-8]], (20000, 45000), 100.0, (0, 65535), fp.CLAMP),
    ("accel_mg", [[-20.0, 1.0, 0.01]], [[16.384, -1.6e-3, 1e-6]], (-40, 105), 1.0, (-32768, 32767), fp.EXTRAPOLATE),
    ("max_gain", [[0.0, 0.5]], [[1.0 / 250.0]], (-32768, 32767), 1.0, (-32768, 32767), fp.CLAMP),
    ("wide_t", [[65000.0, 0.01]], [[1.01, 1e-6]], (-32768, 32767), 1.0, (0, 65535), fp.CLAMP),
    # a half-span just past a power of two and a small constant: Horner's partial sums above the
    # whole (Poly), for the offset and for the scale
    ("steep_line", [[0.0, 15.0]], [[131.0, 0.03]], (-1030, 1030), 1000.0, (-32768, 32767), fp.CLAMP),
    ("steep_square", [[0.0, 0.0, 0.028]], [[131.0, 0.0, 4e-5]], (-1030, 1030), 1000.0, (-32768, 32767), fp.CLAMP),
    ("steep_cube", [[0.0, 0.0, 0.0, 2.7e-5]], [[16.4, 0.0, 0.0, 3e-9]], (-1030, 1030), 1.0, (-32768, 32767), fp.CLAMP),
]


@pytest.mark.parametrize("cfg", CONFIGS, ids=[c[0] for c in CONFIGS])
def test_every_intermediate_stays_within_small_int_range(cfg):
    name, offs, scs, t_cal, out_scale, raw_range, policy = cfg
    comp = _bounded(fp.Compensator(offs, scs, t_cal, out_scale=out_scale, raw_range=raw_range, policy=policy))
    lo, hi = comp.t_in
    r_lo, r_hi = raw_range
    for t in (lo - 5, lo, lo + 1, (lo + hi) // 2, hi - 1, hi, hi + 5):
        comp.update(BInt(t))
        for raw in (r_lo, r_lo + 1, 0 if r_lo < 0 else r_lo + 7, r_hi - 1, r_hi):
            comp.apply(BInt(raw))
        buf = bytearray(b"\x80\x00\x7f\xff\x00\x00")
        out = [0, 0, 0]
        if comp.axes == 1 and raw_range == (-32768, 32767):
            comp.apply_be16(buf, out)


def test_bound_checker_catches_a_real_overflow():
    # the checker itself must be able to fail: (-32768)**2 = 2**30 is one past the limit
    with pytest.raises(BoundError):
        BInt(-32768) * BInt(-32768)


# --- precision against float64 ------------------------------------------------------------------


def _sweep_error(comp, offs, scs, out_scale, t_values, raws):
    worst = 0.0
    exact = 0
    total = 0
    for t in t_values:
        comp.update(int(t))
        tc = min(max(int(t), comp._t_lo), comp._t_hi)
        ys = np.array([[comp.apply(int(r), k) for r in raws] for k in range(comp.axes)])
        for k in range(comp.axes):
            ref = reference(offs[k], scs[k], tc, raws, out_scale)
            err = np.abs(ys[k] - ref)
            worst = max(worst, float(err.max()))
            exact += int(np.sum(ys[k] == np.floor(ref + 0.5)))
            total += len(raws)
    return worst, exact / total


@pytest.mark.parametrize("cfg", CONFIGS[:4], ids=[c[0] for c in CONFIGS[:4]])
def test_precision_against_float64_dense_sweep(cfg):
    name, offs, scs, t_cal, out_scale, raw_range, policy = cfg
    comp = fp.Compensator(offs, scs, t_cal, out_scale=out_scale, raw_range=raw_range, policy=policy)
    r_lo, r_hi = raw_range
    raws = np.unique(np.concatenate([np.linspace(r_lo, r_hi, 1500).astype(int), [r_lo, r_hi]]))
    ts = np.linspace(comp.t_in[0], comp.t_in[1], 41).astype(int)
    worst, exact = _sweep_error(comp, offs, scs, out_scale, ts, raws)
    # documented bound: correct rounding plus 2**(1-S) truncation plus the scale's 2**-24 relative
    y_max = max(abs(reference(offs[0], scs[0], t, [r_lo, r_hi], out_scale)).max() for t in ts)
    bound = 0.5 + 2.0 ** (1 - comp._s) + y_max * 2.0**-24
    assert worst <= bound, (worst, bound)
    assert worst < 0.51
    assert exact > 0.99  # equal to the correctly rounded float64 value almost everywhere


def test_random_configurations_stay_within_the_documented_bound():
    rng = random.Random(seeds.seed("fixedpoint/random_configurations"))
    done = 0
    while done < 25:
        deg_o, deg_s = rng.randint(0, 3), rng.randint(0, 3)
        t_lo = rng.randint(-20000, 20000)
        span = rng.randint(50, 40000)
        t_ref = t_lo + span / 2
        s0 = rng.choice([131.0, 65.5, 16384.0, 2048.0, 12.8, 2.5])
        out_scale = rng.choice([1.0, 10.0, 1000.0])
        off = [rng.uniform(-3000, 3000)] + [rng.uniform(-1, 1) * 400 / (span / 2) ** d for d in range(1, deg_o + 1)]
        sc = [s0] + [rng.uniform(-1, 1) * 0.05 * s0 / (span / 2) ** d for d in range(1, deg_s + 1)]
        try:
            comp = fp.Compensator([off], [sc], (t_lo, t_lo + span), out_scale=out_scale, t_ref=t_ref)
        except ValueError as e:
            assert "output unit too fine" in str(e)
            continue
        raws = np.linspace(-32768, 32767, 400).astype(int)
        ts = np.linspace(t_lo, t_lo + span, 9).astype(int)
        worst = 0.0
        for t in ts:
            comp.update(int(t))
            ys = np.array([comp.apply(int(r)) for r in raws])
            worst = max(worst, float(np.abs(ys - reference(off, sc, t, raws, out_scale, t_ref)).max()))
        y_max = 32768 * out_scale / min(abs(_f64(sc, ts, t_ref)))
        assert worst <= 0.5 + 2.0 ** (1 - comp._s) + 2 * y_max * 2.0**-24, (worst, comp._s)
        done += 1


# --- three-point quadratic ----------------------------------------------------------------------


def _lagrange(pts, t):
    (t0, y0), (t1, y1), (t2, y2) = pts
    return (
        y0 * (t - t1) * (t - t2) / ((t0 - t1) * (t0 - t2))
        + y1 * (t - t0) * (t - t2) / ((t1 - t0) * (t1 - t2))
        + y2 * (t - t0) * (t - t1) / ((t2 - t0) * (t2 - t1))
    )


def test_quadratic_through_reproduces_points_and_matches_lagrange():
    rng = random.Random(seeds.seed("fixedpoint/quadratic_through"))
    for _ in range(200):
        ts = sorted(rng.sample(range(-3000, 5000), 3))
        pts = [(t, rng.uniform(-3000, 3000)) for t in ts]
        c = fp.quadratic_through(*pts, t_ref=pts[1][0])
        for t, y in pts:
            assert _f64(c, t, pts[1][0]) == pytest.approx(y, abs=1e-9 * max(1.0, abs(y)))
        for t in np.linspace(ts[0], ts[2], 17):
            assert _f64(c, t, pts[1][0]) == pytest.approx(_lagrange(pts, t), rel=1e-9, abs=1e-7)


def test_quadratic_through_fixed_point_reproduces_its_points():
    pts_off = [(1850, 1003.4), (2500, 1008.0), (3100, 1011.9)]
    pts_sc = [(1850, 12.41), (2500, 12.80), (3100, 13.02)]
    off = fp.quadratic_through(*pts_off)
    sc = fp.quadratic_through(*pts_sc)
    comp = fp.Compensator([off], [sc], (1850, 3100), out_scale=1000.0, raw_range=(0, 2047))
    for (t, o), (_, s) in zip(pts_off, pts_sc):
        comp.update(t)
        for raw in (0, 500, 1008, 1500, 2047):
            assert abs(comp.apply(raw) - 1000.0 * (raw - o) / s) <= 0.5 + 2.0 ** (1 - comp._s)


def test_quadratic_through_rejects_repeated_temperature():
    with pytest.raises(ValueError, match="must differ"):
        fp.quadratic_through((10, 1.0), (10, 2.0), (20, 3.0))


# --- temperature policy -------------------------------------------------------------------------


def test_clamp_holds_the_edge_value_and_counts():
    off, sc = [[10.0, 0.5]], [[100.0, 0.01]]
    comp = fp.Compensator(off, sc, (0, 1000), policy=fp.CLAMP, out_scale=1000.0)
    comp.update(1000)
    edge = comp.apply(5000)
    comp.update(1500)
    assert comp.apply(5000) == edge
    assert comp.clamped == 1
    comp.update(-200)
    assert comp.apply(5000) == round(reference(off[0], sc[0], 0, 5000, 1000.0))
    assert comp.clamped == 2


def test_extrapolate_follows_the_polynomial_to_t_in_then_clamps():
    off, sc = [[10.0, 0.5]], [[100.0, 0.01]]
    comp = fp.Compensator(off, sc, (0, 1000), t_in=(-500, 1500), policy=fp.EXTRAPOLATE, out_scale=1000.0)
    comp.update(1400)
    assert abs(comp.apply(5000) - reference(off[0], sc[0], 1400, 5000, 1000.0)) <= 0.51
    assert comp.clamped == 0
    comp.update(1800)
    assert abs(comp.apply(5000) - reference(off[0], sc[0], 1500, 5000, 1000.0)) <= 0.51
    assert comp.clamped == 1


def test_default_t_in_for_extrapolate_is_half_a_span_each_side():
    comp = fp.Compensator([[0.0]], [[1.0]], (100, 300), policy=fp.EXTRAPOLATE)
    assert comp.t_in == (0, 400)


def test_shift_offset_moves_the_zero():
    off, sc = [[10.0, 0.5]], [[100.0, 0.01]]
    comp = fp.Compensator(off, sc, (0, 1000), out_scale=1000.0)
    comp.update(400)
    comp.shift_offset(0, 3.25)
    assert abs(comp.apply(2000) - reference([13.25, 0.5], sc[0], 400, 2000, 1000.0)) <= 0.51


def test_apply_be16_matches_apply():
    offs = [[-35.0, 0.009], [12.0, -0.003], [3.0, 0.0, 1e-7]]
    scs = [[131.0, 4e-4], [130.0], [132.5, -2e-4]]
    comp = fp.Compensator(offs, scs, (-4000, 9000), out_scale=1000.0)
    comp.update(1234)
    rng = random.Random(seeds.seed("fixedpoint/apply_be16"))
    for _ in range(200):
        raws = [rng.randint(-32768, 32767) for _ in range(3)]
        buf = bytearray()
        for r in raws:
            buf += (r & 0xFFFF).to_bytes(2, "big")
        out = [0, 0, 0]
        comp.apply_be16(buf, out)
        assert out == [comp.apply(r, k) for k, r in enumerate(raws)]


# --- set-up errors --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(offsets=[[0.0, 0, 0, 0, 1e-9]], scales=[[1.0]], t_cal=(0, 10)), "degree 4"),
        (dict(offsets=[[0.0]], scales=[[1.0]], t_cal=(10, 10)), "must exceed"),
        (dict(offsets=[[0.0]], scales=[[1.0]], t_cal=(0, 70000)), "spans 70000"),
        (dict(offsets=[[0.0]], scales=[[1.0]], t_cal=(0.5, 10)), "pair of ints"),
        (dict(offsets=[[0.0]], scales=[[-1.0]], t_cal=(0, 10)), "must be positive"),
        (dict(offsets=[[0.0]], scales=[[1.0, 0.5]], t_cal=(0, 10)), "varies more than"),
        (dict(offsets=[[0.0]], scales=[[0.001]], t_cal=(0, 10)), "output unit too fine"),
        (dict(offsets=[[90000.0]], scales=[[1.0]], t_cal=(0, 10)), "outside the raw range"),
        (dict(offsets=[[0.0]], scales=[[1.0]], t_cal=(0, 10), t_in=(2, 20)), "must contain"),
        (dict(offsets=[[0.0], [1.0]], scales=[[1.0]], t_cal=(0, 10)), "one offset and one scale"),
        (dict(offsets=[[float("nan")]], scales=[[1.0]], t_cal=(0, 10)), "not finite"),
        (dict(offsets=[[0.0]], scales=[[1.0]], t_cal=(0, 10), out_scale=0), "out_scale"),
        (dict(offsets=[[0.0]], scales=[[1.0]], t_cal=(0, 10), policy=7), "policy"),
        (dict(offsets=[[0.0]], scales=[[1.0]], t_cal=(0, 10), raw_range=(0, 70000)), "spans 70000"),
    ],
)
def test_setup_rejects_bad_input_with_a_clear_error(kwargs, match):
    with pytest.raises(ValueError, match=match):
        fp.Compensator(**kwargs)


# --- the same code in the real MicroPython VM ---------------------------------------------------

VM_CODE = r"""
import allocprobe
from tempcomp.fixedpoint import Compensator, CLAMP, EXTRAPOLATE
offs = [[-35.0, 0.009, -2e-7], [12.0, -0.003], [3.0, 0.0, 1e-7, -1e-11]]
scs = [[131.0, 4e-4, -3e-8], [130.0], [132.5, -2e-4]]
c = Compensator(offs, scs, (-4000, 9000), out_scale=1000.0, policy=EXTRAPOLATE)
out = [0, 0, 0]
rows = []
for t in (-9000, -4000, 0, 4321, 9000, 20000):
    c.update(t)
    for raw in (-32768, -1000, 0, 777, 32767):
        rows.append("%d %d %d %d %d" % (t, raw, c.apply(raw, 0), c.apply(raw, 1), c.apply(raw, 2)))
print("ROWS " + ";".join(rows))
buf = bytearray(b"\x80\x00\x12\x34\x7f\xff")
state = [0]
def sweep_update():
    # a new temperature every call, so the polynomial and division stage really runs
    state[0] = (state[0] + 37) & 0x1FFF
    c.update(state[0] - 4000)
def sample():
    c.apply_be16(buf, out)
def one(raw):
    return c.apply(raw)
c.update(1000)
allocprobe.report("apply", one, (-32768,))
allocprobe.report("apply_be16", sample)
allocprobe.report("update", sweep_update)
def floatpath(raw):
    return (raw - 35.0) / 131.0 * 1000.0
allocprobe.report("float_formula", floatpath, (1234,))
"""


def test_vm_gives_the_same_results_and_allocates_nothing(interp):
    # on every interpreter: the WebAssembly VM, Cortex-M3/M7 firmware, CircuitPython
    out = interps.run(interp, VM_CODE)
    rows = [line for line in out.splitlines() if line.startswith("ROWS ")][0][5:].split(";")
    offs = [[-35.0, 0.009, -2e-7], [12.0, -0.003], [3.0, 0.0, 1e-7, -1e-11]]
    scs = [[131.0, 4e-4, -3e-8], [130.0], [132.5, -2e-4]]
    c = fp.Compensator(offs, scs, (-4000, 9000), out_scale=1000.0, policy=fp.EXTRAPOLATE)
    for row in rows:
        t, raw, *ys = (int(v) for v in row.split())
        c.update(t)
        assert ys == [c.apply(raw, k) for k in range(3)], row
    alloc = vm.alloc_lines(out)
    for name in ("apply", "apply_be16", "update"):
        assert alloc[name] == (0.0, True), (name, alloc[name])
    # the contrast: the same formula in floats allocates on every call
    assert alloc["float_formula"][0] > 0 and not alloc["float_formula"][1]


def test_three_axis_burst_path_stays_within_bounds_at_the_corners():
    # the unrolled path folds the rounding half into the offset term: check its sums at the
    # largest gain and offsets the set-up accepts, for the extreme int16 codes
    offs = [[16000.0, 0.1], [-16000.0, -0.1], [0.0]]
    scs = [[1.0 / 250.0], [1.0 / 250.0, 1e-9], [1.0 / 200.0]]
    comp = _bounded(fp.Compensator(offs, scs, (-30000, 30000), out_scale=1.0))
    assert comp.burst3 is not None
    out = [0, 0, 0]
    for t in (-30000, 0, 30000):
        comp.update(BInt(t))
        for a, b, c in ((-32768, 32767, 0), (32767, -32768, -1), (-1, 0, 32767)):
            buf = bytearray()
            for r in (a, b, c):
                buf += (r & 0xFFFF).to_bytes(2, "big")
            comp.apply_be16(buf, out)
            assert out == [comp.apply(a, 0), comp.apply(b, 1), comp.apply(c, 2)]


@pytest.mark.parametrize("coeffs", [[0.0, 15.0], [3.0, 15.0, 0.002], [0.0, 0.0, 0.028], [0.5, 0.0, 0.0, 2.7e-5]])
def test_horner_partial_sums_keep_their_bound_when_the_range_just_passes_a_power_of_two(coeffs):
    # t range -1030..1030: half-span 1030 just past 2**10, so rho = 1030 / 2**11 ~ 1/2 and
    # Horner's partial sum P_k can be V / rho**k, up to 8x the variable part V. With a small
    # constant (an MPU offset held near its model), V is most of the whole: sized for the whole
    # alone, a quadratic's a_2 reached 2**30 (a long int: allocation per update), and an
    # mpu_tcc record's Horner coefficients passed the 2**28 its boot check allowed
    p = fp.Poly(coeffs, (-1030, 1030))
    assert max(abs(a) for a in p._a) <= 1 << 29, p._a
    for t in (-1030, -1029, 0, 1029, 1030):
        acc = p._a[p._deg]
        for j in range(p._deg - 1, -1, -1):  # every Horner step, at the range's ends too
            assert abs(acc) <= 1 << 29 and abs(acc * t) >> p._h <= 2 ** (28 + 2 / 3), (t, j, acc)
            acc = fp.mul_shift(acc, t - p._mid, p._h) + (p._a[j] if j else 0)
        want = sum(c * t**i for i, c in enumerate(coeffs)) * 2.0**p.frac
        assert abs(p.eval(t) - want) <= 2, (t, p.eval(t), want)
