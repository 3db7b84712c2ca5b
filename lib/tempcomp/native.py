"""Native (@micropython.viper) kernels of the 3-axis int16 burst path of ``fixedpoint``.

Imported by ``fixedpoint`` on first use where the interpreter has the viper emitter (MicroPython
firmware on Cortex-M, the unix ports); importing it elsewhere raises SyntaxError or ImportError
and the pure-Python path is used. The arithmetic is the pure path's, word for word:

    v = signed int16 of the big-endian word
    out = (v * g + ((v * l) >> k) - c) >> s

The parameter words are read as 32-bit and sign-extended, so the same code is right on 64-bit
machines (the unix ports). Bound (fixedpoint's set-up): |v| <= 2**15, |g| <= 2**13, 0 <= l < 2**15, |c| <= 2**29 + 2**23:
|v*g| <= 2**28, |v*l| < 2**30, the sum < 2**30, so a 32-bit machine word never wraps and the
results are bit-identical to Python's unbounded integers.
"""

# ruff: noqa: F821
# pyright: reportUndefinedVariable=false, reportAttributeAccessIssue=false, reportIndexIssue=false
# (ptr8/ptr32 are viper built-ins)

import array

import micropython

_P = 11  # g0 l0 c0 g1 l1 c1 g2 l2 c2 k s: the pure path's list, as 32-bit words


def params():
    """The 32-bit parameter array fixedpoint.update() fills (c: offset term minus half)."""
    return array.array("i", [0] * _P)


def _thumb():
    # the asm_thumb batch kernel: only where it exists (ARM) and after it reproduced the viper
    # kernel here; (kernel, type words) or False
    try:
        from tempcomp import thumb
    except (ImportError, SyntaxError, ValueError, NotImplementedError):
        return False
    return thumb.checked(_many) or False


_t = None  # (asm kernel, its type words), False where there is none: tried once


def kernels(p, check):
    """(apply_be16, apply_be16_n) over the parameter array p; check(buf, out, n, stride)
    raises the clear error of a bad batch call (fixedpoint's own check)."""
    global _t
    if _t is None:
        _t = _thumb()

    @micropython.viper
    def one(buf, out):
        b = ptr8(buf)
        q = ptr32(p)
        k = q[9]
        s = q[10]
        e = 1
        e <<= 31  # (w ^ e) - e: a signed 32-bit word on a 64-bit machine too (no-op on 32-bit)
        v = ((b[0] << 8 | b[1]) ^ 0x8000) - 0x8000
        out[0] = (v * q[0] + ((v * q[1]) >> k) - ((q[2] ^ e) - e)) >> s
        v = ((b[2] << 8 | b[3]) ^ 0x8000) - 0x8000
        out[1] = (v * q[3] + ((v * q[4]) >> k) - ((q[5] ^ e) - e)) >> s
        v = ((b[4] << 8 | b[5]) ^ 0x8000) - 0x8000
        out[2] = (v * q[6] + ((v * q[7]) >> k) - ((q[8] ^ e) - e)) >> s

    # Default arguments, not closure cells, carry p and check: a closure over more than one cell
    # called with 4 arguments builds its argument array on the heap (MemoryError under heap_lock)
    def checked(buf, out, n, stride=6, p=p, check=check):
        # what the asm kernel refuses: the clear error, or any other buffer and sequence
        check(buf, out, n, stride)
        if n:
            _many(p, buf, out, n, stride)

    if _t is False:
        return one, checked
    return one, _batch(p, _t[0], _t[1], checked)


def _batch(p, t, words, checked):
    # apply_be16_n where the asm kernel is: one call to it with [buf, out, p, words] does the
    # checks and the loop (thumb.batch); what it refuses goes to checked(). The list and the
    # kernel are default arguments: a native function reads those without a call. The list
    # keeps the last buf and out referenced until the next call.
    pr = [None, None, p, words]

    @micropython.native
    def many(buf, out, n, stride=6, pr=pr, t=t, checked=checked):
        pr[0] = buf
        pr[1] = out
        if t(pr, n, stride):
            checked(buf, out, n, stride)

    return many


@micropython.viper
def _word(a) -> int:
    return ptr32(a)[1]


def int32(a):
    # True when array a stores 32-bit two's-complement words (typecode i, or l on 32-bit):
    # tempcomp.augment_native's check of its output arrays
    x = a[0]
    y = a[1]
    try:
        a[0] = 0x12345
        a[1] = -2
        ok = _word(a) == -2 and a[1] == -2 and a[0] == 0x12345
    except (OverflowError, TypeError):
        ok = False
    a[0] = x
    a[1] = y
    return ok


@micropython.viper
def _many(p, buf, out, n: int, stride: int):
    # any out sequence: stored through its own item assignment
    b = ptr8(buf)
    q = ptr32(p)
    k = q[9]
    s = q[10]
    e = 1
    e <<= 31
    c0 = (q[2] ^ e) - e
    c1 = (q[5] ^ e) - e
    c2 = (q[8] ^ e) - e
    i = 0
    j = 0
    m = 3 * n
    while i < m:
        v = ((b[j] << 8 | b[j + 1]) ^ 0x8000) - 0x8000
        out[i] = (v * q[0] + ((v * q[1]) >> k) - c0) >> s
        v = ((b[j + 2] << 8 | b[j + 3]) ^ 0x8000) - 0x8000
        out[i + 1] = (v * q[3] + ((v * q[4]) >> k) - c1) >> s
        v = ((b[j + 4] << 8 | b[j + 5]) ^ 0x8000) - 0x8000
        out[i + 2] = (v * q[6] + ((v * q[7]) >> k) - c2) >> s
        i += 3
        j += stride
