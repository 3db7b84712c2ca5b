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

Beside the driver, below it: it stands on ``tempcomp.fixedpoint``, ``tempcomp.mpu6xxx_units``
and ``tempcomp.mpu6xxx_rt`` (the record ``compiled()`` writes). The driver hands the model what
it read from the part (ranges, offsets, temperature) and applies what the model computes
(``BiasModel.compensators``, ``BiasModel.registers``); the model never calls the driver back.
"""

from tempcomp.fixedpoint import (
    CLAMP,
    EXTRAPOLATE,
    Compensator,
    gcd,
    quadratic_through,
    ratio,
    to_float,
)
from tempcomp.mpu6xxx_units import (
    ACCEL_LSB_G,
    ACCEL_STEP,
    GYRO_LSB_DPS,
    GYRO_STEP,
    clamp_accel15,
    clamp_gyro,
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
    rs = [ratio(y) for y in ys]
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
        g = gcd(num, d)
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
            self.coeffs = [[to_float(c) for c in q] for q in self._q]
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

    def registers(self, t_raw):
        """targets(t_raw) as the offset registers can hold them: each clamped to its field (with
        a warning). What ``MPU6xxx.follow`` writes (hardware offset(T))."""
        g, a = self.targets(t_raw)
        return ([clamp_gyro(k, g[k]) for k in range(3)], [clamp_accel15(k, a[k] >> 1) * 2 for k in range(3)])

    def compensators(self, ranges, offsets):
        """The two fixed-point Compensators (accel, gyro) of ``MPU6xxx.read_compensated`` for the
        part's full-scale ``ranges`` (gyro dps, accel g) and the six offset registers it holds
        (gyro x y z, accel x y z): output offset(T) in mg and mdps with those registers held."""
        gdps, ag = ranges
        gfs = gdps // 250
        afs = ag // 2
        k_g = GYRO_STEP / gfs  # output LSB per gyro register LSB at this range
        k_a = ACCEL_STEP / afs  # output LSB per accel word LSB at this range
        offs_g = [self.offset_poly(k, offsets[k], k_g) for k in range(3)]
        offs_a = [self.offset_poly(3 + k, offsets[3 + k] & ~1, k_a) for k in range(3)]
        t_cal = self.t_cal
        cg = Compensator(offs_g, [[GYRO_LSB_DPS / gfs]] * 3, t_cal, out_scale=1000, t_ref=self.t_ref, policy=self.policy)
        ca = Compensator(offs_a, [[ACCEL_LSB_G / afs]] * 3, t_cal, out_scale=1000, t_ref=self.t_ref, policy=self.policy)
        return ca, cg

    def offset_poly(self, axis, base, k):
        """Output offset vs temperature when ``base`` is held: (base - value(t)) * k LSB.

        Coefficients of powers of t - t_ref for ``fixedpoint.Compensator``: exact (num, den)
        pairs of ints where the interpreter has long ints, floats otherwise."""
        q = self._q
        if q is None:
            c = [-v * k for v in self.coeffs[axis]]
            c[0] += base * k
            return c
        kn, kd = ratio(k)
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


def compiled(imu, model_ints):
    """Record ``mpu_tcc``: the per-sample integers that ``imu.compensate(BiasModel.from_ints(
    model_ints))`` computes for the present ranges and offsets, for a boot that should not load
    the set-up: ``imu.compensate(mpu_tcc, mpu_tc)`` (tempcomp.mpu6xxx_rt), bit-identical.

    model_ints is the ``mpu_tc`` record (``model.to_ints()``). The imu's own compensation, if
    any, is left as it was.
    """
    # the record's layout (set-up only)
    from tempcomp.mpu6xxx_rt import LENGTH, VERSION, model_hash

    ranges = imu.ranges()
    g, a = imu.offsets()
    cur = list(g) + list(a)
    out = [VERSION, model_hash(model_ints), ranges[0], ranges[1]] + cur
    for c in BiasModel.from_ints(model_ints).compensators(ranges, cur):
        e = c.export()
        if e is None:
            raise ValueError("compiled(): needs 3 int16 axes with constant scales")
        out += list(e[:8])
        for v in e[8:]:  # gh gl fd fs (3 each), fq (12)
            out += list(v)
    if len(out) != LENGTH:
        raise ValueError("compiled(): %d values, expected %d" % (len(out), LENGTH))
    return out
