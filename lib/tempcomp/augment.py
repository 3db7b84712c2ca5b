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
    aug.apply_be16_n(t, buf, out, n, dt_ms, supply, acc)   # a FIFO burst of n samples

``t`` is the temperature reading (``T = t * t_lsb + t_off`` degC), ``raw`` the raw codes
(``raw * raw_lsb`` out units), ``supply`` the supply reading (``supply * supply_lsb`` V), ``acc``
the accelerometer (``acc * acc_lsb`` g); ``out`` receives ref * out_scale, rounded. ``dt_ms`` is the
time since the previous sample in ms, or -1 to take it from ``time.ticks_ms()``. All six are
positional and required (pass 0 and None for a supply and an accelerometer the model does not
read): the native kernel is a viper method, which takes no defaults. Call ``aug.apply(...)``
itself in the loop: a bound method made beforehand (``ap = aug.apply``) copies more than four
arguments through the heap on every call. A burst (``layout()`` says where each sample's words
are: raw codes, optionally the accelerometer's and the temperature, big-endian int16) gives the
same numbers as its samples through ``apply``, dt_ms apart, with t, supply and acc held unless
the layout reads them from each sample. ``clamped()`` counts the values clamped so far.

Where the interpreter has the viper emitter and 32-bit ints (MicroPython on Cortex-M), ``apply``
and ``apply_be16_n`` are tempcomp.augment_native's viper methods, and a sample's body runs in
asm_thumb (tempcomp.augment_thumb, Thumb-1: Cortex-M0+ to M7); elsewhere the pure-Python kernel
(tempcomp.augment_pure, imported when a model first needs it), which they reproduce bit for bit
(``use_native(False)`` picks it). Work is
done as rarely as its inputs change: the model's integers at set-up, the base gain and offset
term, rho, the features of the reading alone (dT and products of them) with their terms, and the
cross matrix when the reading changes (``augment_pure.step``; the native kernels split it: the
base's part in viper, the terms' part in the sample kernel, asm_thumb, on the first sample that
sees the new reading), the filters' steps alpha when dt changes, the rest per sample.

Fixed point (B = 2**30 is the small-int bound; every clamp is counted in ``clamped()``):

* Features are ints with |f| < 2**15 in units fixed at set-up (each clamped to its bound).
  Filter states are t-readings * 2**12 (|.| <= 2**27) plus a 16-bit sub-unit carry, so a
  slow filter never stalls; the step alpha = 1 - exp(-dt/tau) is in Q28, built from a table
  of exp(-2**k ms/tau) when dt changes.
* Terms ``mul_shift(c, f, 15)`` with |c| <= 2**28, by c's 14-bit limbs (|c >> 14| <= 2**14:
  each product <= 2**29): sum of |c| <= 2**28 per axis, so dO (in 2**-F raw units) and e (Q28,
  |e| <= 1/16) stay below 2**29.
* The base step is the Compensator's, with dO's integer part taken off the raw code and its
  8-bit fraction times the gain's high limb (<= 2**21) added: the sum stays below 2**30, and
  the result keeps 2 guard bits (|y| <= 2**25).
* e and K are scaled by rho = s(t0)/s(T) (Q28) = (G << s) R / 2**26 on a new reading, G the
  Compensator's gain, R = 2**54 / (G0 << s) from set-up with G0 << s in [2**26, 2**27): G << s
  < 2**28 (the scale varies at most 2x), 4 ah bh < 2**30 (``_mul26``); 1/(1+e) by its series to
  e**4 (error < 2**-15 of y) and the cross-axis solve by two fixed-point iterations
  y = (y0 - K y) / (1 + e) (error ~|K|**3 of y); all products Q28 by 14-bit limbs (``_mul28``).
* drift_hyp's (tau >> e) << 14 // (tau + (uptime >> e)): the quotient has 15 bits (the asm
  kernel divides bit by bit: the Cortex-M0+ has no divider).
"""

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


import time

from tempcomp.fixedpoint import EXTRAPOLATE, Compensator, div_pow2, shift_basis

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
_DT = const(0)  # KINDS' indices
_LAG = const(1)
_PLAY = const(2)
_DEXP = const(3)
_DHYP = const(4)
_UP = const(5)
_SUP = const(6)
_ACC = const(7)
_PROD = const(8)


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


# The model compiled into one flat list of ints (self._w; a 32-bit array where the native kernel
# runs), read and written alike by the pure kernel below, tempcomp.augment_native (viper) and
# tempcomp.augment_thumb (asm_thumb): the layout constants are repeated there and
# host_tests/augment/test_augment_kernels.py checks that they agree. Words 0..31 are what the
# asm_thumb kernel reads by immediate offset; then the rest of the header, three per-axis
# blocks, and the sections whose positions the header holds.
_CL = const(0)  # clamps counted: features, raw codes, readings
_XS = const(1)  # the sample's reading << 12
_TS = const(2)  # the reading the step features are for (native: the terms' step runs when it is not _TC)
_SUPS = const(3)  # the supply reading
_AS = const(4)  # the acceleration (3 words)
_UPT = const(7)  # uptime, ms (saturates)
_MID = const(8)  # the raw range's middle, its half-span 2**K, K, S - 2, the rounding 2**(S-3)
_LIM = const(9)
_KB = const(10)
_S2 = const(11)
_RND = const(12)
_NTAU = const(13)  # lowpass states: count, first record (_TREC words each)
_PTAU = const(14)
_NPLAY = const(15)  # play states: count, first record (half width, input state or -1, p)
_PPLAY = const(16)
_NSF = const(17)  # sample features: count, first record (_FREC words each)
_PSF = const(18)
_FL = const(19)  # flags, _F*
_KONE = const(20)  # 2**28, 32767 for the asm kernel
_KFMAX = const(21)
_O = const(22)  # the sample's outputs (3 words)
_SCL = const(25)  # clamps of the step features at reading _TC, counted again every sample
_FILT = const(26)  # 1: the filters step with this sample (not its first)
_SCR = const(27)  # scratch for the asm kernel (5 words)
_SRC = const(32)  # the asm kernel's run (words 32..43 from a second base): the source's address,
_OUTP = const(33)  # the outputs' address, samples left, the source's kind (0: int32 words, 1: a
_NS = const(34)  # burst's big-endian int16 bytes at a stride)
_MODE = const(35)
_STR = const(36)  # burst layout: stride, byte offsets of the raw and acc words (temperature: _TOFF)
_ROFF = const(37)
_AOFF = const(38)
_DTR = const(39)  # the ms each sample adds to the uptime, -1: no uptime to count
_HASF = const(40)  # 1: the model has filters (they step from a run's second sample on)
_NHYP = const(41)  # drift_hyp values: count, first record (value index, tau >> e, e)
_PHYP = const(42)
_UPMAX = const(43)  # the uptime saturates below it: 2**30 - _DT_MAX
_TC = const(44)  # the reading the step values are for (t_lo - 1: none yet)
_TLO = const(45)
_THI = const(46)
_DTC = const(47)  # the dt (ms) the filters' alphas are for (-1: none yet)
_LAST = const(48)  # ticks_ms at the last sample taken with dt_ms = -1
_NB = const(49)  # apply_be16_n: samples in the burst
_TOFF = const(50)
_CRAW = const(51)  # buffer addresses of the arrays the native kernel has checked: a sample's,
_COUT = const(52)
_CACC = const(53)
_NTF = const(54)  # step features (dT and products of them): count, first record
_PTF = const(55)
_DTI = const(56)  # the dT feature's value (the cross terms' temperature part), -1: none
_PUPD = const(57)  # native: the base update's integers, _UREC words per axis
_NEED = const(58)  # bytes of a burst sample the layout reads
_CBOUT = const(59)  # a burst's
_CBACC = const(60)
_SMALL = const(61)  # 1: the array's address is a small int (the kernel passes it as one)
_AXB = const(62)  # the per-axis blocks, _AXS words each (then words 128..):
_AXS = const(22)
_GH = const(0)  # the base gain (high, low limb) and offset term
_GL = const(1)
_B = const(2)
_RHO = const(3)  # s(t0) / s(T), Q28
_DS = const(4)  # the step features' share of the offset terms (dO) and of e
_ES = const(5)
_FO = const(6)  # fraction bits of dO
_AF = const(7)  # the axis' terms: _AGAIN sensitivity, _AOFFS offset, _ACROSS cross-axis
_AGAIN = const(1)
_AOFFS = const(2)
_ACROSS = const(4)
_ASTEPT = const(8)  # the axis has terms of step features (their share computed per reading)
_OT = const(8)  # where the axis' term lists start: count, then (value index, coefficient)
_GT = const(9)
_CR = const(10)  # cross terms: count, then (axis k, k0, k1), one per k
_Y0 = const(11)
_INV = const(12)  # 1 / (1 + rho e), Q28
_Y = const(13)
_KM = const(14)  # the cross matrix' row (3 words), rho-scaled, per step
_RAW = const(17)
_SOT = const(18)  # the step features' term lists
_SGT = const(19)
_RS = const(20)  # rho: the gain's shift and the reciprocal of the gain at t0
_RR = const(21)
_CBUF = const(128)  # a burst's checked buffer, its length, the checked out array's length
_CBUFN = const(129)
_CBOUTN = const(130)
_TSPAN = const(131)  # native: t_hi - t_lo, 2 * 2**K, the base's rounding and shift to the output
_LIM2 = const(132)
_RNDO = const(133)
_S2O = const(134)
_HDR = const(135)
_TREC = const(30)  # lowpass record: drift flag, alpha, state, carry, then the alpha table
_FREC = const(6)  # feature record: operation, value index, s1, s2, bound, shift
_OSUB = const(0)  # the record's operations: w[s1] - w[s2]
_OSUBC = const(1)  # w[s1] - s2
_OSHR = const(2)  # w[s1] >> s2
_OMUL = const(3)  # w[s1] * w[s2]
_UREC = const(30)  # base update record (augment_native)

_FUP = const(1)  # uptime counts
_FFILT = const(2)  # lowpass or play states
_FSTART = const(4)  # the filters have had their first reading
_FTICK = const(8)  # _LAST holds a ticks_ms value
_FRHO = const(16)  # sensitivity or cross terms: rho per step
_FCROSS = const(32)
_FGEN = const(64)  # features or terms: the general per-sample path
_FACC = const(128)  # a feature reads acc
_FDT = const(256)  # dt is used (uptime or filters)
_FSUP = const(512)  # a feature reads the supply
_FBURST = const(1024)  # apply_be16_n's call: _NB samples from a burst


_native = None  # None: the native kernel where the interpreter has one; True/False: forced
_kmod = None
_ktried = False


def _kernel():
    # imported on first use (boot RAM holds no native code until a model is built); only on
    # 32-bit machines, where its 32-bit words are the machine's ints
    global _kmod, _ktried
    if not _ktried:
        _ktried = True
        try:
            import gc
            import sys

            gc.collect()  # the kernels' machine code wants large blocks
            if sys.maxsize >> 31 == 0:
                try:
                    from tempcomp import augment_native
                except ValueError:
                    # an armv7m .mpy on a Cortex-M0+ (RP2040): the armv6m build beside it (make dist)
                    from tempcomp import augment_native_m0 as augment_native  # pyright: ignore[reportAttributeAccessIssue]

                _kmod = augment_native
                Augmented.apply = augment_native.apply  # pyright: ignore[reportAttributeAccessIssue]
                Augmented.apply_be16_n = augment_native.apply_be16_n  # pyright: ignore[reportAttributeAccessIssue]
        except (ImportError, SyntaxError, ValueError, NotImplementedError, AttributeError, MemoryError):
            # CPython, a port without the viper emitter, a .mpy for another architecture, or a
            # heap too small to compile the kernels from .py (the .mpy load in a quarter of it)
            _kmod = None
    return _kmod


_pmod = None


def _pure():
    # the pure-Python kernel, imported when a model first runs it; the class's apply where there
    # is no native one, and _papply / _papply_n for models forced to it beside the native ones
    global _pmod
    if _pmod is None:
        from tempcomp import augment_pure

        _pmod = augment_pure
        Augmented._papply = augment_pure.apply  # pyright: ignore[reportAttributeAccessIssue]
        Augmented._papply_n = augment_pure.apply_be16_n  # pyright: ignore[reportAttributeAccessIssue]
        if _kernel() is None:
            Augmented.apply = augment_pure.apply  # pyright: ignore[reportAttributeAccessIssue]
            Augmented.apply_be16_n = augment_pure.apply_be16_n  # pyright: ignore[reportAttributeAccessIssue]
    return _pmod


def use_native(on=None):
    """Choose the per-sample kernel of Augmented models built from now on.

    None (default): native (viper, with asm_thumb where the port has it) where the interpreter
    has the viper emitter, else pure Python; True: native or ValueError; False: pure Python.
    Returns True when native will be used. Both give bit-identical results.
    """
    global _native
    if on and _kernel() is None:
        raise ValueError("use_native(True): this interpreter has no @micropython.viper emitter")
    _native = None if on is None else bool(on)
    return _native is not False and _kernel() is not None


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
        t0 = float(m.get("t0", 25.0))
        tc = m["t_cal"]
        c_lo = int((float(tc[0]) - t_off) / t_lsb) - 1
        c_hi = int((float(tc[1]) - t_off) / t_lsb) + 2
        # dT counts from the reading nearest t0 (docs: a shift below half a reading step)
        t0r = int(round((t0 - t_off) / t_lsb))
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
        t_lo, t_hi = c.t_in
        feats = [] if base_only else m.get("features", [])
        nf = len(feats)
        # feature program: kind, arg1, arg2, clamp bound (int), shift (>0 right)
        fk = [0] * nf
        fa = [0] * nf
        fb = [0] * nf
        fbound = [0] * nf
        fsh = [0] * nf
        self.unit = [0.0] * nf  # physical value of one feature count
        taus = []  # lowpass time constants (s), shared by lag, play-on-lag and drift_exp
        plays = []  # (half width in state units, lowpass index or -1)
        s_lsb = float(m.get("supply_lsb", 0.001))
        s0 = int(round(float(m.get("supply0", 0.0)) / s_lsb))
        a_lsb = float(m.get("acc_lsb", 0.001))
        fl = 0
        for j in range(nf):
            f = feats[j]
            kind = f["kind"]
            if kind not in KINDS:
                raise ValueError("feature %d: unknown kind %r (one of %s)" % (j, kind, ", ".join(KINDS)))
            k = KINDS.index(kind)
            if k == _PROD and not (0 <= int(f["a"]) < j and 0 <= int(f["b"]) < j):
                raise ValueError("feature %d: prod of features %r and %r; they must come before it"
                                 % (j, f["a"], f["b"]))
            fk[j] = k
            bound = float(f.get("bound", 0.0))
            nat = 0  # the clamp bound in natural units of `u` each
            u = 1.0
            if k == _DT:
                fa[j] = t0r
                nat, u = max(abs(t_lo - t0r), abs(t_hi - t0r)), t_lsb
            elif k == _LAG:
                fa[j] = _lp(taus, float(f["tau"]))
                b = bound if bound > 0 else (t_hi - t_lo) * t_lsb
                nat, u = int(b / t_lsb * (1 << _FV)) + 1, t_lsb / (1 << _FV)
            elif k == _PLAY:
                wd = float(f["width"])
                if not wd > 0:
                    raise ValueError("feature %d: play width must be positive, got %r" % (j, wd))
                lag = float(f.get("lag", 0.0))
                li = _lp(taus, lag) if lag > 0 else -1
                h = int(round(wd / 2 / t_lsb * (1 << _FV)))
                fa[j] = len(plays)
                plays.append((h, li))
                nat, u = h, t_lsb / (1 << _FV)
            elif k == _DEXP:
                fa[j] = _lp(taus, float(f["tau"]), True)
                nat, u = _ONE, 1.0 / _ONE
            elif k == _DHYP:
                tau_ms = float(f["tau"]) * 1000.0
                if not tau_ms >= 1.0:
                    raise ValueError("feature %d: drift_hyp tau must be at least 1 ms, got %r s" % (j, f["tau"]))
                e = 0
                while tau_ms / (1 << e) >= (1 << 15):
                    e += 1
                fa[j] = int(round(tau_ms / (1 << e)))  # (tau >> e) << 14 < 2**29
                fb[j] = e
                fl |= _FUP
                nat, u = 1 << 14, 1.0 / (1 << 14)
            elif k == _UP:
                b_ms = (bound if bound > 0 else 86400.0) * 1000.0
                e = 0
                while b_ms / (1 << e) > _FMAX:
                    e += 1
                fa[j] = e
                fl |= _FUP
                fbound[j] = _FMAX
                self.unit[j] = (1 << e) / 1000.0
                continue
            elif k == _SUP:
                fa[j] = s0
                fl |= _FSUP
                b = bound if bound > 0 else 1.0
                nat, u = int(b / s_lsb) + 1, s_lsb
            elif k == _ACC:
                ax = int(f["axis"])
                if not 0 <= ax < 3:
                    raise ValueError("feature %d: acc axis %r must be 0, 1 or 2" % (j, ax))
                fa[j] = ax
                fl |= _FACC
                b = bound if bound > 0 else 4.0
                nat, u = int(b / a_lsb) + 1, a_lsb
            else:
                a, b = int(f["a"]), int(f["b"])
                fa[j] = a
                fb[j] = b
                u = self.unit[a] * self.unit[b]
                nat = _FMAX * _FMAX
                if bound > 0:
                    nat = min(nat, int(bound / u) + 1)
            # the shift that brings the bound to 2**15 counts; a short range is spread over
            # 2**14..2**15 counts, for small per-count coefficients
            nat = int(nat)
            sh = 0
            while (nat >> sh) > _FMAX:
                sh += 1
            while sh <= 0 and sh > -15 and (nat << (1 - sh)) <= _FMAX:
                sh -= 1
            fbound[j] = nat
            fsh[j] = sh
            self.unit[j] = u * (1 << sh) if sh >= 0 else u / (1 << -sh)
        # largest |feature count| after the clamp and the shift
        fmax = [fbound[j] << -fsh[j] if fsh[j] <= 0 else min(_FMAX, (fbound[j] + (1 << fsh[j]) - 1) >> fsh[j])
                for j in range(nf)]
        dti = -1
        for j in range(nf):
            if fk[j] == _DT:
                dti = j
        # step features: those of the reading alone (dT, products of them), once per new reading
        step = [False] * nf
        for j in range(nf):
            step[j] = fk[j] == _DT or (fk[j] == _PROD and step[fa[j]] and step[fb[j]])
        terms = [[[], [], [], [], 0] for _ in range(3)]  # sample/step offset, sample/step gain, fo
        cross = [[], [], []]
        if not base_only:
            self._set_terms(m, nf, dti, step, fmax, terms, cross)
        # the base: the Compensator's gain and offset term at each reading (pure: its update();
        # native: the same integers from _UREC records)
        c.update(t0r if t_lo <= t0r <= t_hi else (t_lo + t_hi) // 2)
        w = [0] * _HDR
        w[_TC] = t_lo - 1
        w[_TS] = t_lo - 1  # the native kernels run the terms' step when _TS differs from _TC
        w[_TLO] = t_lo
        w[_THI] = t_hi
        w[_DTC] = -1
        w[_MID] = c._mid
        w[_LIM] = 1 << c._k
        w[_KB] = c._k
        w[_S2] = c._s - 2
        w[_RND] = 1 << (c._s - 3)
        w[_TSPAN] = t_hi - t_lo
        w[_LIM2] = 2 << c._k
        w[_RNDO] = (1 << (c._s - 3)) + (1 << (c._s - 1))  # ((y + rnd) >> (S - 2) + 2) >> 2
        w[_S2O] = c._s
        w[_KONE] = _ONE
        w[_KFMAX] = _FMAX
        w[_DTI] = -1
        w[_STR] = 6
        w[_AOFF] = -1
        w[_TOFF] = -1
        w[_NEED] = 6
        w[_UPMAX] = (1 << 30) - _DT_MAX
        for i in range(3):
            ab = _AXB + _AXS * i
            w[ab + _GH] = c._gh[i]
            w[ab + _GL] = c._gl[i]
            w[ab + _B] = c._b[i]
            w[ab + _RHO] = _ONE
            w[ab + _INV] = _ONE  # an axis without sensitivity terms keeps it
            # rho = G / G0 = (G << s) * R / 2**26 with G0 << s in [2**26, 2**27) and
            # R = floor(2**54 / (G0 << s)) in (2**27, 2**28]: G << s < 2**28 (G < 2 G0)
            g0 = ((c._gh[i] << c._k) + c._gl[i]) >> 2
            sh = 0
            while (g0 << sh) < (1 << 26):
                sh += 1
            while (g0 << sh) >= (1 << 27):
                sh -= 1
            w[ab + _RS] = sh
            w[ab + _RR] = div_pow2(1 << 26, 28, g0 << sh) if sh >= 0 else 0
            if sh < 0:
                raise ValueError("axis %d: gain %r beyond the fixed-point range" % (i, g0))
        w[_PUPD] = len(w)
        for i in range(3):
            w.extend(_urec(c, i))
        # lowpass records with their alpha tables: 1 - exp(-2**k ms / tau) in Q28
        w[_NTAU] = len(taus)
        w[_PTAU] = len(w)
        for tau, drift in taus:
            w.extend([1 if drift else 0, 0, 0, 0])
            w.extend([min(_ONE, _fix(1.0 - _exp(-float(1 << kk) / (tau * 1000.0)), _Q)) for kk in range(_TAB)])
        w[_NPLAY] = len(plays)
        w[_PPLAY] = len(w)
        for h, li in plays:
            w.extend([h, 4 * (w[_PTAU] + _TREC * li + 2) if li >= 0 else -1, 0])
        fv = len(w)  # feature values
        w.extend([0] * nf)
        if dti >= 0:
            w[_DTI] = fv + dti
        hyp = []
        for stp in (False, True):
            recs = ([], [], [], [])  # by operation: the asm kernel runs each group without a test;
            for j in range(nf):  # products come last, in order (they read earlier values)
                if step[j] != stp:
                    continue
                k = fk[j]
                a, b = fa[j], fb[j]
                if k == _DT:
                    op, a, b = _OSUBC, _TS, a
                elif k == _LAG:
                    op, a, b = _OSUB, _XS, w[_PTAU] + _TREC * a + 2
                elif k == _PLAY:
                    pl = w[_PPLAY] + 3 * a
                    op, a, b = _OSUB, pl + 2, w[pl + 1] >> 2 if w[pl + 1] >= 0 else _XS
                elif k == _DEXP:
                    op, a, b = _OSUBC, w[_PTAU] + _TREC * a + 2, 0
                elif k == _DHYP:
                    # (tau << 14) // (tau + (uptime >> e)), computed before the records run
                    hyp.append((4 * (fv + j), a, b))
                    op, a, b = _OSUBC, fv + j, 0
                elif k == _UP:
                    op, a, b = _OSHR, _UPT, a
                elif k == _SUP:
                    op, a, b = _OSUBC, _SUPS, a
                elif k == _ACC:
                    op, a, b = _OSUBC, _AS + a, 0
                else:
                    op, a, b = _OMUL, fv + a, fv + b
                # the words' indices as byte offsets (the asm kernel's register-offset loads)
                recs[op].append([op, 4 * (fv + j), 4 * a, 4 * b if op in (_OSUB, _OMUL) else b, fbound[j], fsh[j]])
            w[_NTF if stp else _NSF] = sum(len(g) for g in recs)
            w[_PTF if stp else _PSF] = len(w)
            w.extend([len(g) for g in recs])
            for g in recs:
                for r in g:
                    w.extend(r)
        w[_NHYP] = len(hyp)
        w[_PHYP] = len(w)
        for r in hyp:
            w.extend(r)
        for i in range(3):
            ab = _AXB + _AXS * i
            so, to, sg, tg, fo = terms[i]
            w[ab + _FO] = fo
            w[ab + _AF] = ((_AGAIN if sg or tg else 0) | (_AOFFS if so or to else 0) | (_ACROSS if cross[i] else 0)
                           | (_ASTEPT if to or tg else 0))
            for slot, lst in ((_OT, so), (_SOT, to), (_GT, sg), (_SGT, tg)):
                w[ab + slot] = len(w)
                w.append(len(lst))
                for fi, cc in lst:
                    w.extend([4 * (fv + fi), cc >> 14, cc & 0x3FFF])  # the value's byte offset, c's limbs
            w[ab + _CR] = len(w)
            w.append(len(cross[i]))
            for r in cross[i]:
                w.extend(r)
            if sg or tg or cross[i]:
                fl |= _FRHO
            if cross[i]:
                fl |= _FCROSS
        if taus or plays:
            fl |= _FFILT
            w[_HASF] = 1
        if fl & (_FUP | _FFILT):
            fl |= _FDT
        if nf or fl & _FRHO:
            fl |= _FGEN
        w[_FL] = fl
        # the lowpass time constants (ms, for start()), then (native) the arrays whose buffer
        # addresses are in _C*. Five instance attributes: comp, unit, _aux, _w, _wp (more, and
        # MicroPython's member table fills up, and every apply() lookup, a miss there, probes all of it)
        self._aux = [[t[0] * 1000.0 for t in taus]] + [None] * (_CBUF - _CRAW + 1)
        self._w = w
        self._wp = w
        if _kernel() is not None and _native is not False:
            from array import array

            self._w = array("i", w)
            # the kernel finds the words through their address (a small int on Cortex-M: cheaper
            # to convert than the array); the array stays referenced by _w
            self._wp = _kmod.address(self._w)  # pyright: ignore[reportOptionalMemberAccess]
            self._w[_SMALL] = 1 if type(self._wp) is int else 0
        else:
            _pure()
            if _kernel() is not None:
                # the class holds the native kernels: this model's own, bound to it
                self.apply = self._papply  # pyright: ignore[reportAttributeAccessIssue]
                self.apply_be16_n = self._papply_n  # pyright: ignore[reportAttributeAccessIssue]
        self.start(0)

    def clamped(self):
        """Values clamped so far: features at their bounds, raw codes and readings outside the
        proven ranges (never wrapped). A method, not a property: a property makes MicroPython
        check every attribute the class serves for accessors, apply() included."""
        return self._w[_CL]

    def _set_terms(self, m, nf, dti, step, fmax, terms, cross):
        ot = m.get("offset_terms") or [[], [], []]
        gt = m.get("gain_terms") or [[], [], []]
        cr = m.get("cross") or [[], [], []]
        raw_lsb = float(m.get("raw_lsb", 1.0))
        unit = self.unit
        for i in range(3):
            tot = 0.0
            for fi, cc in ot[i]:
                if not 0 <= int(fi) < nf:
                    raise ValueError("offset term of axis %d names feature %r of %d" % (i, fi, nf))
                tot += abs(float(cc) / raw_lsb) * unit[int(fi)] * fmax[int(fi)]
            if tot > (1 << 15):
                raise ValueError("axis %d: offset terms reach %r raw codes at the features' bounds; "
                                 "more than the raw range" % (i, tot))
            # and each coefficient alone within mul_shift's 2**28 (counts up to 2**15)
            tot = max(tot, max([abs(float(cc) / raw_lsb) * unit[int(fi)] for fi, cc in ot[i]] + [0.0]) * (1 << 15))
            fo = 0
            while fo < 24 and tot * (1 << (fo + 1)) <= (1 << 28):
                fo += 1
            if fo < 8:
                raise ValueError("axis %d: offset terms too large for 8 fraction bits" % i)
            t = terms[i]
            t[4] = fo
            for fi, cc in ot[i]:
                fi = int(fi)
                t[1 if step[fi] else 0].append((fi, _fix(float(cc) / raw_lsb * unit[fi], fo + 15)))
            tot = 0.0
            for fi, g in gt[i]:
                if not 0 <= int(fi) < nf:
                    raise ValueError("gain term of axis %d names feature %r of %d" % (i, fi, nf))
                fi = int(fi)
                tot += abs(float(g)) * unit[fi] * fmax[fi]
                t[3 if step[fi] else 2].append((fi, _fix(float(g) * unit[fi], _Q + 15)))
            if tot > _E_MAX:
                raise ValueError("axis %d: sensitivity terms reach %r at the features' bounds; at most "
                                 "%r are supported" % (i, tot, _E_MAX))
            dt_u = unit[dti] * fmax[dti] if dti >= 0 else 0.0
            for k, k0, k1 in cr[i]:
                k = int(k)
                if not 0 <= k < 3 or k == i:
                    raise ValueError("cross term of axis %d names axis %r" % (i, k))
                if float(k1) != 0 and dti < 0:
                    raise ValueError("cross term with a temperature part needs a dT feature")
                if abs(float(k0)) + abs(float(k1)) * dt_u > _E_MAX:
                    raise ValueError("axis %d: cross-axis term from axis %d above %r" % (i, k, _E_MAX))
                # one term per pair of axes: a later one replaces an earlier
                cross[i] = [r for r in cross[i] if r[0] != k]
                cross[i].append((k, _fix(float(k0), _Q), _fix(float(k1) * (unit[dti] if dti >= 0 else 0.0), _Q + 15)))

    def start(self, uptime_ms=0):
        """Power-on state: filters restart at the next reading, uptime counts from uptime_ms
        (saturating at 2**30 - 2**26 ms, 11.6 days, as it does while counting)."""
        up = int(uptime_ms)
        if up < 0:
            raise ValueError("start: uptime_ms must be >= 0, got %r" % (uptime_ms,))
        up = min(up, (1 << 30) - _DT_MAX - 1)
        w = self._w
        w[_FL] &= ~(_FSTART | _FTICK)
        w[_UPT] = up
        p = w[_PTAU]
        for i in range(w[_NTAU]):
            w[p + 3] = 0
            if w[p]:
                w[p + 2] = _fix(_exp(-float(up) / self._aux[0][i]), _Q)  # pyright: ignore[reportOptionalSubscript]
            p += _TREC

    def layout(self, stride=6, raw=0, acc=-1, temp=-1):
        """The burst apply_be16_n reads: one sample every ``stride`` bytes, its three raw codes as
        big-endian int16 words at byte ``raw``, the accelerometer's at ``acc`` and the temperature
        reading at ``temp`` (-1: from the call's arguments). An MPU-6xxx FIFO packet of accel,
        temperature and gyro: ``layout(14, raw=8, acc=0, temp=6)``."""
        need = 0
        for name, off in (("raw", raw), ("acc", acc), ("temp", temp)):
            if off != int(off) or off < (0 if name == "raw" else -1):
                raise ValueError("layout: %s offset %r must be an int >= %d" % (name, off, 0 if name == "raw" else -1))
            if off >= 0:
                need = max(need, off + (2 if name == "temp" else 6))
        if stride != int(stride) or not need <= stride < 32768:
            raise ValueError("layout: stride %r must cover the words (%d bytes) and be < 32768" % (stride, need))
        w = self._w
        w[_STR] = int(stride)
        w[_ROFF] = int(raw)
        w[_AOFF] = int(acc)
        w[_TOFF] = int(temp)
        w[_NEED] = need

    def _check_burst(self, buf, out, n, dt_ms):
        # apply_be16_n's arguments, by name (both kernels)
        w = self._w
        st = w[_STR]
        if not 0 <= n < 32768 or not 0 <= dt_ms <= _DT_MAX:
            raise ValueError("apply_be16_n: need 0 <= n < 32768 and 0 <= dt_ms <= %d, got n=%r dt_ms=%r"
                             % (_DT_MAX, n, dt_ms))
        if n and (n - 1) * st + w[_NEED] > len(buf):
            raise ValueError("apply_be16_n: %d samples at stride %d need %d bytes, buf has %d"
                             % (n, st, (n - 1) * st + w[_NEED], len(buf)))
        if 3 * n > len(out):
            raise ValueError("apply_be16_n: %d samples need %d outputs, out has %d" % (n, 3 * n, len(out)))

    def _bind(self, raw, out, acc, burst):
        # native: note the arrays' buffer addresses once they are checked 32-bit int arrays (and a
        # burst's lengths, so a later call checks them by comparing), or raise the clear error
        # of a wrong argument (the kernel reads and writes 32-bit words)
        k = _kernel()
        assert k is not None  # only the native kernel calls this
        w = self._w
        if burst:
            if not k.buffer(raw):
                raise ValueError("apply_be16_n: buf must be bytes, bytearray, memoryview or array, got %s"
                                 % type(raw).__name__)
            self._check_burst(raw, out, burst, 0)
            k.note(w, _CBUF, raw)
            w[_CBUFN] = len(raw)
            self._aux[1 + _CBUF - _CRAW] = raw
        for name, a, slot in (("out", out, _CBOUT if burst else _COUT), ("raw", raw, _CRAW),
                              ("acc", acc, _CBACC if burst else _CACC)):
            if name == "raw" and burst or name == "acc" and (not w[_FL] & _FACC or burst and w[_AOFF] >= 0):
                continue
            if not k.words(a, 3):
                raise ValueError("%s must be an array('i') of at least 3 ints (the native kernel reads "
                                 "and writes 32-bit words), got %s" % (name, type(a).__name__))
            k.note(w, slot, a)
            if slot == _CBOUT:
                w[_CBOUTN] = len(a)
            # the reference keeps the checked buffer alive, so no other object's takes its address
            self._aux[1 + slot - _CRAW] = a

    def _ticks(self):
        # dt_ms = -1: the ms since the previous such sample by the port's clock (0 at the first)
        w = self._w
        now = _ticks()
        dt = _ticks_diff(now, w[_LAST]) if w[_FL] & _FTICK else 0
        w[_LAST] = now
        w[_FL] |= _FTICK
        return dt


def _urec(c, i):
    # Compensator c's update() of axis i as integers (augment_native runs it): the constant-scale
    # form (degree fd >= 0, its coefficients and shift) or the scale and offset polynomials and
    # the division's exponents
    sp = c._sc[i]
    op = c._off[i]
    fd = c._fd[i]
    r = [fd, c._fs[i] if fd >= 0 else 0] + (c._fq[4 * i:4 * i + 4] if fd >= 0 else [0] * 4)
    a = list(sp._a) + [0] * (4 - len(sp._a))
    r += [sp._deg, sp._mid, sp._xl, sp._xs, sp._vs, sp._vm, sp._a0h, sp._a0l, a[1], a[2], a[3]]
    a = list(op._a) + [0] * (4 - len(op._a))
    r += [op._deg, op._mid, op._xl, op._xs, op._vs, op._vr, op._a0, a[1], a[2], a[3]]
    r += [c._wg[i], c._eo[i], c._eg[i]]
    return r


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
