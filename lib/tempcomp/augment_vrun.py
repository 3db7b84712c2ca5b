"""The viper run of an ``Augmented`` model's general samples (``augment_thumb.run`` where the port
has the inline assembler): a new reading's terms step, then each sample's raw codes, the uptime,
drift_hyp's values, the filters' step, the features, the terms, per axis y0 and 1 / (1 + rho e),
the cross-axis solve and the outputs, as ``augment_pure.step`` and ``_general`` do them, word for
word (every intermediate within +-2**30 there, so 32-bit machine words never wrap).

A module of its own, imported by ``augment_native`` only where there is no asm_thumb (a viper-only
port) or when a test asks for it (``augment_native.use_asm(False)``): on Cortex-M its code would
only take RAM.
"""

# ruff: noqa: F821
# pyright: reportUndefinedVariable=false, reportAttributeAccessIssue=false, reportIndexIssue=false
# (ptr8/ptr32/int casts are viper built-ins)

import micropython
from micropython import const

# augment's layout (the same names and values there; host_tests/augment checks they agree)
_CL = const(0)
_XS = const(1)
_TS = const(2)
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
_NTF = const(54)
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
_FCROSS = const(32)
_ONE = const(1 << 28)
_FMAX = const(32767)


@micropython.viper
def run(wp):
    """augment_thumb.run where the port has no inline assembler: a run of samples (the run
    block's), each as augment._general does it."""
    w = ptr32(wp)
    t = w[_TC]
    if w[_TS] != t:
        # the terms' part of a new reading's step (augment_pure.step after the base, as
        # augment_thumb's TSTEP): the step features, per axis rho, the step features' share of
        # the terms, the cross matrix' row
        w[_TS] = t
        w[_SCL] = int(_features(wp, w[_NTF], w[_PTF]))
        dtf = 0
        if w[_DTI] >= 0:
            dtf = w[w[_DTI]]
        kb = w[_KB]
        xb = ptr32(int(w) + (_AXB << 2))
        ax = 3
        while ax:
            if xb[_AF] & (_AGAIN | _ACROSS):
                # rho = (G << s) * R / 2**26 (augment_pure._mul26), G = gain * 2**(K+S) >> 2
                a = (((xb[_GH] << kb) + xb[_GL]) >> 2) << xb[_RS]
                b = xb[_RR]
                ah = a >> 14
                al = a & 0x3FFF
                bh = b >> 14
                bl = b & 0x3FFF
                xb[_RHO] = 4 * ah * bh + ((ah * bl + al * bh + ((al * bl) >> 14)) >> 12)
            k = 0
            if xb[_AF] & _ASTEPT:
                k = 2
            while k:
                if k == 2:
                    q = ptr32(int(w) + (xb[_SOT] << 2))
                else:
                    q = ptr32(int(w) + (xb[_SGT] << 2))
                n = q[0]
                e = 0
                while n:
                    f = w[q[1] >> 2]
                    e += (q[2] * f + ((q[3] * f) >> 14)) >> 1
                    q = ptr32(int(q) + 12)
                    n -= 1
                if k == 2:
                    xb[_DS] = e
                else:
                    xb[_ES] = e
                k -= 1
            if xb[_AF] & _ACROSS:
                q = ptr32(int(w) + (xb[_CR] << 2))
                n = q[0]
                a = xb[_RHO]
                ah = a >> 14
                al = a & 0x3FFF
                while n:
                    c = q[3]
                    b = q[2] + (((c >> 14) * dtf + (((c & 0x3FFF) * dtf) >> 14)) >> 1)
                    bh = b >> 14
                    bl = b & 0x3FFF
                    xb[_KM + q[1]] = ah * bh + ((ah * bl + al * bh + ((al * bl) >> 14)) >> 14)
                    q = ptr32(int(q) + 12)
                    n -= 1
            xb = ptr32(int(xb) + _AXS * 4)
            ax -= 1
    while w[_NS]:
        w[_NS] = w[_NS] - 1
        sp = w[_SRC]
        if w[_MODE]:
            sp += w[_ROFF]
            bq = ptr8(sp)
            r0 = ((bq[0] << 8 | bq[1]) ^ 0x8000) - 0x8000
            r1 = ((bq[2] << 8 | bq[3]) ^ 0x8000) - 0x8000
            r2 = ((bq[4] << 8 | bq[5]) ^ 0x8000) - 0x8000
            if w[_AOFF] >= 0:
                bq = ptr8(w[_SRC] + w[_AOFF])
                w[_AS] = ((bq[0] << 8 | bq[1]) ^ 0x8000) - 0x8000
                w[_AS + 1] = ((bq[2] << 8 | bq[3]) ^ 0x8000) - 0x8000
                w[_AS + 2] = ((bq[4] << 8 | bq[5]) ^ 0x8000) - 0x8000
        else:
            q = ptr32(sp)
            r0 = q[0]
            r1 = q[1]
            r2 = q[2]
        if w[_DTR] >= 0:
            u = w[_UPT] + w[_DTR]
            if u < w[_UPMAX]:
                w[_UPT] = u
        n = w[_NHYP]
        q = ptr32(int(w) + (w[_PHYP] << 2))
        while n:
            a = q[1]
            w[q[0] >> 2] = (a << 14) // (a + (w[_UPT] >> q[2]))
            q = ptr32(int(q) + 12)
            n -= 1
        cl = w[_CL] + w[_SCL]
        x = w[_XS]
        if w[_FILT]:
            q = ptr32(int(w) + (w[_PTAU] << 2))
            n = w[_NTAU]
            while n:
                # v += alpha * (target - v), exact to 2**-16 of a unit (carry in q[3])
                a = q[1]
                v = q[2]
                if q[0]:
                    e = 0 - v
                else:
                    e = x - v
                ah = a >> 14
                al = a & 0x3FFF
                dh = e >> 14
                dl = e & 0x3FFF
                m = ah * dl + al * dh
                lo = ((m & 0x3FFF) << 14) + al * dl
                s = q[3] + ((lo & 0xFFFFFFF) >> 12)
                q[2] = v + ah * dh + (m >> 14) + (lo >> 28) + (s >> 16)
                q[3] = s & 0xFFFF
                q = ptr32(int(q) + _TREC * 4)
                n -= 1
            q = ptr32(int(w) + (w[_PPLAY] << 2))
            n = w[_NPLAY]
            while n:
                h = q[0]
                li = q[1]
                xi = x
                if li >= 0:
                    xi = w[li >> 2]
                if xi - h > q[2]:
                    q[2] = xi - h
                elif xi + h < q[2]:
                    q[2] = xi + h
                q = ptr32(int(q) + 12)
                n -= 1
        cl += int(_features(wp, w[_NSF], w[_PSF]))
        mid = w[_MID]
        lim = w[_LIM]
        ax = 0
        while ax < 3:
            xb = ptr32(int(w) + ((_AXB + _AXS * ax) << 2))
            if ax == 0:
                r = r0
            elif ax == 1:
                r = r1
            else:
                r = r2
            xb[_RAW] = r
            e = 0
            if xb[_AF] & _AOFFS:
                e = xb[_DS]
                q = ptr32(int(w) + (xb[_OT] << 2))
                n = q[0]
                while n:
                    f = w[q[1] >> 2]
                    e += (q[2] * f + ((q[3] * f) >> 14)) >> 1
                    q = ptr32(int(q) + 12)
                    n -= 1
            k = xb[_FO]
            f = (e >> (k - 8)) & 0xFF
            r = r - mid - (e >> k)
            if r > lim:
                r = lim
                cl += 1
            elif r < 0 - lim:
                r = 0 - lim
                cl += 1
            g = xb[_GH]
            xb[_Y0] = (r * g + ((r * xb[_GL]) >> w[_KB]) - xb[_B] - ((f * g) >> 8) + w[_RND]) >> w[_S2]
            if xb[_AF] & _AGAIN:
                e = xb[_ES]
                q = ptr32(int(w) + (xb[_GT] << 2))
                n = q[0]
                while n:
                    f = w[q[1] >> 2]
                    e += (q[2] * f + ((q[3] * f) >> 14)) >> 1
                    q = ptr32(int(q) + 12)
                    n -= 1
                a = xb[_RHO]
                ah = a >> 14
                al = a & 0x3FFF
                bh = e >> 14
                bl = e & 0x3FFF
                e = ah * bh + ((ah * bl + al * bh + ((al * bl) >> 14)) >> 14)
                # 1 / (1 + e) = 1 - e (1 - e (1 - e (1 - e))), |e| <= 1/8
                a = _ONE - e
                ah = e >> 14
                al = e & 0x3FFF
                n = 3
                while n:
                    bh = a >> 14
                    bl = a & 0x3FFF
                    a = _ONE - (ah * bh + ((ah * bl + al * bh + ((al * bl) >> 14)) >> 14))
                    n -= 1
                xb[_INV] = a
                a = xb[_Y0]
                b = xb[_INV]
                ah = a >> 14
                al = a & 0x3FFF
                bh = b >> 14
                bl = b & 0x3FFF
                xb[_Y] = ah * bh + ((ah * bl + al * bh + ((al * bl) >> 14)) >> 14)
            else:
                xb[_Y] = xb[_Y0]
            ax += 1
        w[_CL] = cl
        if w[_FL] & _FCROSS:
            # y = (y0 - K y) / (1 + e), two steps from y0 / (1 + e) (augment._general)
            it = 2
            while it:
                ax = 0
                while ax < 3:
                    xb = ptr32(int(w) + ((_AXB + _AXS * ax) << 2))
                    s = xb[_Y0]
                    q = ptr32(int(w) + (xb[_CR] << 2))
                    n = q[0]
                    while n:
                        k = q[1]
                        a = xb[_KM + k]
                        b = w[_AXB + _AXS * k + _Y]
                        ah = a >> 14
                        al = a & 0x3FFF
                        bh = b >> 14
                        bl = b & 0x3FFF
                        s -= ah * bh + ((ah * bl + al * bh + ((al * bl) >> 14)) >> 14)
                        q = ptr32(int(q) + 12)
                        n -= 1
                    if xb[_AF] & _AGAIN:
                        b = xb[_INV]
                        ah = s >> 14
                        al = s & 0x3FFF
                        bh = b >> 14
                        bl = b & 0x3FFF
                        s = ah * bh + ((ah * bl + al * bh + ((al * bl) >> 14)) >> 14)
                    w[_O + ax] = s
                    ax += 1
                w[_AXB + _Y] = w[_O]
                w[_AXB + _AXS + _Y] = w[_O + 1]
                w[_AXB + 2 * _AXS + _Y] = w[_O + 2]
                it -= 1
        q = ptr32(w[_OUTP])
        q[0] = (w[_AXB + _Y] + 2) >> 2
        q[1] = (w[_AXB + _AXS + _Y] + 2) >> 2
        q[2] = (w[_AXB + 2 * _AXS + _Y] + 2) >> 2
        w[_OUTP] = w[_OUTP] + 12
        w[_SRC] = w[_SRC] + w[_STR]
        w[_FILT] = w[_HASF]


@micropython.viper
def _features(wp, n: int, p: int) -> int:
    """augment._features: the n feature records after the group counts at word p, each value
    clamped to its bound (the clamps returned), shifted to at most 2**15 counts, stored."""
    w = ptr32(wp)
    q = ptr32(int(w) + ((p + 4) << 2))
    cl = 0
    while n:
        k = q[0]
        a = w[q[2] >> 2]
        b = q[3]
        if k == _OSUBC:
            v = a - b
        elif k == _OSUB:
            v = a - w[b >> 2]
        elif k == _OMUL:
            v = a * w[b >> 2]
        else:
            v = a >> b
        b = q[4]
        if v > b:
            v = b
            cl += 1
        elif v < 0 - b:
            v = 0 - b
            cl += 1
        k = q[5]
        if k < 0:
            v <<= 0 - k
        elif k:
            v = (v + (1 << (k - 1))) >> k
            if v > _FMAX:
                v = _FMAX
            elif v < 0 - _FMAX:
                v = 0 - _FMAX
        w[q[1] >> 2] = v
        q = ptr32(int(q) + _FREC * 4)
        n -= 1
    return cl
