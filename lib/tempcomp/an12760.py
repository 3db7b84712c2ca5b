"""Accelerometer offset/TCO and sensitivity/TCS compensation, NXP AN12760 eq. 11 (cubic form).

Per axis, from the raw count and the part's own temperature reading::

    acc = (raw_mg - [Off + TCO1 dT + TCO2 dT**2 + TCO3 dT**3])
          / ((1 + SENtol) * (1 + TCS1 dT + TCS2 dT**2 + TCS3 dT**3)),    dT = T - Troom

with raw_mg = raw * 1000 / counts_per_g (AN12760 eq. 1). Works with any accelerometer that
gives raw counts and a temperature code: the caller states counts per g and the linear
code -> degC mapping T = code * t_scale + t_offset (MPU-6050: t_scale=1/340, t_offset=36.53;
a part reporting whole degC: t_scale=1, t_offset=0). The arithmetic is the shared fixed-point
core (``tempcomp.fixedpoint``): integers only and zero allocation per sample.

Usage::

    from tempcomp.an12760 import AN12760
    #       Off mg  TCO mg/C^k  SENtol  TCS 1/C^k   (one tuple per axis)
    axes = [(-20.0, (1.0,), 0.0264, (-0.001,))]
    acc = AN12760(axes, counts_per_g=16384, t_span_c=(-40, 105),
                  t_scale=1 / 340, t_offset=36.53)
    acc.update(temp_code)            # once per temperature reading
    mg = acc.apply(raw_count, 0)     # compensated milli-g (out_per_g=1000), an int

Coefficient record (``tempcomp.record`` kind KIND_AN12760), values in order:
``t_room_c, t_lo_c, t_hi_c, n_axes`` then per axis
``offset_mg, tco1, tco2, tco3 (mg/degC^k), sen_tol, tcs1, tcs2, tcs3 (1/degC^k)``.
"""

from tempcomp import record
from tempcomp.fixedpoint import CLAMP, Compensator, code_span, shift_basis

_PER_AXIS = 8


def _tuple3(v, name):
    # a number means the linear law of eq. 4/10; a sequence gives 1st..3rd order terms
    if isinstance(v, (int, float)):
        v = (v,)
    if len(v) > 3:
        raise ValueError("%s: at most 3rd order (got %d terms)" % (name, len(v)))
    out = [0.0, 0.0, 0.0]
    for i in range(len(v)):
        out[i] = float(v[i])
    return out


def _poly_mul(a, b):
    out = [0.0] * (len(a) + len(b) - 1)
    for i in range(len(a)):
        for j in range(len(b)):
            out[i + j] += a[i] * b[j]
    return out


class AN12760:
    """AN12760 compensation of N accelerometer axes sharing one temperature reading.

    axes: per axis ``(offset_mg, tco, sen_tol, tcs)``; tco/tcs a number or 1..3 terms
    (mg/degC^k and 1/degC^k). t_span_c: calibrated temperature span (degC).
    out_per_g: output units per g (1000: mg, 10000: 0.1 mg). raw_range: the part's codes.
    """

    def __init__(
        self,
        axes,
        counts_per_g,
        t_span_c,
        t_scale=1.0,
        t_offset=0.0,
        t_room=25.0,
        out_per_g=1000,
        raw_range=(-32768, 32767),
        policy=CLAMP,
        t_in_c=None,
    ):
        if not axes:
            raise ValueError("need at least one axis")
        counts_per_g = float(counts_per_g)
        t_scale = float(t_scale)
        if not counts_per_g > 0:
            raise ValueError("counts_per_g must be positive, got %r" % (counts_per_g,))
        if t_scale == 0 or t_scale != t_scale:
            raise ValueError("t_scale (degC per temperature code) must be non-zero")
        lo_c, hi_c = float(t_span_c[0]), float(t_span_c[1])
        if not hi_c > lo_c:
            raise ValueError("t_span_c %r: upper end must exceed lower end" % (t_span_c,))
        self.coeffs = []
        for k in range(len(axes)):
            a = axes[k]
            if len(a) != 4:
                raise ValueError("axis %d: need (offset_mg, tco, sen_tol, tcs)" % k)
            off = float(a[0])
            tco = _tuple3(a[1], "axis %d tco" % k)
            sen = float(a[2])
            tcs = _tuple3(a[3], "axis %d tcs" % k)
            if not sen > -1.0:
                raise ValueError("axis %d: sen_tol %r makes the sensitivity non-positive" % (k, sen))
            self.coeffs.append((off, tco, sen, tcs))
        self.counts_per_g = counts_per_g
        self.t_scale = t_scale
        self.t_offset = float(t_offset)
        self.t_room = float(t_room)
        self.t_span_c = (lo_c, hi_c)
        self.out_per_g = out_per_g
        # dT = T - Troom = t_scale * (code - code_room): coefficients of powers of
        # (code - code_room), so the fixed-point core works on the raw temperature code
        code_room = (self.t_room - self.t_offset) / t_scale
        ref = int(round(code_room))
        cpm = counts_per_g / 1000.0  # raw counts per mg
        offs = []
        scs = []
        for off, tco, sen, tcs in self.coeffs:
            o = [off * cpm]
            s = [1.0]
            p = 1.0
            for i in range(3):
                p *= t_scale
                o.append(tco[i] * p * cpm)
                s.append(tcs[i] * p)
            s = _poly_mul([counts_per_g * (1.0 + sen)], s)  # counts per g at dT
            # re-expanded about the nearest integer code: the core takes an integer t_ref
            offs.append(_trim(shift_basis(o, code_room, ref)))
            scs.append(_trim(shift_basis(s, code_room, ref)))
        t_cal = code_span(lo_c, hi_c, self.t_offset, t_scale)
        t_in = None
        if t_in_c is not None:
            t_in = code_span(float(t_in_c[0]), float(t_in_c[1]), self.t_offset, t_scale)
        self.comp = Compensator(
            offs, scs, t_cal, t_in=t_in, out_scale=out_per_g, raw_range=raw_range,
            policy=policy, t_ref=ref,
        )
        self.axes = len(axes)
        self.update = self.comp.update
        self.apply = self.comp.apply
        self.apply_be16 = self.comp.apply_be16

    def code_of(self, temp_c):
        """Temperature code (int) the part reports at temp_c degC (set-up and tests)."""
        return int(round((temp_c - self.t_offset) / self.t_scale))

    def apply_all(self, raw, out):
        """Compensate raw[i] (counts, axis i) into out[i] (output units); zero allocation."""
        c = self.comp
        i = 0
        n = self.axes
        while i < n:
            out[i] = c.apply(raw[i], i)
            i += 1

    def to_record(self):
        """The coefficient record (list of ints) for tempcomp.store."""
        v = [self.t_room, self.t_span_c[0], self.t_span_c[1], float(self.axes)]
        for off, tco, sen, tcs in self.coeffs:
            v.append(off)
            v.extend(tco)
            v.append(sen)
            v.extend(tcs)
        return record.pack(record.KIND_AN12760, v)

    @classmethod
    def from_record(cls, ints, counts_per_g, **kw):
        """Build from a coefficient record; kw as for the constructor (t_scale, t_offset...)."""
        axes, t_room, span = decode_record(ints)
        return cls(axes, counts_per_g, span, t_room=t_room, **kw)


def decode_record(ints):
    """(axes, t_room_c, (t_lo_c, t_hi_c)) from a KIND_AN12760 record."""
    v = record.unpack(ints, record.KIND_AN12760)
    if len(v) < 4:
        raise ValueError("AN12760 record too short")
    n = int(v[3])
    if n < 1 or len(v) != 4 + _PER_AXIS * n:
        raise ValueError("AN12760 record: %d values do not hold %r axes" % (len(v), v[3]))
    axes = []
    for k in range(n):
        b = 4 + _PER_AXIS * k
        axes.append((v[b], v[b + 1 : b + 4], v[b + 4], v[b + 5 : b + 8]))
    return axes, v[0], (v[1], v[2])


def _trim(c):
    while len(c) > 1 and c[-1] == 0.0:
        c.pop()
    return c
