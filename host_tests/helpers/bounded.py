"""An int that fails the test when any arithmetic result leaves MicroPython's small-int range.

Feeding BInt values through on-device code checks every intermediate of that run against
[-2**30, 2**30 - 1] (32-bit MicroPython small ints): an exact, op-by-op check on CPython that
complements the VM's heap_lock check (which only says *that* something allocated).
"""

LO = -(1 << 30)
HI = (1 << 30) - 1


class BoundError(AssertionError):
    pass


def _chk(v, op, a, b):
    if isinstance(v, bool) or not isinstance(v, int):
        return v
    if v < LO or v > HI:
        raise BoundError("%s(%d, %d) = %d leaves the small-int range" % (op, a, b, v))
    return BInt(v)


class BInt(int):
    def __new__(cls, v):
        v = int(v)
        if v < LO or v > HI:
            raise BoundError("value %d leaves the small-int range" % v)
        return int.__new__(cls, v)

    def _op(name):  # noqa: N805 - builds methods
        def f(self, other):
            r = getattr(int, name)(int(self), other)
            return _chk(r, name, int(self), other)

        return f

    for _n in (
        "__add__", "__radd__", "__sub__", "__rsub__", "__mul__", "__rmul__",
        "__lshift__", "__rshift__", "__rlshift__", "__rrshift__", "__and__", "__rand__",
        "__or__", "__ror__", "__floordiv__", "__rfloordiv__", "__mod__", "__rmod__",
    ):
        locals()[_n] = _op(_n)
    del _n

    def __neg__(self):
        return _chk(-int(self), "neg", int(self), 0)

    def __abs__(self):
        return _chk(abs(int(self)), "abs", int(self), 0)


def bind(obj, names):
    """Replace int attributes / list items of obj named in names with BInt versions."""
    for n in names:
        v = getattr(obj, n)
        if isinstance(v, list):
            setattr(obj, n, [BInt(x) for x in v])
        elif isinstance(v, tuple):
            setattr(obj, n, tuple(BInt(x) for x in v))
        else:
            setattr(obj, n, BInt(v))
