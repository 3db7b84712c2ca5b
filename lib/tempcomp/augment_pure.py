"""The pure-Python kernel of ``tempcomp.augment``: an ``Augmented`` model's per-sample path, its
bursts and its per-reading step, on the word array the set-up lays out. The reference the native
kernels (``augment_native``, ``augment_thumb``, ``augment_vrun``) reproduce bit for bit, and the
path wherever there is no viper emitter (CircuitPython, the WebAssembly VM, CPython) or
``augment.use_native(False)`` asks for it. A module of its own, imported when a model first needs
it: a Cortex-M board running the native kernels never holds it in RAM.

The bounds of every intermediate are augment's module notes.
"""

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


# augment's layout (the same names and values there; host_tests/augment checks they agree)
_FV = const(12)
_ONE = const(1 << 28)
_SUB = const(16)
_FMAX = const(32767)
_DT_MAX = const((1 << 26) - 1)
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
_PSF = const(18)
_FL = const(19)
_O = const(22)
_SCL = const(25)
_FILT = const(26)
_STR = const(36)
_ROFF = const(37)
_AOFF = const(38)
_NHYP = const(41)
_PHYP = const(42)
_TC = const(44)
_TLO = const(45)
_THI = const(46)
_DTC = const(47)
_NB = const(49)
_TOFF = const(50)
_PTF = const(55)
_DTI = const(56)
_AXB = const(62)
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


def apply_be16_n(self, t, buf, out, n, dt_ms, supply, acc):
    # apply_be16_n of the pure kernel (the native one is augment_native.apply_be16_n)
    self._check_burst(buf, out, n, dt_ms)
    if n:
        w = self._w
        w[_NB] = n
        w[_FL] |= _FBURST
        try:
            self.apply(t, buf, out, dt_ms, supply, acc)  # pyright: ignore[reportCallIssue]
        finally:
            w[_FL] &= ~_FBURST  # a call refused before the kernel read it leaves no burst behind




def apply(self, t, raw, out, dt_ms, supply, acc):
    # the pure-Python kernel: the reference, and the fallback where there is no viper;
    # tempcomp.augment_native and augment_thumb do the same, word for word
    w = self._w
    fl = w[_FL]
    n = 1
    st = ro = 0
    ao = to = -1
    if fl & _FBURST:
        fl &= ~_FBURST
        w[_FL] = fl
        n = w[_NB]
        st = w[_STR]
        ro = w[_ROFF]
        ao = w[_AOFF]
        to = w[_TOFF]
    if fl & _FSUP:
        w[_SUPS] = supply
    tr = t  # the burst's reading, clamped (and counted) for every sample as apply() would
    i = 0
    j = 0
    while i < n:
        t = tr
        if st:
            # the burst's big-endian int16 words
            p = j + ro
            r0 = ((raw[p] << 8 | raw[p + 1]) ^ 0x8000) - 0x8000
            r1 = ((raw[p + 2] << 8 | raw[p + 3]) ^ 0x8000) - 0x8000
            r2 = ((raw[p + 4] << 8 | raw[p + 5]) ^ 0x8000) - 0x8000
            if to >= 0:
                t = ((raw[j + to] << 8 | raw[j + to + 1]) ^ 0x8000) - 0x8000
        else:
            r0 = raw[0]
            r1 = raw[1]
            r2 = raw[2]
        if fl & _FACC:
            if ao >= 0:
                p = j + ao
                w[_AS] = ((raw[p] << 8 | raw[p + 1]) ^ 0x8000) - 0x8000
                w[_AS + 1] = ((raw[p + 2] << 8 | raw[p + 3]) ^ 0x8000) - 0x8000
                w[_AS + 2] = ((raw[p + 4] << 8 | raw[p + 5]) ^ 0x8000) - 0x8000
            else:
                if acc is None:
                    raise ValueError("acc must be an array('i') of at least 3 ints (the model reads the "
                                     "accelerometer), got NoneType")
                w[_AS] = acc[0]
                w[_AS + 1] = acc[1]
                w[_AS + 2] = acc[2]
        dt = 0
        if fl & _FDT:
            dt = dt_ms
            if dt < 0:
                dt = self._ticks()
            if dt > _DT_MAX:
                dt = _DT_MAX
            if fl & _FUP:
                u = w[_UPT] + dt
                if u < (1 << 30) - _DT_MAX:
                    w[_UPT] = u
        # the reading, clamped to the range the bounds are proven for
        if t < w[_TLO]:
            t = w[_TLO]
            w[_CL] += 1
        elif t > w[_THI]:
            t = w[_THI]
            w[_CL] += 1
        if t != w[_TC]:
            step(self, t)
        if fl & _FGEN:
            x = t << _FV
            w[_XS] = x
            w[_FILT] = 0
            if fl & _FFILT:
                if not w[_FL] & _FSTART:
                    _start_filters(w, x)
                else:
                    if dt != w[_DTC]:
                        _alphas(w, dt)
                    w[_FILT] = 1
            q = w[_PHYP]
            k = w[_NHYP]
            while k:
                a = w[q + 1]
                w[w[q] >> 2] = (a << 14) // (a + (w[_UPT] >> w[q + 2]))
                q += 3
                k -= 1
            _general(w, r0, r1, r2)
            y0 = w[_O]
            y1 = w[_O + 1]
            y2 = w[_O + 2]
        else:
            # the base model: the Compensator's sample with 2 guard bits, then rounded
            y0 = _base(w, 0, r0)
            y1 = _base(w, 1, r1)
            y2 = _base(w, 2, r2)
        q = 3 * i
        out[q] = y0
        out[q + 1] = y1
        out[q + 2] = y2
        i += 1
        j += st


def step(self, t):
    # everything that depends on the reading alone: the base gain and offset term, rho, the
    # step features and their share of the terms, the cross-axis matrix
    w = self._w
    c = self.comp
    c.update(t)
    K = c._k
    fl = w[_FL]
    for i in range(3):
        ab = _AXB + _AXS * i
        w[ab + _GH] = c._gh[i]
        w[ab + _GL] = c._gl[i]
        w[ab + _B] = c._b[i]
        if fl & _FRHO:
            w[ab + _RHO] = _mul26((((c._gh[i] << K) + c._gl[i]) >> 2) << w[ab + _RS], w[ab + _RR])
    w[_TC] = t
    if not fl & _FGEN:
        return
    w[_TS] = t
    w[_SCL] = _features(w, w[_PTF])
    dtf = w[w[_DTI]] if w[_DTI] >= 0 else 0
    for i in range(3):
        ab = _AXB + _AXS * i
        if w[ab + _AF] & _ASTEPT:
            w[ab + _DS] = _terms(w, w[ab + _SOT], 0)
            w[ab + _ES] = _terms(w, w[ab + _SGT], 0)
        p = w[ab + _CR]
        n = w[p]
        rho = w[ab + _RHO]
        while n:
            k1 = w[p + 3]
            # mul_shift(k1, dtf, 15): |k1| <= 2**28, |dtf| <= 2**15
            w[ab + _KM + w[p + 1]] = _mul28(rho, w[p + 2] + (((k1 >> 14) * dtf + (((k1 & 0x3FFF) * dtf) >> 14)) >> 1))
            p += 3
            n -= 1



def _y0(w, ab, r, fr):
    # the Compensator's sample with 2 guard bits for the axis block at ab: r = raw - mid - di,
    # clamped to the raw range's half-span (counted); fr, dO's 8-bit fraction, taken off too
    lim = w[_LIM]
    if r > lim:
        r = lim
        w[_CL] += 1
    elif r < -lim:
        r = -lim
        w[_CL] += 1
    g = w[ab + _GH]
    return (r * g + ((r * w[ab + _GL]) >> w[_KB]) - w[ab + _B] - ((fr * g) >> 8) + w[_RND]) >> w[_S2]


def _base(w, i, raw):
    # the base model's sample of axis i, rounded to the output
    return (_y0(w, _AXB + _AXS * i, raw - w[_MID], 0) + 2) >> 2


def _start_filters(w, x):
    # the first reading after a power-on: lowpass states (not the drift ones) and plays start there
    w[_FL] |= _FSTART
    p = w[_PTAU]
    n = w[_NTAU]
    while n:
        if not w[p]:
            w[p + 2] = x
        p += _TREC
        n -= 1
    p = w[_PPLAY]
    n = w[_NPLAY]
    while n:
        li = w[p + 1]
        w[p + 2] = x if li < 0 else w[li >> 2]
        p += 3
        n -= 1


def _general(w, r0, r1, r2):
    # one sample of the general model, its inputs in the header: the filters' step (_FILT), the
    # features, per axis y0 and 1 / (1 + rho e), the cross-axis solve; outputs in _O
    w[_CL] += w[_SCL]
    x = w[_XS]
    if w[_FILT]:
        p = w[_PTAU]
        n = w[_NTAU]
        while n:
            # v += alpha * (target - v), exactly to 2**-16 of a state unit (carry in the next
            # word): |target - v| <= 2**28, alpha <= 2**28
            a = w[p + 1]
            v = w[p + 2]
            d = (0 if w[p] else x) - v
            ah = a >> 14
            al = a & 0x3FFF
            dh = d >> 14
            dl = d & 0x3FFF
            m = ah * dl + al * dh
            lo = ((m & 0x3FFF) << 14) + al * dl
            q = ah * dh + (m >> 14) + (lo >> 28)
            s = w[p + 3] + ((lo & 0xFFFFFFF) >> 12)
            w[p + 2] = v + q + (s >> _SUB)
            w[p + 3] = s & 0xFFFF
            p += _TREC
            n -= 1
        p = w[_PPLAY]
        n = w[_NPLAY]
        while n:
            h = w[p]
            li = w[p + 1]
            xi = x if li < 0 else w[li >> 2]
            if xi - h > w[p + 2]:
                w[p + 2] = xi - h
            elif xi + h < w[p + 2]:
                w[p + 2] = xi + h
            p += 3
            n -= 1
    w[_CL] += _features(w, w[_PSF])
    for i in range(3):
        ab = _AXB + _AXS * i
        w[ab + _RAW] = r0 if i == 0 else (r1 if i == 1 else r2)
        d = _terms(w, w[ab + _OT], w[ab + _DS]) if w[ab + _AF] & _AOFFS else 0
        fo = w[ab + _FO]
        # dO = di + fr / 256 raw codes, taken off the raw code and the offset term
        w[ab + _Y0] = _y0(w, ab, w[ab + _RAW] - w[_MID] - (d >> fo), (d >> (fo - 8)) & 0xFF)
        if w[ab + _AF] & _AGAIN:
            e = _mul28(w[ab + _RHO], _terms(w, w[ab + _GT], w[ab + _ES]))
            # 1 / (1 + e) = 1 - e (1 - e (1 - e (1 - e))) + O(e**5), |e| <= 1/8
            q = _ONE - e
            q = _ONE - _mul28(e, q)
            q = _ONE - _mul28(e, q)
            w[ab + _INV] = _ONE - _mul28(e, q)
    for i in range(3):
        ab = _AXB + _AXS * i
        y = w[ab + _Y0]
        if w[ab + _AF] & _AGAIN:
            y = _mul28(y, w[ab + _INV])
        w[ab + _Y] = y
    if w[_FL] & _FCROSS:
        # y = (y0 - K y) / (1 + e): a contraction (|K| <= 1/16), two steps leave ~|K|**3
        it = 2
        while it:
            for i in range(3):
                ab = _AXB + _AXS * i
                s = w[ab + _Y0]
                p = w[ab + _CR]
                n = w[p]
                while n:
                    k = w[p + 1]
                    s -= _mul28(w[ab + _KM + k], w[_AXB + _AXS * k + _Y])
                    p += 3
                    n -= 1
                if w[ab + _AF] & _AGAIN:
                    s = _mul28(s, w[ab + _INV])
                w[_O + i] = s
            for i in range(3):
                w[_AXB + _AXS * i + _Y] = w[_O + i]
            it -= 1
    for i in range(3):
        w[_O + i] = (w[_AXB + _AXS * i + _Y] + 2) >> 2


def _mul26(a, b):
    # floor(a * b / 2**26) for 0 <= a < 2**28, 0 < b <= 2**28: 4 ah bh < 2**30, the middle < 2**29
    ah = a >> 14
    al = a & 0x3FFF
    bh = b >> 14
    bl = b & 0x3FFF
    return 4 * ah * bh + ((ah * bl + al * bh + ((al * bl) >> 14)) >> 12)


def _features(w, p):
    # the feature records at p (after the 4 group counts): each value clamped to its bound
    # (counted; returned), then shifted to at most 2**15 counts
    n = w[p] + w[p + 1] + w[p + 2] + w[p + 3]
    p += 4
    cl = 0
    while n:
        op = w[p]
        a = w[p + 2]
        b = w[p + 3]
        if op == _OSUB:
            v = w[a >> 2] - w[b >> 2]
        elif op == _OSUBC:
            v = w[a >> 2] - b
        elif op == _OMUL:
            v = w[a >> 2] * w[b >> 2]
        else:
            v = w[a >> 2] >> b
        b = w[p + 4]
        if v > b:
            v = b
            cl += 1
        elif v < -b:
            v = -b
            cl += 1
        sh = w[p + 5]
        if sh < 0:
            v <<= -sh
        elif sh:
            v = (v + (1 << (sh - 1))) >> sh
            if v > _FMAX:
                v = _FMAX
            elif v < -_FMAX:
                v = -_FMAX
        w[w[p + 1] >> 2] = v
        p += _FREC
        n -= 1
    return cl


def _terms(w, p, d):
    # d plus the sum of mul_shift(c, f, 15) over the list at p, c by its limbs c >> 14 and
    # c & 0x3FFF: |c| <= 2**28, |f| <= 2**15
    n = w[p]
    while n:
        f = w[w[p + 1] >> 2]
        d += (w[p + 2] * f + ((w[p + 3] * f) >> 14)) >> 1
        p += 3
        n -= 1
    return d


def _alphas(w, dt):
    # alpha(dt) = 1 - prod_k (1 - alpha(2**k)) over dt's set bits; only when dt changes
    w[_DTC] = dt
    p = w[_PTAU]
    n = w[_NTAU]
    while n:
        a = 0
        k = p + 4
        d = dt
        while d:
            if d & 1:
                b = w[k]
                a = a + b - _mul28(a, b)
            d >>= 1
            k += 1
        w[p + 1] = a
        p += _TREC
        n -= 1



def _mul28(a, b):
    # floor(a * b / 2**28) for |a|, |b| <= 2**28, by 14-bit limbs: every partial product
    # <= 2**28, the middle sum <= 2**29 + 2**14
    ah = a >> 14
    al = a & 0x3FFF
    bh = b >> 14
    bl = b & 0x3FFF
    return ah * bh + ((ah * bl + al * bh + ((al * bl) >> 14)) >> 14)
