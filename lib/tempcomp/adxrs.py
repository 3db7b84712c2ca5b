"""Analog gyro with an on-chip temperature output (ADXRS6xx style), ADI three-point calibration.

The rate output and the temperature output VT are read through the board's ADC
(MicroPython ``machine.ADC.read_u16()``, CircuitPython ``analogio.AnalogIn.value``: both
0..65535 over 0..vref). Calibration (ADI AN-1049):

* single point: null V0 measured at rest, scale factor S = (V_rot - V0) / rate;
* three points: (VT, V0, S) at three temperatures; V0 and S are each the quadratic in VT
  through the three points.

The compensated rate is the note's four steps: null at the present VT, corrected voltage
V - V0(VT), scale S(VT), rate = (V - V0(VT)) / S(VT); done in integers on the ADC codes by
``tempcomp.fixedpoint`` (zero allocation per sample).

Usage (board module from ``boards/``, a divider if the 5 V gyro is read by a 3.3 V ADC)::

    import tempcomp_board as board
    from tempcomp.adxrs import AnalogGyro, point
    g = AnalogGyro(board.adc("rate"), board.adc("temp"), board.ADC_VREF_MV)
    vt, v0 = g.measure(512)                 # at rest: mV
    vt, v1 = g.measure(512)                 # on a rate table at +300 dps
    g.set_single(v0, (v1 - v0) / 300)       # or set_three_point(p_cold, p_room, p_hot)
    mdps = g.rate()                         # milli-degrees per second (out_per_dps=1000)

Coefficient record (``tempcomp.record`` kind KIND_ADXRS), values in order:
``vt_ref_mv, vt_lo_mv, vt_hi_mv, v0_c0, v0_c1, v0_c2, s_c0, s_c1, s_c2`` with
V0(VT) = sum v0_ck (VT - vt_ref)^k in mV and S(VT) = sum s_ck (VT - vt_ref)^k in mV per dps;
vt_lo == vt_hi marks a single-point calibration.
"""

from tempcomp import record
from tempcomp.fixedpoint import CLAMP, Compensator, poly_value, quadratic_through, shift_basis

_FULL = 65535  # read_u16 / AnalogIn.value full scale


def _u16(adc):
    return adc.read_u16()


def _value(adc):
    return adc.value


def point(vt_mv, v_rest_mv, v_rot_mv, rate_dps):
    """One calibration point (VT mV, V0 mV, S mV per dps) from a rest and a known-rate reading."""
    if not rate_dps:
        raise ValueError("the known rate must be non-zero (dps)")
    return (float(vt_mv), float(v_rest_mv), (float(v_rot_mv) - v_rest_mv) / rate_dps)


class AnalogGyro:
    """Rate from an analog gyro's rate and temperature voltages (ADC channels).

    vref_mv: the ADC full-scale voltage (board module's ADC_VREF_MV); divider: sensor volts per
    ADC-pin volt (1.0 if wired directly); out_per_dps: output units per degree per second.
    temp_every: read VT every n-th sample; t_smooth: VT low-pass, 2**-t_smooth per sample.
    """

    def __init__(self, rate_adc, temp_adc=None, vref_mv=3300, divider=1.0, out_per_dps=1000,
                 policy=CLAMP, temp_every=1, t_smooth=0):
        if not vref_mv > 0 or not divider > 0:
            raise ValueError("vref_mv and divider must be positive")
        if temp_every < 1 or not 0 <= t_smooth <= 14:
            raise ValueError("temp_every must be >= 1 and t_smooth 0..14")
        self._r = rate_adc
        self._t = temp_adc
        self._read = _u16 if hasattr(rate_adc, "read_u16") else _value
        self.mv_per_code = float(vref_mv) * divider / _FULL
        self.out_per_dps = out_per_dps
        self.policy = policy
        self._every = temp_every
        self._n = 0
        self._k = t_smooth
        self._tf = -1  # filtered VT code << t_smooth (<= 65535 * 2**14 < 2**30); -1: not yet
        self._sign = 1
        self._three = False
        self.comp = None
        self.coeffs = None

    # -- set-up ---------------------------------------------------------------------------
    def read_codes(self):
        """(VT code, rate code) of one sample (set-up; VT -1 without a temperature channel)."""
        t = self._read(self._t) if self._t is not None else -1
        return t, self._read(self._r)

    def measure(self, n=256):
        """Average of n samples as (VT mV, rate-output mV), sensor side (set-up)."""
        if n < 1:
            raise ValueError("n must be >= 1")
        st = 0
        sr = 0
        for _ in range(n):
            t, r = self.read_codes()
            st += t
            sr += r
        q = self.mv_per_code
        return st * q / n, sr * q / n

    def set_single(self, v0_mv, s_mv_per_dps):
        """Single-point calibration: null (mV) and scale factor (mV per dps), no VT."""
        self._set(0.0, (0.0, 0.0), [float(v0_mv)], [float(s_mv_per_dps)])

    def set_three_point(self, p0, p1, p2):
        """Three (VT mV, V0 mV, S mV per dps) points; V0 and S quadratic in VT through them."""
        pts = sorted((p0, p1, p2))
        ref = pts[1][0]
        v0 = quadratic_through((pts[0][0], pts[0][1]), (pts[1][0], pts[1][1]), (pts[2][0], pts[2][1]), ref)
        s = quadratic_through((pts[0][0], pts[0][2]), (pts[1][0], pts[1][2]), (pts[2][0], pts[2][2]), ref)
        self._set(ref, (pts[0][0], pts[2][0]), list(v0), list(s))

    def set_quadratics(self, vt_ref_mv, v0, s, vt_span_mv):
        """V0/S coefficients (powers of VT - vt_ref, mV and mV per dps) over vt_span_mv."""
        self._set(float(vt_ref_mv), (float(vt_span_mv[0]), float(vt_span_mv[1])),
                  [float(c) for c in v0], [float(c) for c in s])

    def _set(self, ref, span, v0, s):
        q = self.mv_per_code
        single = span[0] == span[1]
        if not single and self._t is None:
            raise ValueError("a temperature calibration needs the VT channel (temp_adc)")
        # mV polynomials in VT -> code polynomials in the VT code: VT = q * code, value / q
        off = [v0[k] * _pow(q, k) / q for k in range(len(v0))]
        sc = [s[k] * _pow(q, k) / q for k in range(len(s))]
        if single:
            t_cal = (0, _FULL)
            vals = [sc[0]]
        else:
            lo = int(span[0] / q)
            hi = int(span[1] / q) + 1
            t_cal = (max(lo, 0), min(hi, _FULL))
            vals = [poly_value(sc, c - ref / q) for c in (t_cal[0], t_cal[1], (t_cal[0] + t_cal[1]) // 2)]
        sign = 1
        raw_range = (0, _FULL)
        if max(vals) < 0:
            # a negative scale factor (mounting sign): compensate -code against -V0 and |S|
            sign = -1
            off = [-c for c in off]
            sc = [-c for c in sc]
            raw_range = (-_FULL, 0)
        # about the nearest integer code: the core takes an integer t_ref
        t_ref = int(round(ref / q))
        off = shift_basis(off, ref / q, t_ref)
        sc = shift_basis(sc, ref / q, t_ref)
        comp = Compensator([off], [sc], t_cal, out_scale=self.out_per_dps, raw_range=raw_range,
                           policy=self.policy, t_ref=t_ref)
        self.comp = comp
        self._sign = sign
        self._three = not single
        self._tf = -1
        self._n = 0
        self.coeffs = (ref, span, v0, s)

    def to_record(self):
        """The coefficient record (list of ints) for tempcomp.store."""
        if self.coeffs is None:
            raise ValueError("not calibrated")
        ref, span, v0, s = self.coeffs
        v0 = (list(v0) + [0.0, 0.0, 0.0])[:3]
        s = (list(s) + [0.0, 0.0, 0.0])[:3]
        return record.pack(record.KIND_ADXRS, [ref, span[0], span[1]] + v0 + s)

    def load_record(self, ints):
        """Calibrate from a KIND_ADXRS record (set-up)."""
        v = record.unpack(ints, record.KIND_ADXRS, 9)
        self.set_quadratics(v[0], v[3:6], v[6:9], (v[1], v[2]))

    # -- per sample -------------------------------------------------------------------------
    def rate(self):
        """Compensated rate in output units (int); zero allocation."""
        c = self.comp
        if c is None:
            raise ValueError("gyro not calibrated: call set_single/set_three_point first")
        if self._three:
            n = self._n - 1
            if n <= 0:
                n = self._every
                t = self._read(self._t)
                k = self._k
                if k:
                    tf = self._tf
                    if tf < 0:
                        tf = t << k
                    else:
                        tf += t - (tf >> k)
                    self._tf = tf
                    t = tf >> k
                c.update(t)
            self._n = n
        return c.apply(self._sign * self._read(self._r))

    def rate_from(self, t_code, r_code):
        """Compensated rate for given VT and rate ADC codes (output units); zero allocation."""
        c = self.comp
        if c is None:
            raise ValueError("gyro not calibrated: call set_single/set_three_point first")
        c.update(t_code)
        return c.apply(self._sign * r_code)


def _pow(x, k):
    v = 1.0
    for _ in range(k):
        v *= x
    return v

