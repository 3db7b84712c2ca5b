"""Coefficient records as lists of small ints, for the coefficient store and for JSON.

A record is ``[kind, version, count, m0, e0, m1, e1, ...]``: ``count`` float values, each
stored as a pair (m, e) with value = m * 2**e and |m| < 2**23 (24 significant bits, so a
float32 port holds it exactly). Every int stays far inside the small-int range +-2**30 of
32-bit MicroPython and the 31-bit ints of CircuitPython builds without long ints.

Usage::

    from tempcomp import record
    ints = record.pack(record.KIND_AN12760, [25.0, -40.0, 105.0, -20.0, 1.0])
    values = record.unpack(ints, record.KIND_AN12760)      # [25.0, -40.0, ...]

The record layouts (which value is which) are documented by the module that owns the kind:
``tempcomp.an12760`` and ``tempcomp.adxrs``.
"""

import math

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


VERSION = const(1)
KIND_AN12760 = const(12760)  # per-axis offset/TCO/SENtol/TCS, NXP AN12760 eq. 11 (cubic form)
KIND_ADXRS = const(1049)  # analog gyro null/scale quadratics in VT, ADI AN-1049
KIND_CROSS = const(3)  # 3x3 cross-axis correction matrix
_MANT = const(1 << 23)
_E_LIMIT = const(300)  # exponent sanity bound: any finite double fits


def pack_float(x):
    """(m, e) with x ~= m * 2**e, |m| < 2**23 (round to nearest)."""
    x = float(x)
    if x != x or x in (float("inf"), float("-inf")):
        raise ValueError("record value %r is not finite" % (x,))
    if x == 0.0:
        return 0, 0
    f, e = math.frexp(x)  # x = f * 2**e, 0.5 <= |f| < 1
    m = int(round(math.ldexp(f, 23)))
    e -= 23
    if m >= _MANT or m <= -_MANT:  # rounding carried into bit 23
        m //= 2
        e += 1
    return m, e


def unpack_float(m, e):
    """The float m * 2**e."""
    return math.ldexp(float(m), e)


def pack(kind, values):
    """Record ints for a kind and a sequence of float values."""
    out = [kind, VERSION, len(values)]
    for v in values:
        m, e = pack_float(v)
        out.append(m)
        out.append(e)
    return out


def unpack(ints, kind, count=None):
    """Float values of a record; ValueError naming the problem if it is not a valid one."""
    if len(ints) < 3:
        raise ValueError("coefficient record too short (%d ints)" % len(ints))
    if ints[0] != kind:
        raise ValueError("coefficient record is of kind %r, expected %r" % (ints[0], kind))
    if ints[1] != VERSION:
        raise ValueError("coefficient record version %r not supported (want %d)" % (ints[1], VERSION))
    n = ints[2]
    if count is not None and n != count:
        raise ValueError("coefficient record holds %r values, expected %d" % (n, count))
    if len(ints) != 3 + 2 * n:
        raise ValueError("coefficient record length %d does not match its count %r" % (len(ints), n))
    vals = []
    for i in range(n):
        m = ints[3 + 2 * i]
        e = ints[4 + 2 * i]
        if not (-_MANT < m < _MANT) or not (-_E_LIMIT < e < _E_LIMIT):
            raise ValueError("coefficient record value %d is corrupt (%r, %r)" % (i, m, e))
        vals.append(unpack_float(m, e))
    return vals
