"""Native kernel of ``tempcomp.augment``: an ``Augmented`` model's per-sample path and the base's
per-reading step in @micropython.viper, on the word array its set-up lays out, with the general
sample's body and the terms' per-reading step in asm_thumb (``tempcomp.augment_thumb``) where the
port has the inline assembler.

Imported by ``augment`` on first use where the interpreter has the viper emitter and 32-bit ints
(MicroPython firmware on Cortex-M); elsewhere the import fails and augment's pure-Python kernel
runs. The arithmetic is the pure kernel's (``augment_pure.apply``, ``step``, ``_general``,
``fixedpoint.Compensator.update``), operation for operation: every intermediate is proven within
+-2**30 there (augment's and fixedpoint's module notes), so 32-bit machine words never wrap and the
results are bit-identical to Python's unbounded integers.

The per-sample entries are the class methods ``Augmented.apply`` and ``apply_be16_n`` (this module's
``apply`` and ``apply_be16_n``): a method called as ``aug.apply(...)`` passes its seven arguments
without copying them to the heap. The base model alone takes the shortest path in ``apply``
itself; a model with terms hands its samples, in one run for a whole burst, to
``augment_thumb.run`` (``augment_vrun.run`` where the port has no inline assembler: ``use_asm``). The
arrays a call reads and writes are checked once (32-bit int arrays, a burst's lengths) and
known after that by their buffer addresses, which the model holds references to.
"""

# ruff: noqa: F821
# pyright: reportUndefinedVariable=false, reportAttributeAccessIssue=false, reportIndexIssue=false
# pyright: reportOptionalSubscript=false, reportOperatorIssue=false, reportArgumentType=false, reportOptionalCall=false
# (ptr8/ptr32/int/uint casts are viper built-ins)

import array

import micropython
from micropython import const

try:
    from tempcomp.native import int32
except ValueError:  # the armv6m build where the armv7m one is refused (fixedpoint does the same)
    from tempcomp.native_m0 import int32  # pyright: ignore[reportMissingImports]

# augment's layout (the same names and values there; host_tests/augment checks they agree)
_CL = const(0)
_XS = const(1)
_TS = const(2)
_SUPS = const(3)
_AS = const(4)
_UPT = const(7)
_MID = const(8)
_LIM = const(9)
_KB = const(10)
_S2 = const(11)
_RND = const(12)
_NTAU = const(13)
_PTAU = const(14)
_NPLAY = const(15)
_PPLAY = const(16)
_NSF = const(17)
_PSF = const(18)
_FL = const(19)
_O = const(22)
_SCL = const(25)
_FILT = const(26)
_SRC = const(32)
_OUTP = const(33)
_NS = const(34)
_MODE = const(35)
_STR = const(36)
_ROFF = const(37)
_AOFF = const(38)
_DTR = const(39)
_HASF = const(40)
_NHYP = const(41)
_PHYP = const(42)
_UPMAX = const(43)
_TC = const(44)
_TLO = const(45)
_THI = const(46)
_DTC = const(47)
_LAST = const(48)
_NB = const(49)
_TOFF = const(50)
_CRAW = const(51)
_COUT = const(52)
_CACC = const(53)
_NTF = const(54)
_PTF = const(55)
_DTI = const(56)
_PUPD = const(57)
_NEED = const(58)
_CBOUT = const(59)
_CBACC = const(60)
_SMALL = const(61)
_AXB = const(62)
_CBUF = const(128)
_CBUFN = const(129)
_CBOUTN = const(130)
_TSPAN = const(131)
_LIM2 = const(132)
_RNDO = const(133)
_S2O = const(134)
_AXS = const(22)
_GH = const(0)
_GL = const(1)
_B = const(2)
_RHO = const(3)
_DS = const(4)
_ES = const(5)
_FO = const(6)
_AF = const(7)
_AGAIN = const(1)
_AOFFS = const(2)
_ACROSS = const(4)
_ASTEPT = const(8)
_OT = const(8)
_GT = const(9)
_CR = const(10)
_Y0 = const(11)
_INV = const(12)
_Y = const(13)
_KM = const(14)
_RAW = const(17)
_SOT = const(18)
_SGT = const(19)
_RS = const(20)
_RR = const(21)
_TREC = const(30)
_FREC = const(6)
_OSUB = const(0)
_OSUBC = const(1)
_OMUL = const(3)
_UREC = const(30)
_FUP = const(1)
_FFILT = const(2)
_FSTART = const(4)
_FRHO = const(16)
_FCROSS = const(32)
_FGEN = const(64)
_FACC = const(128)
_FDT = const(256)
_FSUP = const(512)
_FBURST = const(1024)
_ONE = const(1 << 28)
_FMAX = const(32767)
_DT_MAX = const((1 << 26) - 1)
_UP_MAX = const((1 << 30) - (1 << 26) + 1)  # uptime + dt stays below it: (1 << 30) - _DT_MAX

_BUFFERS = (bytes, bytearray, memoryview, array.array)


def words(a, n):
    """True when a is an array of at least n 32-bit two's-complement ints."""
    return type(a) is array.array and len(a) >= n and int32(a)


def buffer(a):
    """True when a is a buffer the burst path may read bytes from."""
    return isinstance(a, _BUFFERS)


@micropython.viper
def note(w, slot: int, a):
    """Store the buffer address of array a in word slot of w."""
    ptr32(w)[slot] = int(ptr32(a))


@micropython.viper
def _address(a) -> int:
    return int(ptr32(a))


def address(a):
    """The buffer address of array a as an int where it is a small int (RAM below 2**30, as on
    Cortex-M), else a itself: the kernel casts either to the same pointer, the int for less."""
    try:
        v = _address(a)
    except OverflowError:  # a port without long ints
        return a
    return v if -0x40000000 <= v < 0x40000000 else a


@micropython.viper
def apply(self, t: int, raw, out, dt_ms, supply, acc):
    """Augmented.apply (and apply_be16_n's burst when the flags say so), word for word the pure
    kernel's ``Augmented._apply``."""
    w = ptr32(self._wp)
    fl = w[_FL]
    rp = ptr32(0)
    op = ptr32(0)
    if not (fl & (_FGEN | _FBURST)):
        # the base model alone: the shortest path
        try:
            rp = ptr32(raw)
            op = ptr32(out)
        except TypeError:
            self._bind(raw, out, acc, 0)
            return
        if (int(rp) ^ w[_CRAW]) | (int(op) ^ w[_COUT]):
            # arrays not seen before: checked once (a list or a 16-bit array is refused by name)
            self._bind(raw, out, acc, 0)
        if uint(t - w[_TLO]) > uint(w[_TSPAN]):
            # outside the proven range: clamped, counted
            w[_CL] = w[_CL] + 1
            if t < w[_TLO]:
                t = w[_TLO]
            else:
                t = w[_THI]
        if t != w[_TC]:
            if w[_SMALL]:
                step(int(w), t)
            else:
                step(self._wp, t)
        mid = w[_MID]
        lim = w[_LIM]
        kb = w[_KB]
        rnd = w[_RNDO]  # the output's rounding folded in: ((y + rnd) >> (S - 2) + 2) >> 2
        s2 = w[_S2O]
        r = rp[0] - mid
        if uint(r + lim) > uint(w[_LIM2]):
            w[_CL] = w[_CL] + 1
            if r > 0:
                r = lim
            else:
                r = 0 - lim
        op[0] = (r * w[_AXB + _GH] + ((r * w[_AXB + _GL]) >> kb) - w[_AXB + _B] + rnd) >> s2
        r = rp[1] - mid
        if uint(r + lim) > uint(w[_LIM2]):
            w[_CL] = w[_CL] + 1
            if r > 0:
                r = lim
            else:
                r = 0 - lim
        op[1] = (r * w[_AXB + _AXS + _GH] + ((r * w[_AXB + _AXS + _GL]) >> kb) - w[_AXB + _AXS + _B] + rnd) >> s2
        r = rp[2] - mid
        if uint(r + lim) > uint(w[_LIM2]):
            w[_CL] = w[_CL] + 1
            if r > 0:
                r = lim
            else:
                r = 0 - lim
        op[2] = (r * w[_AXB + 2 * _AXS + _GH] + ((r * w[_AXB + 2 * _AXS + _GL]) >> kb) - w[_AXB + 2 * _AXS + _B] + rnd) >> s2
        return
    nb = 1
    st = 0
    to = -1
    if fl & _FBURST:
        fl &= ~_FBURST
        w[_FL] = fl
        nb = w[_NB]
        st = w[_STR]
        to = w[_TOFF]
    ra = fl & _FACC
    if st and w[_AOFF] >= 0:
        ra = 0  # the accelerometer's words come with each sample
    bp = ptr8(0)
    ap = ptr32(0)
    try:
        if st:
            bp = ptr8(raw)
        else:
            rp = ptr32(raw)
        op = ptr32(out)
        if ra:
            ap = ptr32(acc)
    except TypeError:
        self._bind(raw, out, acc, nb if st else 0)
        return
    if st:
        ok = int(op) == w[_CBOUT]
        if ok and ra:
            ok = int(ap) == w[_CBACC]
    else:
        ok = int(op) == w[_COUT] and int(rp) == w[_CRAW]
        if ok and ra:
            ok = int(ap) == w[_CACC]
    if not ok:
        self._bind(raw, out, acc, nb if st else 0)
    if ra:
        w[_AS] = ap[0]
        w[_AS + 1] = ap[1]
        w[_AS + 2] = ap[2]
    if fl & _FSUP:
        w[_SUPS] = int(supply)
    d = 0
    if fl & _FDT:
        d = int(dt_ms)
        if d < 0:
            d = int(self._ticks())
        if d > _DT_MAX:
            d = _DT_MAX
    w[_DTR] = -1
    if fl & _FUP:
        w[_DTR] = d
    # one reading for the run: the whole burst, or one sample of it when each has its own
    run = nb
    if to >= 0:
        run = 1
    w[_MODE] = 0
    w[_SRC] = int(rp)
    if st:
        w[_MODE] = 1
        w[_SRC] = int(bp)
    w[_OUTP] = int(op)
    i = 0
    while i < nb:
        if to >= 0:
            p = w[_SRC] + to
            t = ((ptr8(p)[0] << 8 | ptr8(p)[1]) ^ 0x8000) - 0x8000
        if t < w[_TLO]:
            t = w[_TLO]
            w[_CL] = w[_CL] + run
        elif t > w[_THI]:
            t = w[_THI]
            w[_CL] = w[_CL] + run
        if t != w[_TC]:
            if w[_SMALL]:
                step(int(w), t)
            else:
                step(self._wp, t)
        x = t << 12
        w[_XS] = x
        w[_FILT] = 0
        if fl & _FFILT:
            if not (w[_FL] & _FSTART):
                # the first reading after a power-on (augment._start_filters)
                w[_FL] = w[_FL] | _FSTART
                q = ptr32(int(w) + (w[_PTAU] << 2))
                n = w[_NTAU]
                while n:
                    if not q[0]:
                        q[2] = x
                    q = ptr32(int(q) + _TREC * 4)
                    n -= 1
                q = ptr32(int(w) + (w[_PPLAY] << 2))
                n = w[_NPLAY]
                while n:
                    li = q[1]
                    if li < 0:
                        q[2] = x
                    else:
                        q[2] = w[li >> 2]
                    q = ptr32(int(q) + 12)
                    n -= 1
            else:
                w[_FILT] = 1
            if d != w[_DTC] and (w[_FILT] or run > 1):
                # alpha(dt) = 1 - prod_k (1 - alpha(2**k)) over dt's set bits (augment._alphas)
                w[_DTC] = d
                q = ptr32(int(w) + (w[_PTAU] << 2))
                n = w[_NTAU]
                while n:
                    a = 0
                    k = 4
                    e = d
                    while e:
                        if e & 1:
                            b = q[k]
                            ah = a >> 14
                            al = a & 0x3FFF
                            bh = b >> 14
                            bl = b & 0x3FFF
                            a = a + b - (ah * bh + ((ah * bl + al * bh + ((al * bl) >> 14)) >> 14))
                        e >>= 1
                        k += 1
                    q[1] = a
                    q = ptr32(int(q) + _TREC * 4)
                    n -= 1
        w[_NS] = run
        if w[_SMALL]:
            _run(int(w))
        else:
            _run(self._wp)
        i += run


@micropython.viper
def apply_be16_n(self, t: int, buf, out, n: int, dt_ms, supply, acc):
    """Augmented.apply_be16_n: the burst's arguments checked (its buffers by address and length
    against the last ones checked), then apply()'s burst."""
    w = ptr32(self._wp)
    d = int(dt_ms)
    if n < 0 or n > 32767 or d < 0 or d > _DT_MAX:
        self._check_burst(buf, out, n, dt_ms)  # raises
    if n == 0:
        self._check_burst(buf, out, n, dt_ms)
        return
    bp = ptr8(0)
    op = ptr32(0)
    try:
        bp = ptr8(buf)
        op = ptr32(out)
    except TypeError:
        self._bind(buf, out, acc, n)
        return
    if int(bp) != w[_CBUF] or int(op) != w[_CBOUT] or (n - 1) * w[_STR] + w[_NEED] > w[_CBUFN] or 3 * n > w[_CBOUTN]:
        self._bind(buf, out, acc, n)
    w[_NB] = n
    w[_FL] = w[_FL] | _FBURST
    self.apply(t, buf, out, dt_ms, supply, acc)


@micropython.viper
def step(wp, t: int):
    """The base's part of augment_pure.step: what depends on the reading t alone (clamped
    already), with fixedpoint.Compensator.update's arithmetic (the _UREC records of
    augment._urec). The terms' part (rho, the step features, their terms, the cross matrix) runs
    in the general sample's kernel, when it sees _TS differ from _TC (augment_thumb's TSTEP)."""
    w = ptr32(wp)
    kb = w[_KB]
    xb = ptr32(int(w) + (_AXB << 2))
    ur = ptr32(int(w) + (w[_PUPD] << 2))
    ax = 3
    while ax:
        fd = ur[0]
        if fd >= 0:
            # a constant-scale axis: its offset term by Horner's rule (the inline mul_shift)
            b = ur[2]
            if fd:
                x = (t - ur[18]) << ur[19]
                hs = ur[20]
                hp = ptr32(int(ur) + ((2 + fd) << 2))
                a = hp[0]
                while True:
                    a = ((a >> 14) * x + (((a & 0x3FFF) * x) >> 14)) >> hs
                    fd -= 1
                    if not fd:
                        break
                    hp = ptr32(int(hp) - 4)
                    a += hp[0]
                sh = ur[1]
                if sh >= 0:
                    b += a >> sh
                else:
                    b += a << (0 - sh)
            xb[_B] = b
        else:
            # the scale d + e / 2**14 (Poly.eval_ext) and the offset o (Poly.eval)
            k = ur[6]
            if k == 0:
                d = ur[12]
                e = ur[13]
            else:
                x = (t - ur[7]) << ur[8]
                hs = ur[9]
                hp = ptr32(int(ur) + ((13 + k) << 2))
                v = hp[0]
                while True:
                    v = ((v >> 14) * x + (((v & 0x3FFF) * x) >> 14)) >> hs
                    k -= 1
                    if not k:
                        break
                    hp = ptr32(int(hp) - 4)
                    v += hp[0]
                vs = ur[10]
                lo = v & ur[11]
                if vs >= 14:
                    lo >>= vs - 14
                else:
                    lo <<= 14 - vs
                lo += ur[13]
                e = lo & 0x3FFF
                d = ur[12] + (v >> vs) + (lo >> 14)
            k = ur[17]
            if k == 0:
                o = ur[23]
            else:
                x = (t - ur[18]) << ur[19]
                hs = ur[20]
                hp = ptr32(int(ur) + ((23 + k) << 2))
                v = hp[0]
                while True:
                    v = ((v >> 14) * x + (((v & 0x3FFF) * x) >> 14)) >> hs
                    k -= 1
                    if not k:
                        break
                    hp = ptr32(int(hp) - 4)
                    v += hp[0]
                o = ur[23] + ((v + ur[22]) >> ur[21])
            wg = ur[27]
            wx = ur[28] - 7
            g = 0
            b = 0
            if wg >= 0 and wx >= 0:
                # the quick division by the top 20 bits dh, ten bits a step, corrected for
                # the rest f / 2**21 of a unit of dh (fixedpoint's _div_wide and _corr21)
                dh = d >> 7
                f = ((d & 0x7F) << 14) + e
                fh = f >> 14
                fl14 = f & 0x3FFF
                num = 1 << 28
                ex = wg
                k = 2
                while k:
                    q = num // dh
                    r = num - q * dh
                    while ex >= 10:
                        r <<= 10
                        c = r // dh
                        r -= c * dh
                        q = (q << 10) + c
                        ex -= 10
                    if ex:
                        r <<= ex
                        q = (q << ex) + r // dh
                    if f:
                        qh = q >> 14
                        ql = q & 0x3FFF
                        c = ((qh * fh) << 7) + ((ql * fh) >> 7) + ((qh * fl14 + ((ql * fl14) >> 14)) >> 7)
                        q -= c // dh
                    if k == 2:
                        g = q
                        num = o
                        ex = wx
                    else:
                        b = q
                    k -= 1
            else:
                # the plain long division, three bits a step (fixedpoint's div_pow2)
                ex = ur[29]
                num = 1 << 28
                if ex <= 28:
                    num = 1 << ex
                    ex = 0
                else:
                    ex -= 28
                k = 2
                while k:
                    q = num // d
                    r = num - q * d
                    while ex > 0:
                        s = 3
                        if ex < 3:
                            s = ex
                        r <<= s
                        c = r // d
                        r -= c * d
                        q = (q << s) + c
                        ex -= s
                    if e:
                        q -= ((q >> 14) * e + (((q & 0x3FFF) * e) >> 14)) // d
                    if k == 2:
                        g = q
                        num = o
                        ex = ur[28]
                    else:
                        b = q
                    k -= 1
            g = (g + 1) >> 1
            xb[_GH] = g >> kb
            xb[_GL] = g & ((1 << kb) - 1)
            xb[_B] = b
        xb = ptr32(int(xb) + _AXS * 4)
        ur = ptr32(int(ur) + _UREC * 4)
        ax -= 1
    w[_TC] = t


def _vrun():
    # the viper run, a module of its own: only where there is no asm_thumb (or for the tests)
    try:
        from tempcomp import augment_vrun
    except ValueError:  # the armv6m build where the armv7m one is refused
        from tempcomp import augment_vrun_m0 as augment_vrun  # pyright: ignore[reportMissingImports]
    return augment_vrun.run


_asm = None  # a run of samples: asm_thumb where the port has the inline assembler
try:
    from tempcomp import augment_thumb

    _asm = augment_thumb.run
except (ImportError, SyntaxError, ValueError, NotImplementedError, AttributeError):
    pass
_run = _asm or _vrun()


def use_asm(on):
    """Run the general samples with the asm_thumb kernel (True, where there is one) or the viper
    one (False): the same numbers (tests compare them)."""
    global _run
    if on and _asm is None:
        raise ValueError("use_asm(True): this port has no asm_thumb")
    _run = _asm if on else _vrun()
