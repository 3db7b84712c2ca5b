"""Augmented compensation: the base model (offset quadratic, sensitivity linear in temperature)
plus the terms the gap diagnosis found (``python -m tools gap ... --export``), per sample in
integers with zero allocation.

The model (all floats, set-up only; ``docs/augment.md`` has the table)::

    out_i = o_i(T) + dO_i + s_i(T) * ref_i + s_i(t0) * (e_i * ref_i + sum_k K_ik(T) * ref_k)

with o_i up to cubic and s_i linear in dT = T - t0, ``dO_i = sum_j c_ij f_j`` (raw output
units), ``e_i = sum_j g_ij f_j`` (a fraction of the sensitivity at t0) and
``K_ik(T) = k0 + k1 * dT`` (cross-axis: another axis' input), over
features ``f_j`` the board computes from what it sees each sample:

==========  ==================================================================  ==========
kind        value                                                               unit
==========  ==================================================================  ==========
dT          T - t0                                                              degC
lag         T - lowpass(T, tau): thermal lag (a filtered derivative ~ tau dT/dt)  degC
play        play(X, width) - X, X = T or lowpass(T, lag): hysteresis              degC
drift_exp   exp(-uptime / tau): settling since power-on                          1
drift_hyp   1 / (1 + uptime / tau)                                               1
uptime      time since power-on                                                  s
supply      V - supply0                                                          V
acc         acceleration on axis ``axis`` (g-sensitivity of a gyro)              g
prod        the product of features ``a`` and ``b``                              their units
==========  ==================================================================  ==========

Usage (the model from ``--export``, or loaded from the store with ``from_store``)::

    from tempcomp.augment import Augmented, load_json
    aug = Augmented(load_json("/model.json"))
    aug.start(0)                                   # power-on now (uptime in ms)
    aug.apply(t, raw, out, dt_ms, supply, acc)     # per sample; raw/out/acc array('i') of 3

``t`` is the temperature reading (``T = t * t_lsb + t_off`` degC), ``raw`` the raw codes
(``raw * raw_lsb`` out units), ``supply`` the supply reading (``supply * supply_lsb`` V), ``acc``
the accelerometer (``acc * acc_lsb`` g); ``out`` receives ref * out_scale, rounded. ``dt_ms`` is the
time since the previous sample in ms, or -1 to take it from ``time.ticks_ms()``.

Fixed point (B = 2**30 is the small-int bound; every clamp is counted in ``clamped``):

* Features are ints with |f| < 2**15 in units fixed at set-up (each clamped to its bound).
  Filter states are t-readings * 2**12 (|.| <= 2**27) plus a 16-bit sub-unit carry, so a
  slow filter never stalls; the step alpha = 1 - exp(-dt/tau) is in Q28, built from a table
  of exp(-2**k ms/tau) when dt changes.
* Terms ``mul_shift(c, f, 15)`` with |c| <= 2**28: sum of |c| <= 2**28 per axis, so dO (in
  2**-F raw units) and e (Q28, |e| <= 1/16) stay below 2**29.
* The base step is the Compensator's, with dO's integer part taken off the raw code and its
  8-bit fraction times the gain's high limb (<= 2**21) added: the sum stays below 2**30, and
  the result keeps 2 guard bits (|y| <= 2**25).
* e and K are scaled by rho = s(t0)/s(T) (Q28, from the Compensator's gain, on a new
  reading); 1/(1+e) by its series to e**4 (error < 2**-15 of y) and the cross-axis solve by
  two fixed-point iterations y = (y0 - K y) / (1 + e) (error ~|K|**3 of y); all products Q28
  by 14-bit limbs (``_mul28``).
"""

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


import time

from tempcomp.fixedpoint import EXTRAPOLATE, Compensator, div_pow2, mul_shift, shift_basis

FORMAT = const(1)
_FV = const(12)  # fraction bits of filter states (t reading * 2**12)
_Q = const(28)  # alpha, e, K, drift states
_ONE = const(1 << 28)
_SUB = const(16)  # sub-unit carry bits of filter states
_FMAX = const(32767)  # features are clamped to |f| <= 2**15 - 1
_TAB = const(26)  # exp(-2**k ms / tau) for k < 26: dt up to 18 h per step
_E_MAX = 0.0625  # |e| and |K| bounded by 1/16 at the features' bounds
_DT_MAX = const((1 << 26) - 1)

KINDS = ("dT", "lag", "play", "drift_exp", "drift_hyp", "uptime", "supply", "acc", "prod")
_DT, _LAG, _PLAY, _DEXP, _DHYP, _UP, _SUP, _ACC, _PROD = range(9)


# The ms clock for dt_ms=-1, allocation-free where the port has one: time.ticks_ms on
# MicroPython, supervisor.ticks_ms on CircuitPython boards (it wraps at 2**29); CPython's
# time.monotonic() float is the fallback.
_ticks = getattr(time, "ticks_ms", None)  # type: ignore
_ticks_diff = getattr(time, "ticks_diff", None)  # type: ignore
if _ticks is None or _ticks_diff is None:
    try:
        from supervisor import ticks_ms as _ticks  # pyright: ignore[reportMissingImports]

        def _ticks_diff(a, b):
            d = (a - b) & 0x1FFFFFFF
            return d - 0x20000000 if d & 0x10000000 else d
    except ImportError:

        def _ticks():
            return int(time.monotonic() * 1000)  # pyright: ignore[reportAttributeAccessIssue]

        def _ticks_diff(a, b):
            return a - b


def _mul28(a, b):
    # floor(a * b / 2**28) for |a|, |b| <= 2**28, by 14-bit limbs: every partial product
    # <= 2**28, the middle sum <= 2**29 + 2**14
    ah = a >> 14
    al = a & 0x3FFF
    bh = b >> 14
    bl = b & 0x3FFF
    return ah * bh + ((ah * bl + al * bh + ((al * bl) >> 14)) >> 14)


def _bits(v):
    n = 0
    while (1 << n) < v:
        n += 1
    return n


def _exp(x):
    # exp(x) for x <= 0 without math (some ports lack it): halve until small, Taylor, square
    n = 0
    while x < -0.5:
        x *= 0.5
        n += 1
    term = 1.0
    s = 1.0
    k = 1
    while k < 14:
        term *= x / k
        s += term
        k += 1
    while n > 0:
        s *= s
        n -= 1
    return s


def _fix(x, frac):
    return int(round(x * (1 << frac))) if frac >= 0 else int(round(x / (1 << -frac)))


def load_json(path):
    """The device model from an exported JSON file (its "device" section) or a dict."""
    import json

    with open(path) as f:
        d = json.load(f)
    return d.get("device", d)


def from_store(store, name):
    """The device model saved with ``pack`` in record ``name`` of a tempcomp Store."""
    rec = store.record(name)
    return unpack([rec.real(i) for i in range(len(rec.values))])


# Flat form for the coefficient store (one float per value, see docs/augment.md):
# FORMAT, t_lsb, t_off, raw_lsb, raw_lo, raw_hi, out_scale, t0, tc_lo, tc_hi, supply_lsb,
# supply0, acc_lsb, then per axis o0 o1 o2 o3 s0 s1, then nfeat and per feature
# kind, p1, p2, p3 (tau/width/axis/a, lag/b, bound), then per axis
# n_off (fi c)*, n_gain (fi g)*, n_cross (k k0 k1)*.
_HEAD = ("t_lsb", "t_off", "raw_lsb", "raw_lo", "raw_hi", "out_scale", "t0", "tc_lo", "tc_hi",
         "supply_lsb", "supply0", "acc_lsb")
_FEAT_P = {"dT": (), "lag": ("tau",), "play": ("width", "lag"), "drift_exp": ("tau",),
           "drift_hyp": ("tau",), "uptime": (), "supply": (), "acc": ("axis",), "prod": ("a", "b")}


def pack(m):
    """The model dict as a flat list of floats (host or device)."""
    v = [float(FORMAT), m["t_lsb"], m.get("t_off", 0.0), m.get("raw_lsb", 1.0),
         m.get("raw_range", (-32768, 32767))[0], m.get("raw_range", (-32768, 32767))[1],
         m.get("out_scale", 1.0), m.get("t0", 25.0), m["t_cal"][0], m["t_cal"][1],
         m.get("supply_lsb", 0.001), m.get("supply0", 0.0), m.get("acc_lsb", 0.001)]
    for i in range(3):
        o = [float(c) for c in m["offset"][i]]
        v += (o + [0.0] * (4 - len(o))) + [float(c) for c in m["sensitivity"][i]]
    feats = m.get("features", [])
    v.append(len(feats))
    for f in feats:
        names = _FEAT_P[f["kind"]]
        p = [float(f.get(n, 0.0)) for n in names] + [0.0] * (2 - len(names))
        v += [KINDS.index(f["kind"])] + p + [float(f.get("bound", 0.0))]
    for key, width in (("offset_terms", 2), ("gain_terms", 2), ("cross", 3)):
        rows = m.get(key) or [[], [], []]
        for i in range(3):
            v.append(len(rows[i]))
            for r in rows[i]:
                v += [float(x) for x in r[:width]]
    return [float(x) for x in v]


def unpack(v):
    """Inverse of pack (set-up)."""
    if int(v[0]) != FORMAT:
        raise ValueError("augmented model format %r; this library reads %d" % (v[0], FORMAT))
    m = {}
    p = 1
    for k in _HEAD:
        m[k] = v[p]
        p += 1
    m["raw_range"] = (int(m.pop("raw_lo")), int(m.pop("raw_hi")))
    m["t_cal"] = (m.pop("tc_lo"), m.pop("tc_hi"))
    m["offset"] = []
    m["sensitivity"] = []
    for _ in range(3):
        m["offset"].append(v[p:p + 4])
        m["sensitivity"].append(v[p + 4:p + 6])
        p += 6
    n = int(v[p])
    p += 1
    feats = []
    for _ in range(n):
        kind = KINDS[int(v[p])]
        f = {}
        f["kind"] = kind
        names = _FEAT_P[kind]
        for j, name in enumerate(names):
            x = v[p + 1 + j]
            f[name] = int(x) if name in ("axis", "a", "b") else x
        f["bound"] = v[p + 3]
        feats.append(f)
        p += 4
    m["features"] = feats
    for key, width in (("offset_terms", 2), ("gain_terms", 2), ("cross", 3)):
        rows = []
        for _ in range(3):
            k = int(v[p])
            p += 1
            row = []
            for _ in range(k):
                r = list(v[p:p + width])
                r[0] = int(r[0])
                row.append(r)
                p += width
            rows.append(row)
        m[key] = rows
    if p != len(v):
        raise ValueError("augmented model: %d values, layout uses %d" % (len(v), p))
    return m


class Augmented:
    """The augmented model of one 3-axis sensor, set up once from a model dict."""

    def __init__(self, m, base_only=False):
        t_lsb = float(m["t_lsb"])
        t_off = float(m.get("t_off", 0.0))
        if not t_lsb > 0:
            raise ValueError("t_lsb must be positive, got %r" % (t_lsb,))
        raw_lsb = float(m.get("raw_lsb", 1.0))
        if not raw_lsb > 0:
            raise ValueError("raw_lsb must be positive, got %r" % (raw_lsb,))
        self.t_lsb = t_lsb
        self.t_off = t_off
        t0 = float(m.get("t0", 25.0))
        tc = m["t_cal"]
        c_lo = int((float(tc[0]) - t_off) / t_lsb) - 1
        c_hi = int((float(tc[1]) - t_off) / t_lsb) + 2
        # dT counts from the reading nearest t0 (docs: a shift below half a reading step)
        self._t0 = int(round((t0 - t_off) / t_lsb))
        self.t0 = self._t0 * t_lsb + t_off
        t_ref = (c_lo + c_hi) // 2
        offs = []
        scs = []
        for i in range(3):
            o = [float(c) / raw_lsb for c in m["offset"][i]]
            s = [float(c) / raw_lsb for c in m["sensitivity"][i]]
            offs.append(_rebase(o, t_lsb, t_off, t0, t_ref))
            scs.append(_rebase(s, t_lsb, t_off, t0, t_ref))
        rr = m.get("raw_range", (-32768, 32767))
        if max(abs(c_lo), abs(c_hi)) + (c_hi - c_lo) // 2 >= (1 << 16):
            raise ValueError("temperature readings %d..%d: beyond +-2**16 the filters' states "
                             "overflow; use a reading with an offset (t_off)" % (c_lo, c_hi))
        self.comp = Compensator(offs, scs, (c_lo, c_hi), out_scale=float(m.get("out_scale", 1.0)),
                                raw_range=(int(rr[0]), int(rr[1])), policy=EXTRAPOLATE, t_ref=t_ref)
        c = self.comp
        self.out_scale = c.out_scale
        t_lo, t_hi = c.t_in
        self.clamped = 0
        feats = [] if base_only else m.get("features", [])
        nf = len(feats)
        # feature program: kind, arg1, arg2, clamp bound (int), shift (>0 right)
        self._fk = [0] * nf
        self._fa = [0] * nf
        self._fb = [0] * nf
        self._fbound = [0] * nf
        self._fsh = [0] * nf
        self.unit = [0.0] * nf  # physical value of one feature count
        self._f = [0] * nf
        taus = []  # lowpass time constants (ms), shared by lag, play-on-lag and drift_exp
        plays = []  # (half width in state units, lowpass index or -1)
        self._up_sh = 0
        self._up_on = False
        self._hyp = []  # (tau >> e, e)
        self._s_lsb = float(m.get("supply_lsb", 0.001))
        self._s0 = int(round(float(m.get("supply0", 0.0)) / self._s_lsb))
        a_lsb = float(m.get("acc_lsb", 0.001))
        for j in range(nf):
            f = feats[j]
            kind = f["kind"]
            if kind not in KINDS:
                raise ValueError("feature %d: unknown kind %r (one of %s)" % (j, kind, ", ".join(KINDS)))
            k = KINDS.index(kind)
            if k == _PROD and not (0 <= int(f["a"]) < j and 0 <= int(f["b"]) < j):
                raise ValueError("feature %d: prod of features %r and %r; they must come before it"
                                 % (j, f["a"], f["b"]))
            self._fk[j] = k
            bound = float(f.get("bound", 0.0))
            if k == _DT:
                nat = max(abs(t_lo - self._t0), abs(t_hi - self._t0))
                self._set_feat(j, nat, t_lsb)
            elif k == _LAG:
                self._fa[j] = _lp(taus, float(f["tau"]))
                b = bound if bound > 0 else (t_hi - t_lo) * t_lsb
                self._set_feat(j, int(b / t_lsb * (1 << _FV)) + 1, t_lsb / (1 << _FV))
            elif k == _PLAY:
                w = float(f["width"])
                if not w > 0:
                    raise ValueError("feature %d: play width must be positive, got %r" % (j, w))
                lag = float(f.get("lag", 0.0))
                li = _lp(taus, lag) if lag > 0 else -1
                h = int(round(w / 2 / t_lsb * (1 << _FV)))
                self._fa[j] = len(plays)
                plays.append((h, li))
                self._set_feat(j, h, t_lsb / (1 << _FV))
            elif k == _DEXP:
                self._fa[j] = _lp(taus, float(f["tau"]), True)
                self._set_feat(j, _ONE, 1.0 / _ONE)
            elif k == _DHYP:
                tau_ms = float(f["tau"]) * 1000.0
                e = 0
                while tau_ms / (1 << e) >= (1 << 15):
                    e += 1
                self._fa[j] = len(self._hyp)
                self._hyp.append((int(round(tau_ms / (1 << e))), e))
                self._up_on = True
                self._set_feat(j, 1 << 14, 1.0 / (1 << 14))
            elif k == _UP:
                b_ms = (bound if bound > 0 else 86400.0) * 1000.0
                e = 0
                while b_ms / (1 << e) > _FMAX:
                    e += 1
                self._up_sh = e
                self._up_on = True
                self._fsh[j] = 0
                self._fbound[j] = _FMAX
                self.unit[j] = (1 << e) / 1000.0
            elif k == _SUP:
                b = bound if bound > 0 else 1.0
                self._set_feat(j, int(b / self._s_lsb) + 1, self._s_lsb)
            elif k == _ACC:
                ax = int(f["axis"])
                if not 0 <= ax < 3:
                    raise ValueError("feature %d: acc axis %r must be 0, 1 or 2" % (j, ax))
                self._fa[j] = ax
                b = bound if bound > 0 else 4.0
                self._set_feat(j, int(b / a_lsb) + 1, a_lsb)
            else:
                a, b = int(f["a"]), int(f["b"])
                self._fa[j] = a
                self._fb[j] = b
                u = self.unit[a] * self.unit[b]
                nat = _FMAX * _FMAX
                if bound > 0:
                    nat = min(nat, int(bound / u) + 1)
                self._set_feat(j, nat, u)
        self._ntau = len(taus)
        self._tau_ms = [t[0] * 1000.0 for t in taus]
        # alpha tables: 1 - exp(-2**k ms / tau) in Q28
        self._atab = []
        for tau_ms in self._tau_ms:
            self._atab.append([min(_ONE, _fix(1.0 - _exp(-float(1 << kk) / tau_ms), _Q)) for kk in range(_TAB)])
        self._alpha = [0] * len(taus)
        self._v = [0] * len(taus)  # lowpass states (t * 2**12), drift ones in Q28
        self._w = [0] * len(taus)  # sub-unit carries
        self._drift = [t[1] for t in taus]  # drift states decay to 0 instead of following T
        self._plays = plays
        self._p = [0] * len(plays)
        self._nplay = len(plays)
        self._dt = -1
        self._last = 0
        self._started = False
        self._up = 0  # uptime, ms (saturates)
        # coefficients
        self._oc = [[], [], []]
        self._oi = [[], [], []]
        self._gc = [[], [], []]
        self._gi = [[], [], []]
        self._kc = [[], [], []]
        self._kk = [[], [], []]
        self._k1 = [[], [], []]
        self._fo = [0, 0, 0]
        dti = -1
        for j in range(nf):
            if self._fk[j] == _DT:
                dti = j
        self._dti = dti
        if not base_only:
            self._set_terms(m, nf)
        self._y = [0, 0, 0]
        self._y0 = [0, 0, 0]
        self._inv = [_ONE, _ONE, _ONE]
        self._kmat = [0] * 9
        self._cross = any(self._kk[i] for i in range(3))
        # rho_i(T) = s_i(t0) / s_i(T): the terms are fractions of the sensitivity at t0
        self._rho_on = self._cross or any(self._gc[i] for i in range(3))
        self._rho = [_ONE, _ONE, _ONE]
        self._rt = None
        c.update(self._t0 if t_lo <= self._t0 <= t_hi else (t_lo + t_hi) // 2)
        self._g0 = [((c._gh[i] << c._k) + c._gl[i]) >> 2 for i in range(3)]
        self.start(0)

    def _set_feat(self, j, nat, unit):
        # clamp bound `nat` (natural units of `unit` each) and the shift that brings it to 2**15
        nat = int(nat)
        sh = 0
        while (nat >> sh) > _FMAX:
            sh += 1
        while sh <= 0 and sh > -15 and (nat << (1 - sh)) <= _FMAX:
            sh -= 1  # a short range is spread over 2**14..2**15 counts: small per-count coefficients
        self._fbound[j] = nat
        self._fsh[j] = sh
        self.unit[j] = unit * (1 << sh) if sh >= 0 else unit / (1 << -sh)

    def _fmax(self, j):
        # largest |feature count| after the clamp and the shift
        sh = self._fsh[j]
        if sh <= 0:
            return self._fbound[j] << -sh
        return min(_FMAX, (self._fbound[j] + (1 << sh) - 1) >> sh)

    def _set_terms(self, m, nf):
        ot = m.get("offset_terms") or [[], [], []]
        gt = m.get("gain_terms") or [[], [], []]
        cr = m.get("cross") or [[], [], []]
        raw_lsb = float(m.get("raw_lsb", 1.0))
        for i in range(3):
            tot = 0.0
            for fi, cc in ot[i]:
                if not 0 <= int(fi) < nf:
                    raise ValueError("offset term of axis %d names feature %r of %d" % (i, fi, nf))
                tot += abs(float(cc) / raw_lsb) * self.unit[int(fi)] * self._fmax(int(fi))
            if tot > (1 << 15):
                raise ValueError("axis %d: offset terms reach %r raw codes at the features' bounds; "
                                 "more than the raw range" % (i, tot))
            # and each coefficient alone within mul_shift's 2**28 (counts up to 2**15)
            tot = max(tot, max([abs(float(cc) / raw_lsb) * self.unit[int(fi)] for fi, cc in ot[i]] + [0.0]) * (1 << 15))
            fo = 0
            while fo < 24 and tot * (1 << (fo + 1)) <= (1 << 28):
                fo += 1
            if fo < 8:
                raise ValueError("axis %d: offset terms too large for 8 fraction bits" % i)
            self._fo[i] = fo
            for fi, cc in ot[i]:
                self._oi[i].append(int(fi))
                self._oc[i].append(_fix(float(cc) / raw_lsb * self.unit[int(fi)], fo + 15))
            tot = 0.0
            for fi, g in gt[i]:
                if not 0 <= int(fi) < nf:
                    raise ValueError("gain term of axis %d names feature %r of %d" % (i, fi, nf))
                tot += abs(float(g)) * self.unit[int(fi)] * self._fmax(int(fi))
                self._gi[i].append(int(fi))
                self._gc[i].append(_fix(float(g) * self.unit[int(fi)], _Q + 15))
            if tot > _E_MAX:
                raise ValueError("axis %d: sensitivity terms reach %r at the features' bounds; at most "
                                 "%r are supported" % (i, tot, _E_MAX))
            dt_u = self.unit[self._dti] * self._fmax(self._dti) if self._dti >= 0 else 0.0
            for k, k0, k1 in cr[i]:
                k = int(k)
                if not 0 <= k < 3 or k == i:
                    raise ValueError("cross term of axis %d names axis %r" % (i, k))
                if float(k1) != 0 and self._dti < 0:
                    raise ValueError("cross term with a temperature part needs a dT feature")
                if abs(float(k0)) + abs(float(k1)) * dt_u > _E_MAX:
                    raise ValueError("axis %d: cross-axis term from axis %d above %r" % (i, k, _E_MAX))
                self._kk[i].append(k)
                self._kc[i].append(_fix(float(k0), _Q))
                self._k1[i].append(_fix(float(k1) * (self.unit[self._dti] if self._dti >= 0 else 0.0), _Q + 15))

    def start(self, uptime_ms=0):
        """Power-on state: filters restart at the next reading, uptime counts from uptime_ms."""
        self._started = False
        self._ticked = False
        self._up = int(uptime_ms)
        for i in range(self._ntau):
            self._w[i] = 0
            if self._drift[i]:
                self._v[i] = _fix(_exp(-float(uptime_ms) / self._tau_ms[i]), _Q)

    def _alphas(self, dt):
        # alpha(dt) = 1 - prod_k (1 - alpha(2**k)) over dt's set bits; only when dt changes
        self._dt = dt
        tabs = self._atab
        i = 0
        while i < self._ntau:
            tab = tabs[i]
            a = 0
            k = 0
            d = dt
            while d:
                if d & 1:
                    b = tab[k]
                    a = a + b - _mul28(a, b)
                d >>= 1
                k += 1
            self._alpha[i] = a
            i += 1

    def _filters(self, t, dt):
        v = self._v
        w = self._w
        x = t << _FV
        if not self._started:
            self._started = True
            i = 0
            while i < self._ntau:
                if not self._drift[i]:
                    v[i] = x
                i += 1
            i = 0
            while i < self._nplay:
                h, li = self._plays[i]
                self._p[i] = x if li < 0 else v[li]
                i += 1
            return
        if dt != self._dt:
            self._alphas(dt)
        al = self._alpha
        i = 0
        while i < self._ntau:
            # v += alpha * (target - v), exactly to 2**-16 of a state unit (carry in w):
            # |target - v| <= 2**28, alpha <= 2**28
            a = al[i]
            d = (0 if self._drift[i] else x) - v[i]
            ah = a >> 14
            al_ = a & 0x3FFF
            dh = d >> 14
            dl = d & 0x3FFF
            mid = ah * dl + al_ * dh
            lo = ((mid & 0x3FFF) << 14) + al_ * dl
            q = ah * dh + (mid >> 14) + (lo >> 28)
            s = w[i] + ((lo & 0xFFFFFFF) >> 12)
            v[i] += q + (s >> _SUB)
            w[i] = s & 0xFFFF
            i += 1
        i = 0
        while i < self._nplay:
            h, li = self._plays[i]
            xi = x if li < 0 else v[li]
            p = self._p[i]
            if xi - h > p:
                self._p[i] = xi - h
            elif xi + h < p:
                self._p[i] = xi + h
            i += 1

    def _features(self, t, supply, acc):
        f = self._f
        fk = self._fk
        x = t << _FV
        j = 0
        n = len(f)
        while j < n:
            k = fk[j]
            if k == _DT:
                nat = t - self._t0
            elif k == _LAG:
                nat = x - self._v[self._fa[j]]
            elif k == _PLAY:
                h, li = self._plays[self._fa[j]]
                nat = self._p[self._fa[j]] - (x if li < 0 else self._v[li])
            elif k == _DEXP:
                nat = self._v[self._fa[j]]
            elif k == _DHYP:
                tau, e = self._hyp[self._fa[j]]
                nat = (tau << 14) // (tau + (self._up >> e))
            elif k == _UP:
                nat = self._up >> self._up_sh
            elif k == _SUP:
                nat = supply - self._s0
            elif k == _ACC:
                nat = acc[self._fa[j]]
            else:
                nat = f[self._fa[j]] * f[self._fb[j]]
            b = self._fbound[j]
            if nat > b:
                nat = b
                self.clamped += 1
            elif nat < -b:
                nat = -b
                self.clamped += 1
            sh = self._fsh[j]
            if sh < 0:
                nat <<= -sh
            elif sh:
                nat = (nat + (1 << (sh - 1))) >> sh
                if nat > _FMAX:
                    nat = _FMAX
                elif nat < -_FMAX:
                    nat = -_FMAX
            f[j] = nat
            j += 1

    def apply(self, t, raw, out, dt_ms=-1, supply=0, acc=None):
        """Compensate raw[0..2] at temperature reading t into out[0..2]; zero allocation."""
        if dt_ms < 0:
            now = _ticks()
            dt_ms = _ticks_diff(now, self._last) if self._ticked else 0
            self._last = now
            self._ticked = True
        if dt_ms > _DT_MAX:
            dt_ms = _DT_MAX
        if self._up_on:
            u = self._up + dt_ms
            self._up = u if u < (1 << 30) - _DT_MAX else self._up
        c = self.comp
        c.update(t)
        t = c._t  # the reading as clamped to the proven input range
        if self._ntau or self._nplay:
            self._filters(t, dt_ms)
        if self._f:
            self._features(t, supply, acc)
        f = self._f
        if self._rho_on and t != self._rt:
            self._rt = t
            i = 0
            while i < 3:
                # G = gain * 2**(K+S) <= 2**28; G / G0 < 2 (the scale varies at most 2x)
                self._rho[i] = div_pow2(((c._gh[i] << c._k) + c._gl[i]) >> 2, _Q, self._g0[i])
                i += 1
        gh = c._gh
        gl = c._gl
        b = c._b
        K = c._k
        S2 = c._s - 2
        rnd = 1 << (S2 - 1)
        lim = 1 << K
        mid = c._mid
        y0 = self._y0
        inv = self._inv
        i = 0
        while i < 3:
            fo = self._fo[i]
            d = 0
            cs = self._oc[i]
            fi = self._oi[i]
            j = 0
            n = len(cs)
            while j < n:
                d += mul_shift(cs[j], f[fi[j]], 15)
                j += 1
            # dO = di + fr / 256 raw codes
            di = d >> fo
            fr = (d >> (fo - 8)) & 0xFF
            r = raw[i] - mid - di
            if r > lim:
                r = lim
                self.clamped += 1
            elif r < -lim:
                r = -lim
                self.clamped += 1
            g = gh[i]
            y0[i] = (r * g + ((r * gl[i]) >> K) - b[i] - ((fr * g) >> 8) + rnd) >> S2
            cs = self._gc[i]
            n = len(cs)
            if n:
                fi = self._gi[i]
                e = 0
                j = 0
                while j < n:
                    e += mul_shift(cs[j], f[fi[j]], 15)
                    j += 1
                e = _mul28(self._rho[i], e)
                # 1 / (1 + e) = 1 - e (1 - e (1 - e (1 - e))) + O(e**5), |e| <= 1/8
                q = _ONE - e
                q = _ONE - _mul28(e, q)
                q = _ONE - _mul28(e, q)
                inv[i] = _ONE - _mul28(e, q)
            else:
                inv[i] = _ONE
            i += 1
        y = self._y
        if self._cross:
            km = self._kmat
            dtf = f[self._dti] if self._dti >= 0 else 0
            i = 0
            while i < 3:
                ks = self._kk[i]
                j = 0
                while j < len(ks):
                    km[i * 3 + ks[j]] = _mul28(self._rho[i], self._kc[i][j] + mul_shift(self._k1[i][j], dtf, 15))
                    j += 1
                y[i] = _mul28(y0[i], inv[i])
                i += 1
            it = 0
            while it < 2:
                # y = (y0 - K y) / (1 + e): a contraction (|K| <= 1/16), two steps leave ~|K|**3
                a0 = y0[0] - _mul28(km[1], y[1]) - _mul28(km[2], y[2])
                a1 = y0[1] - _mul28(km[3], y[0]) - _mul28(km[5], y[2])
                a2 = y0[2] - _mul28(km[6], y[0]) - _mul28(km[7], y[1])
                y[0] = _mul28(a0, inv[0])
                y[1] = _mul28(a1, inv[1])
                y[2] = _mul28(a2, inv[2])
                it += 1
        else:
            y[0] = _mul28(y0[0], inv[0])
            y[1] = _mul28(y0[1], inv[1])
            y[2] = _mul28(y0[2], inv[2])
        out[0] = (y[0] + 2) >> 2
        out[1] = (y[1] + 2) >> 2
        out[2] = (y[2] + 2) >> 2


def _lp(taus, tau, drift=False):
    # one state per (time constant, kind): lag and play-on-lag of one tau share it
    if not tau > 0:
        raise ValueError("time constant must be positive, got %r s" % (tau,))
    for i in range(len(taus)):
        if taus[i][0] == tau and taus[i][1] == drift:
            return i
    taus.append((tau, drift))
    return len(taus) - 1


def _rebase(c, t_lsb, t_off, t0, t_ref):
    # powers of (T - t0) degC -> powers of (t - t_ref) readings: T - t0 = t_lsb (t - t_ref) + d
    d = t_ref * t_lsb + t_off - t0
    b = shift_basis(c, 0.0, d)  # powers of (u - d) = t_lsb * (t - t_ref), u = T - t0
    return [b[k] * t_lsb ** k for k in range(len(b))]
