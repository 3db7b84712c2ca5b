"""Fixed-point temperature compensation core shared by every sensor module.

A sensor's offset and scale are polynomials (degree 0..3) of its own temperature reading ``t``
(an integer: an ADC code, a register value, millivolts). Set-up turns the coefficients (floats, or
exact ``(num, den)`` pairs of ints) into integers once, in exact arithmetic where the port has long
ints, so every interpreter gets the same integers from the same coefficients; after that ::

    y = out_scale * (raw - offset(t)) / scale(t)

is computed with integer arithmetic only, every intermediate inside the small-int range
[-2**30, 2**30 - 1] of 32-bit MicroPython, so reading and compensating allocates nothing.

Usage::

    from tempcomp.fixedpoint import Compensator, quadratic_through
    off = quadratic_through((1800, -12.0), (2500, 0.0), (3100, 7.5))    # raw LSB vs t
    sc = quadratic_through((1800, 130.2), (2500, 131.0), (3100, 131.9))  # LSB per dps
    comp = Compensator([off], [sc], t_cal=(1800, 3100), out_scale=1000)  # milli-dps out
    comp.update(2630)          # new temperature reading: once per temperature sample
    mdps = comp.apply(raw)     # per sample, zero allocation

Two stages, with their bounds (B = 2**30 is the small-int limit):

* Per temperature (``update``): each polynomial is evaluated by Horner's rule in the
  normalised variable x = (t - t_mid) / 2**h, |x| <= 1, with coefficients scaled so that the
  sum of their magnitudes is <= 2**28 (2**27 for scales); a partial sum of Horner's rule is
  then <= 2**28 too, or up to 2**29 where the span just passes a power of two (Poly: then
  |acc * x| <= 2**(28 + 2/3)). A product acc*X is split into 14-bit limbs (``mul_shift``):
  |limb * X| <= 2**14 * 2**15, or <= 2**(29 + 2/3) for those partial sums.
  The gain out_scale/scale(t) and the offset term are obtained by long division whose
  remainder is < 2**27, shifted 3 bits a step: < 2**30.
* Per sample (``apply``): r = raw - raw_mid with |r| <= 2**K (K <= 15: the raw range's
  half-span); the gain G = gain * 2**(K+S) <= 2**28 is split as G = gh * 2**K + gl with
  |gh| <= 2**(28-K), 0 <= gl < 2**K, so |r*gh| <= 2**28, |r*gl| < 2**30, and the offset term
  |Boff| = |offset - raw_mid| * gain * 2**S <= 2**(K+1) * 2**(28-K) = 2**29: the sum < 2**30.
  S (fraction bits) is chosen at set-up from the largest gain and kept in [5, 24]; the
  intermediate truncations add < 2**(1 - S) <= 1/16 output LSB before the final rounding,
  and the scale's 27-bit evaluation adds about |y| * 2**-24 (|y| the output magnitude).

Temperature outside the calibrated span ``t_cal`` follows the caller's policy: ``CLAMP``
(default) holds offset and scale at the span's edge; ``EXTRAPOLATE`` evaluates the polynomials
up to the declared input range ``t_in`` and clamps beyond it. Every clamp is counted in
``Compensator.clamped`` so a reading outside the bounds is visible, never silently wrapped.
"""

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


CLAMP = const(0)
EXTRAPOLATE = const(1)

_LIMB = const(14)  # mul_shift limb: |a| <= 2**28 -> |a >> 14| <= 2**14
_LIMB_MASK = const(0x3FFF)
_VALUE_BITS = const(28)  # Horner partial sums of offset polynomials
_DIV_BITS = const(27)  # scale values (the divisor) < 2**27: remainder << 3 stays < 2**30
_DIV_STEP = const(3)
_GAIN_BITS = const(28)  # G = gain * 2**(K+S) <= 2**28: the long division's quotient bound
_S_MIN = const(5)  # truncation error < 2**(1 - S) output LSB
_S_MAX = const(24)
_MAX_DEGREE = const(3)
_SPAN_LIMIT = const(65535)  # t and raw ranges: half-span <= 2**15 keeps |x| limbs in bound
_SCALE_RATIO = const(2)  # scale may vary at most 2x over the input range
_EXT = const(14)  # extra fraction bits of eval_ext(): the scale's rounding, 2**-27 -> 2**-41
_EXT_MASK = const(0x3FFF)
_WIDE = const(7)  # update()'s quick division: by the top 20 of the scale value's 27 bits
_WIDE_MASK = const(0x7F)
_GAIN_NUM = const(1 << 28)


def mul_shift(a, x, h):
    """Return floor(a * x / 2**h) exactly for |a| <= 2**28, |x| <= 2**15 and |x| <= 2**h."""
    ah = a >> _LIMB
    al = a & _LIMB_MASK
    hi = ah * x  # |ah| <= 2**14, |x| <= 2**15: |hi| <= 2**29
    lo = al * x  # 0 <= al < 2**14: |lo| < 2**29
    if h >= _LIMB:
        # a*x = hi*2**14 + lo, so floor(a*x / 2**h) = floor((hi + floor(lo / 2**14)) / 2**(h-14))
        return (hi + (lo >> _LIMB)) >> (h - _LIMB)  # |lo >> 14| <= 2**15: sum < 2**30
    return (hi << (_LIMB - h)) + (lo >> h)  # |hi| <= 2**(14+h): the shift gives <= 2**28


def div_pow2(num, e, d):
    """Return floor(num * 2**e / d) exactly for 0 < d < 2**27, |num| <= 2**28, e >= 0.

    The caller guarantees the quotient is below 2**29; the remainder stays below d, and
    (d - 1) << 3 <= 2**30 - 8, so no intermediate leaves the small-int range.
    """
    q = num // d
    r = num - q * d
    while e > 0:
        s = _DIV_STEP if e >= _DIV_STEP else e
        r <<= s
        c = r // d
        r -= c * d
        q = (q << s) + c
        e -= s
    return q


def _pow2(n):
    # 2.0 ** n without depending on the port's pow() for negative exponents
    v = 1.0
    if n >= 0:
        for _ in range(n):
            v *= 2.0
    else:
        for _ in range(-n):
            v *= 0.5
    return v


def _fit_frac(total, budget, max_frac):
    # largest f <= max_frac with total * 2**f <= budget (max_frac when total is 0)
    if total <= 0:
        return max_frac
    f = 0
    while total * _pow2(f + 1) <= budget and f < max_frac:
        f += 1
    while total * _pow2(f) > budget:
        f -= 1
    return f


def _binomial(n, k):
    r = 1
    for i in range(k):
        r = r * (n - i) // (i + 1)
    return r


def shift_basis(coeffs, old_ref, new_ref):
    """Coefficients of powers of (t - old_ref) re-expanded in powers of (t - new_ref) (set-up)."""
    d = new_ref - old_ref
    n = len(coeffs)
    out = [0.0] * n
    for i in range(n):
        c = float(coeffs[i])
        for j in range(i + 1):
            out[j] += c * _binomial(i, j) * float(d) ** (i - j)
    return out


def code_span(lo_c, hi_c, t_offset, t_scale):
    """(lo, hi) integer temperature codes covering lo_c..hi_c degC, T = code * t_scale + t_offset (set-up)."""
    a = (lo_c - t_offset) / t_scale
    b = (hi_c - t_offset) / t_scale
    if a > b:
        a, b = b, a
    lo = int(a)
    if lo > a:
        lo -= 1
    hi = int(b)
    if hi < b:
        hi += 1
    return (lo, hi)


def poly_value(coeffs, u):
    """Float value of sum coeffs[k] * u**k (set-up and checks; allocates)."""
    v = 0.0
    i = len(coeffs) - 1
    while i >= 0:
        v = v * u + coeffs[i]
        i -= 1
    return v


def _extrema(coeffs, lo, hi):
    # min and max of a polynomial (powers of u) over [lo, hi]: endpoints and critical points
    pts = [float(lo), float(hi)]
    n = len(coeffs) - 1
    if n == 2 and coeffs[2] != 0:
        pts.append(-coeffs[1] / (2.0 * coeffs[2]))
    elif n == 3:
        a, b, c = 3.0 * coeffs[3], 2.0 * coeffs[2], coeffs[1]
        if a == 0:
            if b != 0:
                pts.append(-c / b)
        else:
            disc = b * b - 4.0 * a * c
            if disc >= 0:
                sq = disc**0.5
                pts.append((-b + sq) / (2.0 * a))
                pts.append((-b - sq) / (2.0 * a))
    vals = [poly_value(coeffs, p) for p in pts if lo <= p <= hi]
    return min(vals), max(vals)


def _check_range(name, rng):
    lo, hi = rng
    if not isinstance(lo, int) or not isinstance(hi, int):
        raise ValueError("%s must be a pair of ints, got %r" % (name, rng))
    if hi <= lo:
        raise ValueError("%s: upper end %d must exceed lower end %d" % (name, hi, lo))
    if hi - lo > _SPAN_LIMIT:
        raise ValueError("%s spans %d counts; at most %d are supported" % (name, hi - lo, _SPAN_LIMIT))
    return lo, hi


def _check_coeffs(name, coeffs):
    n = len(coeffs)
    if n < 1 or n > _MAX_DEGREE + 1:
        raise ValueError("%s: degree %d not supported (0..%d)" % (name, n - 1, _MAX_DEGREE))
    for c in coeffs:
        c = to_float(c)
        if c != c or c in (float("inf"), float("-inf")):
            raise ValueError("%s: coefficient %r is not finite" % (name, c))


class Poly:
    """p(t) = sum c[i] * (t - t_ref)**i in fixed point for integer t in [t_lo, t_hi].

    ``eval(t)`` returns round(p(t) * 2**frac) within a few units, where ``frac`` is chosen so
    that all Horner partial sums stay <= 2**limit. Zero allocation per ``eval``.
    """

    def __init__(self, coeffs, t_range, t_ref=0, limit=_VALUE_BITS, max_frac=60, div=1.0, sub=0):
        # the polynomial is (sum coeffs[i] (t - t_ref)**i - sub) / div (div > 0, sub an int)
        _check_coeffs("polynomial", coeffs)
        t_lo, t_hi = _check_range("temperature range", t_range)
        mid = (t_lo + t_hi) // 2
        half = max(t_hi - mid, mid - t_lo)
        h = 0
        while (1 << h) < half:
            h += 1
        # coefficients of x = (t - mid) / 2**h, so |x| <= 1 over the range
        fc = [to_float(c) for c in coeffs]
        fc[0] -= sub
        b = [v / div for v in shift_basis(fc, t_ref, mid)]
        self.t_range = (t_lo, t_hi)
        self._mid = mid
        self._h = h
        ex = None
        try:
            ex = _exact_mid(coeffs, t_ref, mid, div, sub)
        except (OverflowError, ValueError, TypeError):
            pass  # a build without long ints: the float path below
        if ex is not None:
            # The same choices and numbers as the float path below, in exact rational arithmetic
            # (long ints, set-up only): with b_j = B[j] / q, n_j rho**j = b_j half**j, so every
            # bound is an integer over q. Single-precision floats (the Cortex-M3) and float64 then
            # give identical integers for identical coefficients.
            bq, q = ex
            while len(bq) > 1 and bq[-1] == 0:
                bq.pop()
            deg = len(bq) - 1
            vb = 0
            for k in range(1, deg + 1):
                pk = 0
                for j in range(deg, k - 1, -1):
                    pk = pk * half + abs(bq[j])
                vb = max(vb, pk << (h * k))
            vsum = 0
            for j in range(deg, 0, -1):
                vsum = (vsum + abs(bq[j])) * half
            vb = max(vb, vsum)
            frac = _fit_frac_q(abs(bq[0]) + vsum, q, limit, max_frac)
            vfrac = _fit_frac_q(vb, q, limit, frac + 24)
            if vfrac < frac:  # a partial sum above the whole (below)
                frac = min(frac, vfrac + 1)
                vfrac = frac
            a0x = _scaled(bq[0], frac + _EXT, q)
            self._a0 = (a0x + (1 << (_EXT - 1))) >> _EXT
            self._a0h = a0x >> _EXT
            self._a0l = a0x & _EXT_MASK
            self._a = (0,) + tuple(_scaled(bq[j], h * j + vfrac, q) for j in range(1, deg + 1))
        else:
            n = [b[j] * _pow2(h * j) for j in range(len(b))]
            while len(n) > 1 and n[-1] == 0:
                n.pop()
            # |x| <= rho = half / 2**h (between 1/2 and 1): Horner's partial sums
            # P_k = sum_{j>=k} n_j x**(j-k) (k >= 1, each fed to mul_shift) and the variable part
            # V = sum_{j>=1} n_j x**j are bounded by their sums of |n_j| rho**(j-k), not of |n_j|:
            # up to 3 more fraction bits than the plain sum for a cubic over a span just past 2**h
            rho = half / _pow2(h)
            deg = len(n) - 1
            vb = 0.0
            for k in range(1, deg + 1):
                pk = 0.0
                for j in range(deg, k - 1, -1):
                    pk = pk * rho + abs(n[j])
                vb = max(vb, pk)
            vsum = 0.0
            for j in range(deg, 0, -1):
                vsum = (vsum + abs(n[j])) * rho
            vb = max(vb, vsum)
            budget = _pow2(limit) * (1.0 - 1.0 / 1024)  # room for coefficient rounding
            frac = _fit_frac(abs(n[0]) + vsum, budget, max_frac)
            # The temperature-dependent part is small next to the constant (a few % of drift), so
            # it gets its own, finer scale: Horner's few units of rounding then land below one
            # unit of the result instead of adding up in it. The variable part V is no larger
            # than the whole, but a partial sum can be: P_k <= V / rho**k, when the range just
            # passes a power of two (rho ~ 1/2) and the constant is small (an MPU offset held
            # near the model). P_k <= 2 * 2**limit is kept, lowering the constant's scale if
            # need be: |P_k * (t - mid)| / 2**h <= min(2 rho, rho**(1-k)) * 2**limit, at most
            # 2**(limit + 2/3) (k = 3), so mul_shift's limb products stay < 2**30 (module notes)
            vfrac = _fit_frac(vb, budget, frac + 24)
            if vfrac < frac:
                frac = min(frac, vfrac + 1)
                vfrac = frac
            self._a0 = int(round(n[0] * _pow2(frac)))
            # the constant again with _EXT more bits, as a0h + a0l / 2**_EXT
            # (0 <= a0l < 2**_EXT), for eval_ext(); two small ints
            f0 = n[0] * _pow2(frac)
            a0h = int(f0 // 1.0)
            a0l = int(round((f0 - a0h) * _pow2(_EXT)))
            if a0l >= (1 << _EXT):
                a0h += 1
                a0l -= 1 << _EXT
            self._a0h = a0h
            self._a0l = a0l
            self._a = (0,) + tuple(int(round(v * _pow2(vfrac))) for v in n[1:])
        self.frac = frac
        self._deg = deg
        # eval()'s mul_shift(acc, x, h) inline, one form for every h: x << (14 - h) when
        # h < 14 gives floor(acc * x * 2**(14-h) / 2**14) = floor(acc * x / 2**h) with
        # |x| <= 2**14; |acc| <= 2**29, each limb product <= 2**(29 + 2/3) (module notes): the sum < 2**30
        self._xl = _LIMB - h if h < _LIMB else 0
        self._xs = h - _LIMB if h >= _LIMB else 0
        self._vs = vfrac - frac
        self._vr = (1 << (vfrac - frac - 1)) if vfrac > frac else 0
        self._vm = (1 << (vfrac - frac)) - 1
        self.ext = 0
        self._coeffs_mid = b  # float coefficients of (t - mid), for set-up checks

    def eval(self, t):
        """Fixed-point value at integer reading t (caller keeps t inside t_range)."""
        i = self._deg
        if i == 0:
            return self._a0
        a = self._a
        acc = a[i]
        x = (t - self._mid) << self._xl
        hs = self._xs
        while True:
            acc = ((acc >> _LIMB) * x + (((acc & _LIMB_MASK) * x) >> _LIMB)) >> hs  # mul_shift
            i -= 1
            if not i:
                break
            acc += a[i]
        # |variable part| <= sum|a[1:]| <= 2**limit; shifted down to frac and rounded
        return self._a0 + ((acc + self._vr) >> self._vs)

    def eval_ext(self, t):
        """eval(t) with _EXT more bits: returns D and sets self.ext = R, where
        p(t) * 2**frac ~ D + R / 2**_EXT, 0 <= R < 2**_EXT. Zero allocation."""
        i = self._deg
        if i == 0:
            self.ext = self._a0l
            return self._a0h
        a = self._a
        v = a[i]
        x = (t - self._mid) << self._xl
        hs = self._xs
        while True:
            v = ((v >> _LIMB) * x + (((v & _LIMB_MASK) * x) >> _LIMB)) >> hs  # mul_shift
            i -= 1
            if not i:
                break
            v += a[i]
        # |v| <= 2**limit, in units of 2**-(frac + vs)
        vs = self._vs
        lo = v & self._vm  # 0 <= lo < 2**vs
        if vs >= _EXT:
            lo >>= vs - _EXT
        else:
            lo <<= _EXT - vs  # < 2**_EXT
        lo += self._a0l  # < 2**(_EXT + 1)
        self.ext = lo & _EXT_MASK
        return self._a0h + (v >> vs) + (lo >> _EXT)

    def extrema(self):
        """(min, max) of the float polynomial over t_range (set-up use)."""
        lo, hi = self.t_range
        return _extrema(self._coeffs_mid, lo - self._mid, hi - self._mid)


def _exact_float(x):
    # (m, e) with x == m * 2**e exactly: doubling a binary float is exact (set-up only)
    x = float(x)
    e = 0
    while x != int(x):
        x *= 2.0
        e -= 1
    return int(x), e


# The exact-coefficient helpers, public for the modules that hand this one (num, den) pairs
# (tempcomp.mpu6xxx_tc's exact fit): the gcd that reduces a pair, a float's exact ratio, and a
# pair's float value.


def gcd(a, b):
    """Greatest common divisor of two ints (non-negative)."""
    a = abs(a)
    b = abs(b)
    while b:
        a, b = b, a % b
    return a


def ratio(c):
    """A coefficient as an exact (num, den) pair, den > 0: a float is the binary fraction it is."""
    if type(c) is tuple:
        return c
    if type(c) is int:
        return (c, 1)
    m, e = _exact_float(c)
    return (m, 1 << -e)


def to_float(c):
    """Float value of a coefficient: a number, or an exact pair (num, den) of ints, den > 0.

    Every coefficient the set-up takes may be such a pair (BiasModel's exact fits): the integers
    are then computed from the rational number itself, not from its rounding to this port's
    floats."""
    if type(c) is not tuple:
        return float(c)
    n, d = c
    while d >> 80 and abs(n) >> 80:
        n >>= 16  # single-precision floats end at 2**128; 64 bits of each keep the ratio
        d >>= 16
    return n / d


def _round_div(num, den):
    # round(num / den) for den > 0, halves up; exact on ints of any size
    return (2 * num + den) // (2 * den)


def _scaled(num, k, den):
    # round(num * 2**k / den) for den > 0, any int k
    return _round_div(num << k, den) if k >= 0 else _round_div(num, den << -k)


def _fit_frac_q(num, den, limit, max_frac):
    # _fit_frac for the exact total num / den (den > 0) against budget 2**limit * 1023 / 1024:
    # the largest f <= max_frac with num * 2**f * 1024 <= den * 1023 * 2**limit
    if num <= 0:
        return max_frac
    f = max_frac
    a = num * 1024
    b = (den * 1023) << limit
    if f >= 0:
        a <<= f
    else:
        b <<= -f
    while a > b:
        if f > 0:
            a >>= 1  # a = num * 1024 * 2**f: even, so this is exact
        else:
            b <<= 1
        f -= 1
    return f


def _exact_mid(coeffs, t_ref, mid, div, sub):
    """The polynomial's coefficients in powers of (t - mid), minus sub, over div, as exact
    rationals B[j] / q (set-up, long ints).

    Float steps in single precision (the Cortex-M3 firmware) err by 2**-24 relative: dividing
    by out_scale, re-expanding about the range's middle. Here every float is taken as the exact
    binary fraction it is, a pair (num, den) as the number it is, and the rest is integer
    arithmetic. Returns None where t_ref is no int.
    """
    if t_ref != int(t_ref):
        return None
    d = mid - int(t_ref)
    rs = [ratio(c) for c in coeffs]
    dn, dd = ratio(div)
    if dn <= 0:
        return None
    q = 1
    for _, r in rs:
        q = q * r // gcd(q, r)
    m = [c * (q // r) for c, r in rs]
    m[0] -= sub * q
    out = []
    for j in range(len(m)):
        bj = 0
        for i in range(j, len(m)):
            bj += m[i] * _binomial(i, j) * d ** (i - j)
        out.append(bj * dd)
    return out, q * dn


def quadratic_through(p0, p1, p2, t_ref=0):
    """Coefficients (c0, c1, c2) of powers of (t - t_ref) through three (t, y) points.

    Newton's divided differences in float: the AN2/AN-1049 closed forms multiply four
    millivolt values (~2**45) and overflow 32-bit integers; this form never does.
    Pass the same ``t_ref`` to Compensator (both default to 0); a t_ref inside the span
    keeps single-precision set-up on boards well conditioned.
    """
    (t0, y0), (t1, y1), (t2, y2) = p0, p1, p2
    if t0 == t1 or t1 == t2 or t0 == t2:
        raise ValueError("quadratic_through: temperatures %r, %r, %r must differ" % (t0, t1, t2))
    d01 = (float(y1) - y0) / (float(t1) - t0)
    d12 = (float(y2) - y1) / (float(t2) - t1)
    d012 = (d12 - d01) / (float(t2) - t0)
    # y = y0 + d01 (t - t0) + d012 (t - t0)(t - t1), re-expanded about t_ref
    a = float(t0) - t_ref
    b = float(t1) - t_ref
    c2 = d012
    c1 = d01 - d012 * (a + b)
    c0 = y0 - d01 * a + d012 * a * b
    return (c0, c1, c2)


class Compensator:
    """out_scale * (raw - offset(t)) / scale(t) for N axes sharing one temperature reading.

    offsets, scales: one coefficient sequence per axis (powers of t - t_ref; raw LSB and
    raw LSB per physical unit), each a number or an exact (num, den) pair of ints. t_cal: calibrated span of the reading; t_in: the readings the
    bounds are proven for (default: t_cal with CLAMP, t_cal widened by half its span with
    EXTRAPOLATE). raw_range: the raw codes (at most 65536 of them, signed or unsigned).

    ``burst3``: for 3 signed int16 axes, the 11 numbers the unrolled burst path reads (per axis
    the gain's two limbs and the offset term with the rounding half; then K and S), kept current
    by ``update()`` in the same list (or 32-bit array), so a driver may unpack it per sample
    (``tempcomp.mpu6xxx.read_compensated``); None for other Compensators. ``export()`` gives
    every number of the per-sample state, for a boot that resumes it without the set-up.
    """

    def __init__(
        self,
        offsets,
        scales,
        t_cal,
        t_in=None,
        out_scale=1.0,
        raw_range=(-32768, 32767),
        policy=CLAMP,
        t_ref=0,
    ):
        if len(offsets) != len(scales) or not offsets:
            raise ValueError("need one offset and one scale polynomial per axis")
        if policy not in (CLAMP, EXTRAPOLATE):
            raise ValueError("policy must be CLAMP or EXTRAPOLATE, got %r" % (policy,))
        c_lo, c_hi = _check_range("t_cal", t_cal)
        if t_in is None:
            if policy == EXTRAPOLATE:
                w = (c_hi - c_lo) // 2
                t_in = (c_lo - w, c_hi + w)
            else:
                t_in = (c_lo, c_hi)
        i_lo, i_hi = _check_range("t_in", t_in)
        if i_lo > c_lo or i_hi < c_hi:
            raise ValueError("t_in %r must contain t_cal %r" % (t_in, t_cal))
        r_lo, r_hi = _check_range("raw_range", raw_range)
        out_scale = float(out_scale)
        if not out_scale > 0 or out_scale == float("inf"):
            raise ValueError("out_scale must be a positive number, got %r" % (out_scale,))
        self.policy = policy
        self.t_cal = (c_lo, c_hi)
        self.t_in = (i_lo, i_hi)
        self.raw_range = (r_lo, r_hi)
        self.out_scale = out_scale
        if policy == CLAMP:
            self._t_lo, self._t_hi = c_lo, c_hi
        else:
            self._t_lo, self._t_hi = i_lo, i_hi
        mid = (r_lo + r_hi + 1) // 2
        # K: bits of the raw half-span, |raw - mid| <= 2**K <= 2**15; also the gain's limb
        K = 1
        while (1 << K) < max(r_hi - mid, mid - r_lo):
            K += 1
        if mid == 0:
            # apply_be16 decodes whole int16 words, and a word outside a narrower signed range
            # (a 14-bit part's +-8192, a glitch) must stay in bound too: |r| <= 2**15 = 2**K
            K = 15
        self._mid = mid
        self._k = K
        self._kmask = (1 << K) - 1
        n = len(offsets)
        self.axes = n
        ev = (self._t_lo, self._t_hi)
        gain_max = 0.0
        offs = []
        scs = []
        for k in range(n):
            _check_coeffs("offset[%d]" % k, offsets[k])
            _check_coeffs("scale[%d]" % k, scales[k])
            o = list(offsets[k])  # floats or exact (num, den) pairs: Poly takes either as it is
            sp = Poly(list(scales[k]), ev, t_ref, limit=_DIV_BITS, div=out_scale)
            s_min, s_max = sp.extrema()
            if not s_min > 0:
                raise ValueError(
                    "scale[%d] must be positive over t %r (min %r); flip the axis sign in "
                    "the offset and raw instead" % (k, ev, s_min * out_scale)
                )
            if s_max > _SCALE_RATIO * s_min:
                raise ValueError(
                    "scale[%d] varies more than %dx over t %r (%r..%r): not a sensor's "
                    "temperature drift; check the coefficients" % (k, _SCALE_RATIO, ev, s_min, s_max)
                )
            gain_max = max(gain_max, 1.0 / s_min)
            offs.append(o)
            scs.append(sp)
        # S: largest fraction with G = gain * 2**(K+S) <= 2**28, with a rounding margin
        limit = _pow2(_GAIN_BITS - K) * (1.0 - 1.0 / 1024)
        S = _S_MAX
        while S >= _S_MIN and gain_max * _pow2(S) > limit:
            S -= 1
        if S < _S_MIN:
            raise ValueError(
                "output unit too fine: %r output units per raw LSB; at most %r are supported, "
                "use a smaller out_scale" % (gain_max, limit / _pow2(_S_MIN))
            )
        self._s = S
        self._half = 1 << (S - 1)
        self._sc = scs
        self._off = list(scs)  # placeholders of the same type, each replaced just below
        self._eo = [0] * n
        # G = gain * 2**(K+S) = 2**(K+S+Fs) / D, with one extra bit for rounding
        self._eg = [K + S + sp.frac + 1 for sp in scs]
        # update()'s quick division needs the scale value d >= 2**24 over the whole range and
        # 2**eg / 2**28 / 2**_WIDE >= 1; -1: the plain 3-bit long division
        self._wg = [-1] * n
        for k in range(n):
            sp = scs[k]
            if sp.extrema()[0] * _pow2(sp.frac) >= _pow2(24) * 1.01:
                if self._eg[k] - 28 - _WIDE >= 0:
                    self._wg[k] = self._eg[k] - 28 - _WIDE
        for k in range(n):
            self._set_offset(k, offs[k], ev, t_ref, "offset[%d]" % k, mid)
        self._gh = [0] * n
        self._gl = [0] * n
        self._b = [0] * n
        # constant-scale axes (most gyros and accelerometers): their gain once here, their
        # offset term as a polynomial of its own (_set_fast), so update() is Horner only
        self._fd = [-1] * n  # degree of that polynomial, -1: the scale varies, full update
        self._fq = [0] * (4 * n)  # its coefficients, 4 per axis
        self._fs = [0] * n  # its variable part's shift
        for k in range(n):
            self._set_fast(k)
        self.clamped = 0
        self._t = None
        # the unrolled 3-axis burst path needs signed int16 raw codes (raw range middle 0)
        self.burst3 = None
        self._nk = None
        self._q0 = self._q1 = self._q2 = None
        if n == 3 and mid == 0:
            nk = _kernels() if _native is not False else None
            if nk is not None:
                # native kernels read the 11 numbers (and the batch's stride and output tag)
                # from a 32-bit array; the pure path unpacks a list faster
                self.burst3 = nk.params()
                self._nk = nk.kernels(self.burst3, self._check_n)
            else:
                self.burst3 = [0] * 11
                # _be16_3's numbers per axis (gain limbs, offset term minus half)
                self._q0 = [0, 0, 0]
                self._q1 = [0, 0, 0]
                self._q2 = [0, 0, 0]
        if min(self._fd) >= 0:
            # every scale constant: update() is Horner only
            self._fill_burst3()
            self.update = self._update_fast
        self.update(self._t_lo)
        if mid != 0:
            # a signed word minus a middle far from 0 may leave |r| <= 2**15
            self.apply_be16 = self._be16_refused  # type: ignore[assignment]
            self.apply_be16_n = self._be16_refused
        elif self._nk is not None:
            # closures over the parameter array: calling them allocates nothing
            self.apply_be16, self.apply_be16_n = self._nk
        elif self.burst3 is not None:
            self.apply_be16 = self._be16_3
            self.apply_be16_n = self._be16_3n

    def _set_offset(self, k, coeffs, t_range, t_ref, what, sub=0):
        # Offset polynomial k in fixed point and its exponent in update()'s division
        # (Boff = off * gain * 2**S). |offset - raw_mid| <= 2**(K+1) keeps |Boff| <= 2**29.
        op = Poly(coeffs, t_range, t_ref, limit=_VALUE_BITS, max_frac=self._s + self._sc[k].frac, sub=sub)
        o_min, o_max = op.extrema()
        reach = max(-o_min, o_max)
        if reach > (2 << self._k):
            raise ValueError(
                "%s: offset[%d] reaches %r raw LSB from the raw range's middle over t %r: "
                "outside the raw range %r" % (what, k, reach, t_range, self.raw_range)
            )
        self._off[k] = op
        self._eo[k] = self._s + self._sc[k].frac - op.frac

    def _set_fast(self, k):
        # For a constant scale d + e/2**14 (eval_ext), B(t) = O(t) * c with the constant
        # c = 2**eo / (d + e/2**14): q0 = a0 * c and q_j = a_j * c / 2**w, w = eo - L + 1 with
        # 2**(L-1) <= d < 2**L, so c / 2**w is in (1/2, 1] and the q_j keep the offset
        # polynomial's Horner bounds (<= 2**28). B = q0 + (Horner(q) >> (vs - w)).
        sp = self._sc[k]
        if sp._deg:
            self._fd[k] = -1
            return
        d = sp.eval_ext(0)
        e = sp.ext
        g = _gain_num(self._eg[k], d)
        if e:
            g -= mul_shift(g, e, _EXT) // d
        g = (g + 1) >> 1
        self._gh[k] = g >> self._k
        self._gl[k] = g & self._kmask
        op = self._off[k]
        L = 1
        while (1 << L) <= d:
            L += 1
        j = 4 * k
        q = div_pow2(op._a0, self._eo[k], d)  # |q| <= 2**29: update()'s offset term bound
        if e:
            q -= mul_shift(q, e, _EXT) // d
        self._fq[j] = q
        i = 1
        while i <= op._deg:
            q = div_pow2(op._a[i], L - 1, d)  # <= |a_i| <= 2**28
            if e:
                q -= mul_shift(q, e, _EXT) // d
            self._fq[j + i] = q
            i += 1
        self._fs[k] = op._vs - (self._eo[k] - L + 1)
        self._fd[k] = op._deg
        self._fxm = op._mid  # the same t range, so the same x, for every axis
        self._fxl = _LIMB - op._h if op._h < _LIMB else 0
        self._fxs = op._h - _LIMB if op._h >= _LIMB else 0

    def update(self, t):
        """Set the temperature reading used by apply(); zero allocation."""
        if t < self._t_lo:
            t = self._t_lo
            self.clamped += 1
        elif t > self._t_hi:
            t = self._t_hi
            self.clamped += 1
        if t == self._t:
            return
        self._t = t
        for k in range(self.axes):
            f = self._fd[k]
            if f >= 0:
                # constant scale: the gain is fixed, the offset term is Horner's (_set_fast)
                j = 4 * k
                q = self._fq
                b = q[j]
                if f:
                    op = self._off[k]
                    x = t - op._mid
                    h = op._h
                    acc = q[j + f]
                    while f > 1:
                        f -= 1
                        acc = q[j + f] + mul_shift(acc, x, h)
                    acc = mul_shift(acc, x, h)
                    sh = self._fs[k]
                    # |acc >> sh| or |acc << -sh|: the variable part of B, <= 2**29
                    b += (acc >> sh) if sh >= 0 else (acc << -sh)
                self._b[k] = b
                continue
            sp = self._sc[k]
            d = sp.eval_ext(t)
            e = sp.ext
            # the scale is d + e / 2**14: 2**e/(d + e') = q * (1 - e'/d + ...) with q = 2**e/d,
            # so the quotients below drop q * e / (2**14 * d) (at most 2**29 * 2**14 / 2**14 /
            # 2**24 = 32 units; the second-order term is below 2**-18 units)
            o = self._off[k].eval(t)
            wg = self._wg[k]
            wo = self._eo[k] - _WIDE
            if wg >= 0 and wo >= 0:
                # d >= 2**24 here (set-up): divide by its top 20 bits dh in 10-bit steps and
                # correct for the rest, f / 2**21 of a unit of dh, as for e above (first order:
                # the second-order term is below 2**29 / 2**34 units)
                dh = d >> _WIDE
                f = ((d & _WIDE_MASK) << _EXT) + e
                g = _div_wide(_GAIN_NUM, wg, dh)  # 2**eg / d, < 2**29
                if f:
                    g -= _corr21(g, f, dh)
                b = _div_wide(o, wo, dh)  # |b| <= 2**29
                if f:
                    b -= _corr21(b, f, dh)
            else:
                g = _gain_num(self._eg[k], d)  # < 2**29
                if e:
                    g -= mul_shift(g, e, _EXT) // d  # mul_shift: 2**29 * 2**14 / 2**14 < 2**30
                b = div_pow2(o, self._eo[k], d)  # |b| <= 2**29
                if e:
                    b -= mul_shift(b, e, _EXT) // d
            g = (g + 1) >> 1
            self._gh[k] = g >> self._k
            self._gl[k] = g & self._kmask
            # floor, not round: apply()'s floor of r*gl/2**15 errs the other way, so the two
            # truncations partly cancel
            self._b[k] = b
        self._fill_burst3()

    def _fill_burst3(self):
        p = self.burst3
        if p is not None:
            j = 0
            for k in range(3):
                p[j] = self._gh[k]
                p[j + 1] = self._gl[k]
                p[j + 2] = self._b[k] - self._half
                j += 3
            p[9] = self._k
            p[10] = self._s
            q = self._q0
            if q is not None:
                # the same numbers per axis for _be16_3 (no tuple: update() allocates nothing)
                q[0] = p[0]
                q[1] = p[1]
                q[2] = p[2]
                q = self._q1
                q[0] = p[3]  # type: ignore[index]  # set with _q0
                q[1] = p[4]  # type: ignore[index]
                q[2] = p[5]  # type: ignore[index]
                q = self._q2
                q[0] = p[6]  # type: ignore[index]
                q[1] = p[7]  # type: ignore[index]
                q[2] = p[8]  # type: ignore[index]

    def export(self):
        """(t_lo, t_hi, fxm, fxl, fxs, half, k, s, gh, gl, fd, fs, fq): every number ``update()``
        and the 3-axis burst path read, for 3 signed int16 axes whose scales do not vary with t;
        None for any other Compensator. ``tempcomp.mpu6xxx_tc.compiled()`` saves them, and
        ``tempcomp.mpu6xxx_rt`` resumes them without this module (the same integers)."""
        if self.burst3 is None or min(self._fd) < 0:
            return None
        return (self._t_lo, self._t_hi, self._fxm, self._fxl, self._fxs, self._half, self._k, self._s,
                tuple(self._gh), tuple(self._gl), tuple(self._fd), tuple(self._fs), tuple(self._fq))

    def _update_fast(self, t):
        # update() when every scale is constant: the offset terms by Horner (_set_fast's
        # polynomials, the same arithmetic as update()'s branch for them), mul_shift inline
        if t < self._t_lo:
            t = self._t_lo
            self.clamped += 1
        elif t > self._t_hi:
            t = self._t_hi
            self.clamped += 1
        if t == self._t:
            return
        self._t = t
        # mul_shift(acc, x, h) with x << (14 - h) when h < 14, so the h >= 14 form serves
        # both: floor(acc * x * 2**(14-h) / 2**14) = floor(acc * x / 2**h), and |x| <= 2**14
        x = (t - self._fxm) << self._fxl
        hs = self._fxs
        q = self._fq
        fd = self._fd
        fs = self._fs
        bb = self._b
        p = self.burst3
        half = self._half
        n = self.axes
        k = 0
        j = 0
        while k < n:
            f = fd[k]
            b = q[j]
            if f:
                acc = q[j + f]
                while True:
                    # |acc| <= 2**29, each product <= 2**(29 + 2/3) (module notes): the sum < 2**30
                    acc = ((acc >> _LIMB) * x + (((acc & _LIMB_MASK) * x) >> _LIMB)) >> hs
                    f -= 1
                    if not f:
                        break
                    acc += q[j + f]
                sh = fs[k]
                b += (acc >> sh) if sh >= 0 else (acc << -sh)
            bb[k] = b
            if p is not None:
                p[3 * k + 2] = b - half
            k += 1
            j += 4
        q = self._q0
        if q is not None:
            q[2] = bb[0] - half
            self._q1[2] = bb[1] - half  # type: ignore[index]  # set with _q0
            self._q2[2] = bb[2] - half  # type: ignore[index]

    def apply(self, raw, axis=0):
        """Compensated value of one raw code (inside raw_range) in output units."""
        r = raw - self._mid
        return (r * self._gh[axis] + ((r * self._gl[axis]) >> self._k) - self._b[axis] + self._half) >> self._s

    def apply_be16(self, buf, out):
        """Compensate big-endian int16 words (axis i at buf[2i:2i+2]) into out[i]."""
        gh = self._gh
        gl = self._gl
        b = self._b
        s = self._s
        half = self._half
        mid = self._mid
        k = self._k
        i = 0
        j = 0
        n = self.axes
        while i < n:
            v = buf[j] << 8 | buf[j + 1]
            if v & 0x8000:
                v -= 0x10000
            r = v - mid
            out[i] = (r * gh[i] + ((r * gl[i]) >> k) - b[i] + half) >> s
            i += 1
            j += 2

    def _be16_refused(self, buf, out, n=1, stride=6):
        raise ValueError(
            "apply_be16 decodes signed int16 words; raw_range %r is not centred on 0: use apply()"
            % (self.raw_range,)
        )

    def _check_n(self, buf, out, n, stride):
        # checked before any word is read: the native kernels index the buffers unchecked
        if n < 0 or stride < 2 * self.axes:
            raise ValueError("apply_be16_n: need n >= 0 and stride >= %d, got n=%r stride=%r" % (2 * self.axes, n, stride))
        if n and (n - 1) * stride + 2 * self.axes > len(buf):
            raise ValueError("apply_be16_n: %d samples at stride %d need %d bytes, buf has %d" % (n, stride, (n - 1) * stride + 2 * self.axes, len(buf)))
        if self.axes * n > len(out):
            raise ValueError("apply_be16_n: %d samples need %d outputs, out has %d" % (n, self.axes * n, len(out)))

    def apply_be16_n(self, buf, out, n, stride=6):
        """Compensate n bursts (sample i's words at buf[i*stride:]) into out[axes*i + axis].

        The same numbers as n calls of apply_be16 on buf[i*stride:]; zero allocation.
        """
        self._check_n(buf, out, n, stride)
        gh = self._gh
        gl = self._gl
        b = self._b
        s = self._s
        half = self._half
        k = self._k
        na = self.axes
        m = na * n
        i = 0
        j = 0
        while i < m:
            a = 0
            while a < na:
                v = ((buf[j + 2 * a] << 8 | buf[j + 2 * a + 1]) ^ 0x8000) - 0x8000
                out[i + a] = (v * gh[a] + ((v * gl[a]) >> k) - b[a] + half) >> s
                a += 1
            i += na
            j += stride

    def _be16_3n(self, buf, out, n, stride=6):
        # apply_be16_n for the unrolled 3-axis case: _be16_3's arithmetic (and bound) per sample
        self._check_n(buf, out, n, stride)
        g0, l0, b0, g1, l1, b1, g2, l2, b2, k, s = self.burst3  # type: ignore[misc]  # set when bound
        i = 0
        j = 0
        m = 3 * n
        while i < m:
            v = ((buf[j] << 8 | buf[j + 1]) ^ 0x8000) - 0x8000
            out[i] = (v * g0 + ((v * l0) >> k) - b0) >> s
            v = ((buf[j + 2] << 8 | buf[j + 3]) ^ 0x8000) - 0x8000
            out[i + 1] = (v * g1 + ((v * l1) >> k) - b1) >> s
            v = ((buf[j + 4] << 8 | buf[j + 5]) ^ 0x8000) - 0x8000
            out[i + 2] = (v * g2 + ((v * l2) >> k) - b2) >> s
            i += 3
            j += stride

    def _be16_3(self, buf, out):
        # The common 3-axis int16 burst, unrolled, the rounding half folded into the offset term.
        # Each axis unpacks its own three numbers (_q0.._q2): 8 locals and 3 stack slots fit the
        # 11 words a frame may take on the C stack; unpacking all 11 numbers at once took the
        # frame from the heap on every call (py/objfun.c: a third of the sample on the M0+),
        # and reading each from the flat list costs the VM a subscript apiece. k is 15 here
        # (K for a raw range centred on 0). Bound: |v*g| <= 2**28, |(v*l) >> 15| < 2**15,
        # |c| <= 2**29 + 2**23: sum < 2**30.
        s = self._s
        g, lo, c = self._q0  # type: ignore[misc]  # set when this method is bound
        v = ((buf[0] << 8 | buf[1]) ^ 0x8000) - 0x8000
        out[0] = (v * g + ((v * lo) >> 15) - c) >> s
        g, lo, c = self._q1  # type: ignore[misc]
        v = ((buf[2] << 8 | buf[3]) ^ 0x8000) - 0x8000
        out[1] = (v * g + ((v * lo) >> 15) - c) >> s
        g, lo, c = self._q2  # type: ignore[misc]
        v = ((buf[4] << 8 | buf[5]) ^ 0x8000) - 0x8000
        out[2] = (v * g + ((v * lo) >> 15) - c) >> s

    def value(self, t, raw, axis=0):
        """update(t) then apply(raw, axis)."""
        self.update(t)
        return self.apply(raw, axis)

    def shift_offset(self, axis, delta_raw):
        """Add delta_raw (raw LSB, float ok) to offset(t) from now on (set-up, e.g. a re-zero)."""
        op = self._off[axis]
        # rebuild the offset polynomial with the shifted constant term; set-up only
        c = list(op._coeffs_mid)
        c[0] += float(delta_raw)
        lo, hi = op.t_range
        self._set_offset(axis, c, op.t_range, (lo + hi) // 2, "offset shift %r" % (delta_raw,))
        self._set_fast(axis)
        t = self._t
        self._t = None
        self.update(t)


_native = None  # None: native kernels where the interpreter has them; True/False: forced
_nmod = None  # the kernel module once imported
_ntried = False


def _kernels():
    # imported on first use, so boot RAM holds no native code until a 3-axis path is built
    global _nmod, _ntried
    if not _ntried:
        _ntried = True
        try:
            try:
                from tempcomp import native
            except ValueError:
                # an armv7m .mpy on a Cortex-M0+ (RP2040): the armv6m build beside it (make dist)
                from tempcomp import native_m0 as native  # pyright: ignore[reportAttributeAccessIssue]

            _nmod = native
        except (ImportError, SyntaxError, ValueError, NotImplementedError):
            # CPython (no micropython module), a port without the viper emitter, or a .mpy
            # compiled for another architecture
            pass
    return _nmod


def use_native(on=None):
    """Choose the 3-axis int16 kernels of Compensators built from now on.

    None (default): native (viper) where the interpreter has the emitter, else pure Python;
    True: native or ValueError; False: pure Python. Returns True when native will be used.
    Both give bit-identical results.
    """
    global _native
    if on and _kernels() is None:
        raise ValueError("use_native(True): this interpreter has no @micropython.viper emitter")
    _native = None if on is None else bool(on)
    return _native is not False and _kernels() is not None


def _div_wide(num, e, d):
    """floor(num * 2**e / d) for 0 < d < 2**20, |num| <= 2**28, e >= 0, the quotient < 2**29.

    Ten bits a step: the remainder stays below d, so (d - 1) << 10 < 2**30.
    """
    q = num // d
    r = num - q * d
    while e >= 10:
        r <<= 10
        c = r // d
        r -= c * d
        q = (q << 10) + c
        e -= 10
    if e:
        r <<= e
        c = r // d
        q = (q << e) + c
    return q


def _corr21(q, f, d):
    # floor(floor(q * f / 2**21) / d) within a unit, |q| < 2**29, 0 <= f < 2**21: the two
    # mul_shift calls stay < 2**29 + 2**22 (limbs of q: 2**15 * 2**7 << 7 and 2**15 * 2**14)
    return (mul_shift(q, f >> _EXT, _WIDE) + (mul_shift(q, f & _EXT_MASK, _EXT) >> _WIDE)) // d


def _gain_num(e, d):
    # floor(2**e / d): start from 2**28 so the first quotient already has leading bits
    if e <= _VALUE_BITS:
        return div_pow2(1 << e, 0, d)
    return div_pow2(1 << _VALUE_BITS, e - _VALUE_BITS, d)
