"""Simulated analog gyro with an on-chip temperature output (ADXRS6xx style) behind ADC stand-ins.

MicroPython-compatible (runs in the VM and on the virtual board). The sensor's outputs, in
sensor-side millivolts, follow the model the ADI three-point calibration assumes:

* VT = vt25_mv + vt_per_c * (T - 25)                     (ADXRS620: 2.5 V at 25 degC, 9 mV/K)
* V0(VT) = sum null_mv[k] * (VT - vt25_mv)**k             (null drifts as a quadratic in VT)
* S(VT)  = sum scale_mv[k] * (VT - vt25_mv)**k            (mV per dps, quadratic in VT)
* Vrate  = V0(VT) + S(VT) * rate_dps + noise

The ADC channels divide by ``divider`` (sensor volts per pin volt), quantise to ``bits``
(12-bit parts return the code with its top bits replicated, as RP2040's read_u16 does) and
clip to 0..vref. Usage::

    from tools.sim.analog_gyro_sim import AnalogGyroSim
    sim = AnalogGyroSim(vref_mv=3300, divider=2.0)
    sim.temp_c = 85.0
    sim.rate_dps = 120.0
    code = sim.rate.read_u16()       # or sim.rate.value (CircuitPython AnalogIn)
"""

try:
    from array import array
except ImportError:  # pragma: no cover
    array = None


class _Rand:
    # xorshift32; gauss() is Irwin-Hall (sum of 12 uniforms - 6): unit variance, deterministic
    # on CPython and MicroPython alike
    def __init__(self, seed):
        self.s = (seed * 2654435761 + 1) & 0xFFFFFFFF or 1

    def u(self):
        s = self.s
        s ^= (s << 13) & 0xFFFFFFFF
        s ^= s >> 17
        s ^= (s << 5) & 0xFFFFFFFF
        self.s = s
        return s / 4294967296.0

    def gauss(self):
        t = 0.0
        for _ in range(12):
            t += self.u()
        return t - 6.0


class _Channel:
    def __init__(self, sim, which):
        self._sim = sim
        self._which = which

    def read_u16(self):
        return self._sim.code(self._which)

    @property
    def value(self):
        return self._sim.code(self._which)


class AnalogGyroSim:
    """A gyro's rate and VT outputs as two ADC channels: ``.rate`` and ``.temp``."""

    def __init__(self, vref_mv=3300.0, divider=2.0, vt25_mv=2500.0, vt_per_c=9.0,
                 null_mv=(2500.0, 0.08, 2.0e-4), scale_mv=(6.0, -4.0e-4, 1.5e-6),
                 noise_mv=0.0, t_noise_mv=0.0, bits=16, seed=1):
        self.vref_mv = float(vref_mv)
        self.divider = float(divider)
        self.vt25_mv = float(vt25_mv)
        self.vt_per_c = float(vt_per_c)
        self.null_mv = tuple(float(c) for c in null_mv)
        self.scale_mv = tuple(float(c) for c in scale_mv)
        self.noise_mv = float(noise_mv)
        self.t_noise_mv = float(t_noise_mv)
        self.bits = bits
        self.temp_c = 25.0
        self.rate_dps = 0.0
        self._rand = _Rand(seed)
        self.rate = _Channel(self, 0)
        self.temp = _Channel(self, 1)

    @staticmethod
    def _poly(c, u):
        v = 0.0
        i = len(c) - 1
        while i >= 0:
            v = v * u + c[i]
            i -= 1
        return v

    def vt_mv(self):
        """True temperature output (mV) at temp_c."""
        return self.vt25_mv + self.vt_per_c * (self.temp_c - 25.0)

    def null_at(self, vt_mv):
        """True null V0 (mV) at temperature output vt_mv."""
        return self._poly(self.null_mv, vt_mv - self.vt25_mv)

    def scale_at(self, vt_mv):
        """True scale factor S (mV per dps) at temperature output vt_mv."""
        return self._poly(self.scale_mv, vt_mv - self.vt25_mv)

    def rate_mv(self):
        """Noise-free rate output (mV) at temp_c and rate_dps."""
        vt = self.vt_mv()
        return self.null_at(vt) + self.scale_at(vt) * self.rate_dps

    def to_code(self, mv):
        """ADC read_u16 code for a sensor-side voltage (mV)."""
        full = (1 << self.bits) - 1
        c = int(mv / self.divider / self.vref_mv * full + 0.5)
        if c < 0:
            c = 0
        elif c > full:
            c = full
        b = self.bits
        if b < 16:
            # widen like read_u16 on 12-bit ports: replicate the top bits into the low ones
            c = (c << (16 - b)) | (c >> (2 * b - 16))
        return c

    def code(self, which):
        if which == 0:
            mv = self.rate_mv()
            if self.noise_mv:
                mv += self.noise_mv * self._rand.gauss()
        else:
            mv = self.vt_mv()
            if self.t_noise_mv:
                mv += self.t_noise_mv * self._rand.gauss()
        return self.to_code(mv)


class ReplayADC:
    """ADC stand-in returning pre-recorded codes in a loop, without allocating (VM probes)."""

    def __init__(self, codes):
        self._buf = array("H", codes)
        self._i = 0
        self._n = len(self._buf)

    def read_u16(self):
        i = self._i
        v = self._buf[i]
        i += 1
        if i >= self._n:
            i = 0
        self._i = i
        return v

    @property
    def value(self):
        return self.read_u16()
