"""Cross-axis / misalignment correction of three compensated axes: out = (I + E) v, fixed point.

Applied after the per-axis compensation (``tempcomp.an12760``): v is that output (any
units, |v_i| < 2**18), E the small correction matrix fitted on the host
(``python -m tools.fit sixpos``: ``cross_correction`` = (I + N)^-1 - I, |E_ij| < 1/16).

E is held as e_ij = round(E_ij * 2**20) (|e| <= 2**16). v_j is split as vh * 2**8 + vl with
0 <= vl < 256, so |vh * e| <= 2**10 * 2**16 and vl * e < 2**24; the three terms of a row sum
below 2**29 before the final shift. Worst error: 0.5 (rounding) + 3 * 2**-21 * 2**18
(coefficient rounding) < 0.9 output LSB at full scale, < 0.51 LSB for |v| < 2**14.

Usage::

    from tempcomp.crossaxis import CrossAxis
    ca = CrossAxis([[0.0, -0.004, 0.002], [0.004, 0.0, 0.001], [-0.002, -0.001, 0.0]])
    ca.apply(v, out)       # v, out: sequences of 3 ints (out may be v); zero allocation

Record (``tempcomp.record`` kind KIND_CROSS): the nine E_ij row by row.
"""

from tempcomp import record

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


_F = const(20)  # coefficient fraction bits
_SPLIT = const(8)
_LOW = const(0xFF)
_HALF = const(1 << (_F - _SPLIT - 1))
_E_MAX = 1.0 / 16


class CrossAxis:
    """3x3 correction out = v + E v; E as nine floats (row-major sequence or rows)."""

    def __init__(self, e):
        if len(e) == 3:
            e = [c for row in e for c in row]
        if len(e) != 9:
            raise ValueError("cross-axis correction needs 9 values (3x3), got %d" % len(e))
        q = []
        for i in range(9):
            v = float(e[i])
            if v != v or not -_E_MAX < v < _E_MAX:
                raise ValueError("cross-axis term E[%d][%d] = %r is outside +-1/16: check the fit"
                                 % (i // 3, i % 3, v))
            q.append(int(round(v * (1 << _F))))
        self.e = [float(v) for v in e]
        self._q = q

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
            # each product <= 2**26 in magnitude; the sum < 2**29
            acc = xh * a + ((xl * a) >> _SPLIT) + yh * b + ((yl * b) >> _SPLIT) + zh * c + ((zl * c) >> _SPLIT)
            w = (acc + _HALF) >> (_F - _SPLIT)
            if i == 0:
                out[0] = x + w
            elif i == 1:
                out[1] = y + w
            else:
                out[2] = z + w
            i += 1

    def to_record(self):
        """The coefficient record (list of ints)."""
        return record.pack(record.KIND_CROSS, self.e)

    @classmethod
    def from_record(cls, ints):
        return cls(record.unpack(ints, record.KIND_CROSS, 9))
