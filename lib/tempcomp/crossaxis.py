"""Cross-axis / misalignment correction of three compensated axes: out = (I + E(T)) v, fixed point.

Applied after the per-axis compensation (``tempcomp.an12760``): v is that output (any
units, |v_i| < 2**18), E the small correction matrix fitted on the host
(``python -m tools.fit sixpos``: ``cross_correction`` = (I + N)^-1 - I, |E_ij| < 1/16).
E may follow a temperature law E(T) = E0 + E1 dT + E2 dT**2 + E3 dT**3, dT = T - Troom, fitted
from the six positions at several temperatures: the cross-axis sensitivity of MEMS parts
drifts (1e-4/degC leaves 6.5 mg at 65 degC from Troom), so a matrix held at Troom is not
enough over -40..85 degC.

Fixed point: E is held as e_ij = round(E_ij * 2**22) (|e| < 2**18). Per temperature reading
(``update(code)``), each e_ij(T) comes from ``tempcomp.fixedpoint.Poly`` (Horner in integers,
partial sums <= 2**28) in the same temperature code the AN12760 step takes. Per sample, v_j
is split as vh * 2**8 + vl with 0 <= vl < 256, so |vh * e| <= 2**10 * 2**18 = 2**28 and
|vl * e| < 2**26; the three terms of a row plus the rounding half sum below 3 * (2**28 +
2**18) + 2**13 < 2**30. Error against float64 (I + E(T)) v: 0.5 (rounding) + sum |v_j| x the
coefficient error, which is 0.5 unit of 2**-22 for a constant matrix (< 0.6 output LSB at full
scale) and, with a temperature law, up to about 3.3 units once Horner's rounding is in
(measured over 200 random sets of 40 laws; < 4 asserted: < 1.25 LSB at full scale, < 0.55 for
|v| < 2**14; docs/adi_nxp.md).

Usage::

    from tempcomp.crossaxis import CrossAxis
    ca = CrossAxis([[0.0, -0.004, 0.002], [0.004, 0.0, 0.001], [-0.002, -0.001, 0.0]])
    ca.apply(v, out)       # v, out: sequences of 3 ints (out may be v); zero allocation

    # with a temperature law (E1 per degC) in the MPU-6500's temperature code
    ca = CrossAxis(e0, law=[e1], t_span_c=(-40, 85), t_scale=1 / 333.87, t_offset=21.0)
    ca.update(code)        # once per temperature reading, like AN12760.update; zero allocation
    ca.apply(v, out)

Record (``tempcomp.record`` kind KIND_CROSS): the nine E_ij row by row (constant matrix,
the original layout, still read); with a law, those nine (E0) then ``t_room_c, t_lo_c,
t_hi_c, degree`` and the nine E_ij of each order 1..degree (per degC**k).
"""

from tempcomp import record
from tempcomp.fixedpoint import Poly, code_span, shift_basis

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


_F = const(22)  # coefficient fraction bits
_SPLIT = const(8)
_LOW = const(0xFF)
_HALF = const(1 << (_F - _SPLIT - 1))
_E_MAX = 1.0 / 16
_HEAD = const(4)  # t_room_c, t_lo_c, t_hi_c, degree


def _nine(e, what):
    if len(e) == 3:
        e = [c for row in e for c in row]
    if len(e) != 9:
        raise ValueError("%s needs 9 values (3x3), got %d" % (what, len(e)))
    out = [float(v) for v in e]
    for i in range(9):
        v = out[i]
        if v != v or v in (float("inf"), float("-inf")):
            raise ValueError("%s E[%d][%d] = %r is not finite" % (what, i // 3, i % 3, v))
    return out


class CrossAxis:
    """3x3 correction out = v + E(T) v.

    e: E (at t_room) as nine floats (row-major sequence or rows). law: optional sequence of
    1..3 matrices E1..E3 (per degC**k) for the temperature law; t_span_c: the calibrated
    span (the law is held at its edges beyond it); t_scale/t_offset: temperature code ->
    degC as for ``AN12760`` (T = code * t_scale + t_offset).
    """

    def __init__(self, e, law=None, t_room=25.0, t_span_c=(-40.0, 85.0), t_scale=1.0, t_offset=0.0):
        self.e = _nine(e, "cross-axis correction")
        self.law = [] if law is None else [_nine(m, "cross-axis law order %d" % (k + 1)) for k, m in enumerate(law)]
        if len(self.law) > 3:
            raise ValueError("cross-axis law: at most 3rd order (got %d matrices)" % len(self.law))
        self.t_room = float(t_room)
        self.t_scale = float(t_scale)
        self.t_offset = float(t_offset)
        lo_c, hi_c = float(t_span_c[0]), float(t_span_c[1])
        if not hi_c > lo_c:
            raise ValueError("t_span_c %r: upper end must exceed lower end" % (t_span_c,))
        self.t_span_c = (lo_c, hi_c)
        self.clamped = 0
        self._polys = None
        if not self.law:
            q = []
            for i in range(9):
                v = self.e[i]
                if not -_E_MAX < v < _E_MAX:
                    raise ValueError("cross-axis term E[%d][%d] = %r is outside +-1/16: check the fit"
                                     % (i // 3, i % 3, v))
                q.append(int(round(v * (1 << _F))))
            self._q = q
            return
        if self.t_scale == 0 or self.t_scale != self.t_scale:
            raise ValueError("t_scale (degC per temperature code) must be non-zero")
        lo, hi = code_span(lo_c, hi_c, self.t_offset, self.t_scale)
        code_room = (self.t_room - self.t_offset) / self.t_scale
        ref = int(round(code_room))
        polys = []
        for i in range(9):
            # coefficients of powers of (code - code_room): E_k * t_scale**k
            c = [self.e[i]]
            p = 1.0
            for m in self.law:
                p *= self.t_scale
                c.append(m[i] * p)
            pl = Poly(shift_basis(c, code_room, ref), (lo, hi), ref, max_frac=_F)
            if pl.frac != _F:
                raise ValueError("cross-axis law E[%d][%d]: coefficients too large for fixed point" % (i // 3, i % 3))
            a, b = pl.extrema()
            # 2 units of 2**-22 margin for Horner's rounding keep |e| < 2**18
            m = _E_MAX - 2.0 / (1 << _F)
            if not (-m < a and b < m):
                raise ValueError("cross-axis term E[%d][%d] reaches %r..%r over %r..%r degC, outside +-1/16: "
                                 "check the fit" % (i // 3, i % 3, a, b, lo_c, hi_c))
            polys.append(pl)
        self._polys = polys
        self._lo = lo
        self._hi = hi
        self._q = [0] * 9
        self.update(ref)
        self.clamped = 0

    def code_of(self, temp_c):
        """Temperature code (int) at temp_c degC (set-up and tests)."""
        return int(round((temp_c - self.t_offset) / self.t_scale))

    def update(self, code):
        """New temperature reading (the part's code); zero allocation. No-op without a law."""
        polys = self._polys
        if polys is None:
            return
        if code < self._lo:
            code = self._lo
            self.clamped += 1
        elif code > self._hi:
            code = self._hi
            self.clamped += 1
        q = self._q
        i = 0
        while i < 9:
            q[i] = polys[i].eval(code)
            i += 1

    def apply(self, v, out):
        """out[i] = v[i] + sum_j E[i][j] v[j], rounded; |v[i]| < 2**18; zero allocation."""
        q = self._q
        x = v[0]
        y = v[1]
        z = v[2]
        xh = x >> _SPLIT
        xl = x & _LOW
        yh = y >> _SPLIT
        yl = y & _LOW
        zh = z >> _SPLIT
        zl = z & _LOW
        i = 0
        while i < 3:
            k = 3 * i
            a = q[k]
            b = q[k + 1]
            c = q[k + 2]
            # each high product <= 2**28 in magnitude, each low one < 2**18: the sum < 2**30
            acc = xh * a + ((xl * a) >> _SPLIT) + yh * b + ((yl * b) >> _SPLIT) + zh * c + ((zl * c) >> _SPLIT)
            w = (acc + _HALF) >> (_F - _SPLIT)
            if i == 0:
                out[0] = x + w
            elif i == 1:
                out[1] = y + w
            else:
                out[2] = z + w
            i += 1

    def matrix(self, temp_c):
        """Float E at temp_c degC (law held at the span's edges; set-up and checks)."""
        lo, hi = self.t_span_c
        d = min(max(float(temp_c), lo), hi) - self.t_room
        out = list(self.e)
        p = 1.0
        for m in self.law:
            p *= d
            for i in range(9):
                out[i] += m[i] * p
        return out

    def to_record(self):
        """The coefficient record (list of ints): 9 values without a law, 13 + 9 * degree with one."""
        v = list(self.e)
        if self.law:
            v += [self.t_room, self.t_span_c[0], self.t_span_c[1], float(len(self.law))]
            for m in self.law:
                v += m
        return record.pack(record.KIND_CROSS, v)

    @classmethod
    def from_record(cls, ints, t_scale=1.0, t_offset=0.0):
        """Build from a KIND_CROSS record (either layout); t_scale/t_offset as for AN12760."""
        v = record.unpack(ints, record.KIND_CROSS)
        if len(v) == 9:
            return cls(v)
        if len(v) < 9 + _HEAD:
            raise ValueError("cross-axis record: %d values are neither 9 nor 9 + 4 + 9 * degree" % len(v))
        d = int(v[12])
        if d < 1 or d > 3 or len(v) != 9 + _HEAD + 9 * d:
            raise ValueError("cross-axis record: %d values do not hold a degree %r law" % (len(v), v[12]))
        law = [v[13 + 9 * k : 22 + 9 * k] for k in range(d)]
        return cls(v[:9], law=law, t_room=v[9], t_span_c=(v[10], v[11]), t_scale=t_scale, t_offset=t_offset)
