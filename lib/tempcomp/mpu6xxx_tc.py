"""Temperature-dependent bias of an MPU-6xxx part over its own temperature sensor.

Capture ``bias_point()`` at rest at two or more temperatures; each gives the raw temperature
and the offset-register values that would zero the bias there. ``BiasModel`` fits, per
axis, a polynomial of those register values in the raw temperature (exact through 1..3
points, least-squares quadratic through more) and evaluates it with the fixed-point core.
The fit and the fixed-point set-up are exact rational arithmetic (long ints), so one
``to_ints()`` record gives the same integers on every interpreter, single-precision
firmware included; a build without long ints fits in floats.
Use it either way:

* hardware: ``imu.follow(model, step_c100=50)`` re-writes the offset registers whenever the
  temperature moved by 0.5 degC since the last write (no work per sample);
* software: ``imu.compensate(model)`` then ``imu.read_compensated(out)`` per sample
  (mg, mdps; zero allocation), keeping the held registers as they are.

Usage::

    from tempcomp.mpu6xxx_tc import BiasModel
    pts = [imu.bias_point()]          # cold
    pts.append(imu.bias_point())      # warm ... (one call per temperature)
    model = BiasModel(pts)
    store.save("mpu_tc", model.to_ints())
    model = BiasModel.from_ints(store.load("mpu_tc"))
"""

from tempcomp.fixedpoint import (
    CLAMP,
    EXTRAPOLATE,
    Compensator,
    _fl,
    _gcd,
    _ratio,
    quadratic_through,
)

_FRAC = 16  # to_ints keeps register values in 1/16 LSB


def _lsq_quadratic(ts, ys, t_ref):
    # least-squares c0 + c1 u + c2 u**2, u = (t - t_ref) / w, w keeps the normal matrix sane
    w = float(max(abs(t - t_ref) for t in ts)) or 1.0
    m = [[0.0] * 4 for _ in range(3)]
    for t, y in zip(ts, ys):
        u = (t - t_ref) / w
        p = (1.0, u, u * u)
        for i in range(3):
            for j in range(3):
                m[i][j] += p[i] * p[j]
            m[i][3] += p[i] * y
    for c in range(3):  # Gauss-Jordan with partial pivoting
        piv = max(range(c, 3), key=lambda r: abs(m[r][c]))
        m[c], m[piv] = m[piv], m[c]
        if m[c][c] == 0:
            raise ValueError("bias points do not determine a quadratic")
        for r in range(3):
            if r != c:
                f = m[r][c] / m[c][c]
                for j in range(c, 4):
                    m[r][j] -= f * m[c][j]
    return [m[0][3] / m[0][0], m[1][3] / m[1][1] / w, m[2][3] / m[2][2] / (w * w)]


def _det(a):
    if len(a) == 1:
        return a[0][0]
    if len(a) == 2:
        return a[0][0] * a[1][1] - a[0][1] * a[1][0]
    return (a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]))


def _exact_fit(ts, ys, t_ref):
    # _fit in exact rationals: the least-squares polynomial of degree min(n - 1, 2) (through the
    # points when n <= 3) by Cramer's rule on the integer normal equations in u = t - t_ref, each
    # y taken as the binary fraction it is. Returns (num, den) pairs, den > 0, of powers of u.
    # Long ints (u**4 * n alone passes 2**31): OverflowError on a build without them.
    rs = [_ratio(y) for y in ys]
    den = max(r for _, r in rs)  # powers of two (or 1): the largest is a common multiple
    yi = [v * (den // r) for v, r in rs]
    us = [t - t_ref for t in ts]
    m = min(len(us), 3)
    s = [sum(u**k for u in us) for k in range(2 * m - 1)]
    a = [[s[i + j] for j in range(m)] for i in range(m)]
    r = [sum(u**i * y for u, y in zip(us, yi)) for i in range(m)]
    det = _det(a)
    if det == 0:
        raise ValueError("bias points do not determine a quadratic")
    out = []
    for i in range(m):
        num = _det([row[:i] + [r[k]] + row[i + 1:] for k, row in enumerate(a)])
        d = det * den
        if d < 0:
            num, d = -num, -d
        g = _gcd(num, d)
        out.append((num // g, d // g))
    return out


def _fit(ts, ys, t_ref):
    n = len(ts)
    if n == 1:
        return [float(ys[0])]
    if n == 2:
        slope = (ys[1] - ys[0]) / float(ts[1] - ts[0])
        return [ys[0] + slope * (t_ref - ts[0]), slope]
    if n == 3:
        return list(quadratic_through((ts[0], ys[0]), (ts[1], ys[1]), (ts[2], ys[2]), t_ref))
    return _lsq_quadratic(ts, ys, t_ref)


def merge_points(points):
    """Average bias points that share a temperature reading: (points, readings merged).

    Two captures at the same raw temperature happen on a real board when a heater is slower
    than the session (or the board did not warm at all): they measure the same thing twice, so
    they are averaged into one point instead of making the fit fail."""
    groups = {}
    order = []
    for p in points:
        t = int(p[0])
        if t not in groups:
            groups[t] = []
            order.append(t)
        groups[t].append(p)
    out = []
    merged = []
    for t in order:
        g = groups[t]
        if len(g) == 1:
            out.append(g[0])
            continue
        merged.append(t)
        n = float(len(g))
        out.append((t, tuple(sum(p[1][k] for p in g) / n for k in range(3)),
                    tuple(sum(p[2][k] for p in g) / n for k in range(3))))
    return out, merged


class BiasModel:
    """Offset-register values vs raw temperature for the six axes (gyro x y z, accel x y z).

    points: (t_raw, (gx, gy, gz), (ax, ay, az)) tuples from ``MPU6xxx.bias_point()``, at
    distinct temperatures. Outside the measured span the values are held at its edges
    (``CLAMP``) or the polynomials continue over half the span again (``EXTRAPOLATE``).
    """

    def __init__(self, points, policy=CLAMP):
        if not points:
            raise ValueError("need at least one bias point")
        pts = sorted(points)  # by temperature reading first
        ts = [int(p[0]) for p in pts]
        for i in range(1, len(ts)):
            if ts[i] == ts[i - 1]:
                raise ValueError("two bias points at the same temperature reading %d: the temperature did "
                                 "not move between them; average them with merge_points() or capture "
                                 "the second after it has changed" % ts[i])
        for p in pts:
            if len(p[1]) != 3 or len(p[2]) != 3:
                raise ValueError("a bias point is (t_raw, (gx, gy, gz), (ax, ay, az)), got %r" % (p,))
            for v in tuple(p[1]) + tuple(p[2]):
                if not -1e9 < float(v) < 1e9:  # NaN fails this too
                    raise ValueError("a bias point's register values must be finite, |v| < 1e9, got %r" % (p,))
        if policy not in (CLAMP, EXTRAPOLATE):
            raise ValueError("policy must be CLAMP or EXTRAPOLATE")
        self.points = pts
        self.policy = policy
        self.t_ref = ts[len(ts) // 2]
        self.t_cal = (ts[0], ts[-1]) if len(ts) > 1 else (ts[0] - 1, ts[0] + 1)
        ys = [[float(p[1][k]) for p in pts] for k in range(3)] + [[float(p[2][k]) for p in pts] for k in range(3)]
        try:
            # exact: the fixed-point set-up then gives the same integers on every interpreter, single-
            # precision floats (Cortex-M3) or float64 (the host), from the same points (to_ints)
            self._q = [_exact_fit(ts, y, self.t_ref) for y in ys]
            self.coeffs = [[_fl(c) for c in q] for q in self._q]
        except OverflowError:  # a build without long ints: in floats
            self._q = None
            self.coeffs = [_fit(ts, y, self.t_ref) for y in ys]
        self._hw = None  # the 6-axis Compensator of targets(): built on first use (docs/ram.md)

    def _hw_comp(self):
        # apply(0, axis) of this compensator = round(value / scale): register LSB for the gyro,
        # 15-bit field units (2 word LSB) for the accel, whose bit 0 is not ours to set. Only
        # follow() (hardware offset(T)) needs it: a boot that compensates in software never
        # builds it.
        hw = self._hw
        if hw is None:
            hw = self._hw = Compensator(
                [self.offset_poly(k, 0, 1) for k in range(6)],
                [[1.0]] * 3 + [[2.0]] * 3,
                self.t_cal,
                out_scale=1.0,
                policy=self.policy,
                t_ref=self.t_ref,
            )
        return hw

    def value(self, axis, t_raw):
        """Float register value of ``axis`` (0..5) at t_raw, as fitted (reference, set-up use)."""
        lo, hi = self._hw_comp().t_in if self.policy == EXTRAPOLATE else self.t_cal
        t = min(max(t_raw, lo), hi)
        u = float(t - self.t_ref)
        v = 0.0
        for c in reversed(self.coeffs[axis]):
            v = v * u + c
        return v

    def targets(self, t_raw):
        """((gx, gy, gz), (ax, ay, az)) register values for temperature reading t_raw."""
        hw = self._hw_comp()
        hw.update(t_raw)
        g = (hw.apply(0, 0), hw.apply(0, 1), hw.apply(0, 2))
        a = (hw.apply(0, 3) * 2, hw.apply(0, 4) * 2, hw.apply(0, 5) * 2)
        return (g, a)

    def offset_poly(self, axis, base, k):
        """Output offset vs temperature when ``base`` is held: (base - value(t)) * k LSB.

        Coefficients of powers of t - t_ref for ``fixedpoint.Compensator``: exact (num, den)
        pairs of ints where the interpreter has long ints, floats otherwise."""
        q = self._q
        if q is None:
            c = [-v * k for v in self.coeffs[axis]]
            c[0] += base * k
            return c
        kn, kd = _ratio(k)
        q = q[axis]
        c = [(-v * kn, d * kd) for v, d in q]
        c[0] = ((base * q[0][1] - q[0][0]) * kn, q[0][1] * kd)
        return c

    def to_ints(self):
        """Flat ints for a coefficient store: [n, t, 6 values * 16] per point."""
        out = [len(self.points)]
        for t, g, a in self.points:
            out.append(int(t))
            for v in tuple(g) + tuple(a):
                out.append(int(round(v * _FRAC)))
        return out

    @classmethod
    def from_ints(cls, ints, policy=CLAMP):
        """Rebuild a model saved with to_ints()."""
        if not ints or len(ints) != 1 + 7 * ints[0]:
            raise ValueError("not a BiasModel record: %r" % (ints,))
        pts = []
        for i in range(ints[0]):
            r = ints[1 + 7 * i : 8 + 7 * i]
            pts.append((r[0], tuple(v / _FRAC for v in r[1:4]), tuple(v / _FRAC for v in r[4:7])))
        return cls(pts, policy)


def follow(imu, model, step_c100=50):
    # MPU6xxx.follow(): here, beside the model it needs, so a boot that never follows the
    # temperature in hardware does not load it (docs/ram.md)
    from tempcomp.mpu6xxx import MPUError, _clamp_accel15, _clamp_gyro
    from tempcomp.mpu6xxx_parts import TEMP_SENS

    if imu._dev.read_u8(0x6B) & 0x40:  # PWR_MGMT_1.SLEEP (RM-MPU-6000A 4.28)
        raise MPUError("the part is asleep (PWR_MGMT_1.SLEEP): its temperature is stale")
    t = imu.temp_raw()
    step = step_c100 * imu._row[TEMP_SENS] // 10000
    last = imu._follow_t
    if last is not None and abs(t - last) < step:
        return False
    g, a = model.targets(t)
    imu.apply(
        [_clamp_gyro(k, g[k]) for k in range(3)],
        [_clamp_accel15(k, a[k] >> 1) * 2 for k in range(3)],
    )
    imu._follow_t = t
    return True


def compensate(imu, model, check=None):  # check: used by the compiled form only
    # MPU6xxx.compensate(model) for a BiasModel: the fixed-point set-up, here beside the model,
    # so a boot that resumes the compiled state (tempcomp.mpu6xxx_rt) never loads it
    imu._comp_set(*_compensators(imu, model))


def _compensators(imu, model):
    gdps, ag = imu.ranges()
    cur = imu._read_offsets()
    gfs = gdps // 250
    afs = ag // 2
    k_g = 4 / gfs  # output LSB per gyro register LSB (one +-1000 dps LSB = 4 LSB at +-250 dps)
    k_a = 8 / afs  # output LSB per accel word LSB (2048 LSB/g words, 16384 LSB/g at +-2 g)
    offs_g = [model.offset_poly(k, cur[k], k_g) for k in range(3)]
    offs_a = [model.offset_poly(3 + k, cur[3 + k] & ~1, k_a) for k in range(3)]
    t_cal = model.t_cal
    cg = Compensator(offs_g, [[131 / gfs]] * 3, t_cal, out_scale=1000, t_ref=model.t_ref, policy=model.policy)
    ca = Compensator(offs_a, [[16384 / afs]] * 3, t_cal, out_scale=1000, t_ref=model.t_ref, policy=model.policy)
    return ca, cg


def compiled(imu, model_ints):
    """Record ``mpu_tcc``: the per-sample integers that ``imu.compensate(BiasModel.from_ints(
    model_ints))`` computes for the present ranges and offsets, for a boot that should not load
    the set-up: ``imu.compensate(mpu_tcc, mpu_tc)`` (tempcomp.mpu6xxx_rt), bit-identical.

    model_ints is the ``mpu_tc`` record (``model.to_ints()``). The imu's own compensation, if
    any, is left as it was.
    """
    from tempcomp.mpu6xxx_rt import LENGTH, VERSION, model_hash

    gdps, ag = imu.ranges()
    cur = imu._read_offsets()
    out = [VERSION, model_hash(model_ints), gdps, ag] + list(cur)
    for c in _compensators(imu, BiasModel.from_ints(model_ints)):
        if c._p3 is None or min(c._fd) < 0:
            raise ValueError("compiled(): needs 3 int16 axes with constant scales")
        out += [c._t_lo, c._t_hi, c._fxm, c._fxl, c._fxs, c._half, c._k, c._s]
        out += list(c._gh) + list(c._gl) + list(c._fd) + list(c._fs) + list(c._fq)
    if len(out) != LENGTH:
        raise ValueError("compiled(): %d values, expected %d" % (len(out), LENGTH))
    return out
