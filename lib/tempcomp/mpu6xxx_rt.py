"""An MPU's software offset(T) at boot, from the integers set-up computed at calibration.

``imu.compensate(model)`` turns a ``BiasModel`` into two fixed-point Compensators: exact fits,
basis shifts and bound proofs in ``tempcomp.fixedpoint`` (about 25 KB of heap from ``.mpy``).
All they leave for the per-sample path is a few dozen integers; ``tempcomp.mpu6xxx_tc.compiled``
exports those once the model is in use, the session saves them as record ``mpu_tcc`` next to
``mpu_tc``, and a boot rebuilds only this per-sample state (docs/ram.md)::

    imu.restore(st)                                         # the offsets it was built for
    imu.compensate(st.load("mpu_tcc"), st.load("mpu_tc"))   # no fixed-point set-up at boot
    imu.read_compensated(out)

The arithmetic of ``_State.update`` is ``fixedpoint.Compensator._update_fast`` for three axes
with constant scales (every MPU range), with its bounds; results are bit-identical
(host_tests/sensors/test_mpu6xxx_rt.py compares them over the whole temperature range).

Beside the driver, below it: it imports nothing. The driver hands ``resume`` the record and what
it read from the part (ranges, offsets) and installs the two states it returns.
"""

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


VERSION = const(1)
_LIMB = const(14)
_LIMB_MASK = const(0x3FFF)
_HEAD = const(10)  # version, model_hash, gyro dps, accel g, the six offset words it was built for
_PER = const(32)  # per Compensator: t_lo t_hi fxm fxl fxs half k s, gh*3 gl*3 fd*3 fs*3 fq*12
LENGTH = const(74)  # _HEAD + 2 * _PER
_FXM = const(2)
_FXL = const(3)
_FXS = const(4)
_HALF = const(5)
_K = const(6)
_S = const(7)
_GH = const(8)
_GL = const(11)
_FD = const(14)
_FS = const(17)
_FQ = const(20)


def model_hash(ints):
    """24-bit hash of a BiasModel.to_ints() record: the compiled state names the model it came
    from, so a stale ``mpu_tcc`` (a save cut short between the two records) is refused."""
    h = len(ints)
    for v in ints:
        h = (h * 31 + (v & 0xFFFFFF)) & 0xFFFFFF  # < 2**29: small ints on 32-bit ports
    return h


class _State:
    # what read_compensated() uses of a fixedpoint.Compensator (update, burst3, clamped), reading
    # its numbers from the record itself (v: the loaded array, i: this Compensator's block)
    def __init__(self, v, i):
        self._v = v
        self._i = i
        p = self.burst3 = [0] * 11
        for k in range(3):
            p[3 * k] = v[i + _GH + k]
            p[3 * k + 1] = v[i + _GL + k]
        p[9] = v[i + _K]
        p[10] = v[i + _S]
        self.clamped = 0
        self._t = None
        self.update(v[i])

    def update(self, t):
        # Compensator._update_fast: the offset terms by Horner, mul_shift inline; zero allocation
        v = self._v
        i = self._i
        if t < v[i]:
            t = v[i]
            self.clamped += 1
        elif t > v[i + 1]:
            t = v[i + 1]
            self.clamped += 1
        if t == self._t:
            return
        self._t = t
        x = (t - v[i + _FXM]) << v[i + _FXL]
        hs = v[i + _FXS]
        p = self.burst3
        k = 0
        while k < 3:
            j = i + _FQ + 4 * k
            f = v[i + _FD + k]
            b = v[j]
            if f:
                acc = v[j + f]
                while True:
                    # |acc| <= 2**29, |acc * x| >> h <= 2**(28 + 2/3) (fixedpoint: Poly): < 2**30
                    acc = ((acc >> _LIMB) * x + (((acc & _LIMB_MASK) * x) >> _LIMB)) >> hs
                    f -= 1
                    if not f:
                        break
                    acc += v[j + f]
                sh = v[i + _FS + k]
                b += (acc >> sh) if sh >= 0 else (acc << -sh)
            p[3 * k + 2] = b - v[i + _HALF]
            k += 1


def resume(v, model, ranges, offsets):
    """The two per-sample states (accel, gyro) of ``MPU6xxx.compensate(mpu_tcc, mpu_tc)``: record
    ``v`` checked, and that it was built from ``model`` (the mpu_tc record, or None: not
    checked) for the part's full-scale ``ranges`` (gyro dps, accel g) and the six offset
    registers it holds. ValueError (one line) when it does not fit; nothing is kept then."""
    ok = len(v) == LENGTH and v[0] == VERSION
    i = _HEAD
    while ok and i < LENGTH:
        # the bounds update() relies on (fixedpoint's module notes)
        s = v[i + _S]
        ok = (0 <= v[i + _FXL] <= _LIMB and 0 <= v[i + _FXS] <= _LIMB and 1 <= v[i + _K] <= 15 and 5 <= s <= 24
              and v[i] <= v[i + 1] and v[i + _HALF] == 1 << (s - 1))
        for j in range(3):
            ok = ok and 0 <= v[i + _FD + j] <= 3
        for j in range(12):  # Horner's coefficients <= 2**29 (fixedpoint: Poly)
            ok = ok and -(1 << 29) <= v[i + _FQ + j] <= 1 << 29
        i += _PER
    if not ok:
        from tempcomp.mpu6xxx_faults import tcc_malformed

        raise tcc_malformed()
    if model is not None and model_hash(model) != v[1]:
        from tempcomp.mpu6xxx_faults import tcc_other_model

        raise tcc_other_model()
    if ranges[0] != v[2] or ranges[1] != v[3]:
        from tempcomp.mpu6xxx_faults import tcc_other_ranges

        raise tcc_other_ranges(v[2:4], ranges)
    for k in range(6):
        m = -1 if k < 3 else -2  # accel bit 0 is the part's, not ours
        if offsets[k] & m != v[4 + k] & m:
            from tempcomp.mpu6xxx_faults import tcc_other_offsets

            raise tcc_other_offsets()
    return _State(v, _HEAD), _State(v, _HEAD + _PER)
