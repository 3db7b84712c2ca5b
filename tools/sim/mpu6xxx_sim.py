"""Register-file model of the InvenSense MPU-6050 and MPU-6500 families (I2C side).

Written from the register maps (RM-MPU-6000A, RM-MPU-9250) and ../shared/reference/
sensor-facts.md, independently of tempcomp.mpu6xxx, so tests compare the driver against the
documented behaviour rather than against itself. Runs on CPython and in the MicroPython VM.

What is modelled:

* WHO_AM_I, power management (sleep, device reset), SMPLRT_DIV/CONFIG/GYRO_CONFIG/
  ACCEL_CONFIG(2) with full-scale selection, the sample clock (8 kHz with DLPF_CFG 0/7,
  1 kHz otherwise, divided by 1 + SMPLRT_DIV), data registers 0x3B..0x48, INT_STATUS overflow.
* The FIFO: FIFO_EN selects what is written per sample in register order (accel, temp,
  gyro x/y/z); USER_CTRL FIFO_EN/FIFO_RST; FIFO_COUNT_H/L; FIFO_R_W pops bytes (no
  auto-increment); its size per part; overflow drops the oldest bytes (MPU-6050 family, or
  CONFIG.FIFO_MODE = 0 on the MPU-6500 family) or the new sample (FIFO_MODE = 1). On the
  ICM-20602 FIFO_EN bit 4 enables all gyro axes and the temperature is always included.
* Samples from a true rate (dps) and acceleration (g), the temperature (deg C), a bias that
  may depend on temperature, seeded Gaussian noise, output rounding and int16 saturation.
  Optionally (``set_cross``) an accelerometer cross-axis matrix that drifts linearly with
  temperature, held within the datasheets' +-2 % cross-axis sensitivity.
* Offset registers: gyro 0x13..0x18, signed, one register LSB moves the output by
  4 / 2**FS_SEL output LSB, 0 at power-on. Accel words (0x06.. stride 2 on the MPU-6050
  family, 0x77.. stride 3 on the MPU-6500 family): bits 15..1 an offset in 2048 LSB/g units
  of the whole word, bit 0 reserved (stored, no effect), factory trim at power-on.
* Time advances with bus traffic: every transaction costs its bytes at ``bus_hz``
  (9 clocks a byte), so polling the FIFO sees it fill at the configured rate.
* Motion: ``set_motion`` (a rate and an acceleration held as given), ``turn`` (a steady rotation
  that also turns gravity in the part's frame, as a real turn does), ``schedule`` (a change
  later in simulated time).
* Default biases are drawn within the part's datasheet zero-rate tolerance (+-20 deg/s on the
  MPU-6050 family, +-5 deg/s on the MPU-6500 family: PS-MPU-6000A-00 6.1, PS-MPU-9250A-01 3.1).
* Faults: NACKs come from SimI2C.fail_at, corrupted reads from SimI2C.garble_at; ``stuck`` is a set of registers that ignore writes
  (a read-back mismatch); ``glitch_trim(axis)`` changes an accel trim register at runtime as
  the ICM-20602 is known to do.

Usage::

    from tools.sim.buses import SimI2C
    from tools.sim.mpu6xxx_sim import MPU6xxxSim
    sim = MPU6xxxSim("MPU-6500", seed=3)
    sim.place("-y")                 # the y axis points down
    bus = SimI2C({0x68: sim})       # a machine.I2C stand-in
"""

import math
import sys
from array import array

# part: (family, WHO_AM_I, accel offset base, stride, FIFO bytes, (LSB/degC, degC at 0),
#        PWR_MGMT_1 reset value, temperature always in FIFO)
PARTS = {
    "MPU-6050": (6050, 0x68, 0x06, 2, 1024, (340.0, 36.53), 0x40, False),
    "MPU-9150": (6050, 0x68, 0x06, 2, 1024, (340.0, 36.53), 0x40, False),
    "MPU-6500": (6500, 0x70, 0x77, 3, 512, (333.87, 21.0), 0x01, False),
    "MPU-9250": (6500, 0x71, 0x77, 3, 512, (333.87, 21.0), 0x01, False),
    "MPU-9255": (6500, 0x73, 0x77, 3, 512, (333.87, 21.0), 0x01, False),
    "ICM-20602": (6500, 0x12, 0x77, 3, 1008, (326.8, 25.0), 0x41, True),
}

FACES = {
    "+x": (1.0, 0.0, 0.0),
    "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "+z": (0.0, 0.0, 1.0),
    "-z": (0.0, 0.0, -1.0),
}

SMPLRT_DIV = 0x19
CONFIG = 0x1A
GYRO_CONFIG = 0x1B
ACCEL_CONFIG = 0x1C
ACCEL_CONFIG2 = 0x1D
FIFO_EN = 0x23
INT_ENABLE = 0x38
INT_STATUS = 0x3A
DATA = 0x3B  # ACCEL_XOUT_H .. GYRO_ZOUT_L = 0x48
USER_CTRL = 0x6A
PWR_MGMT_1 = 0x6B
PWR_MGMT_2 = 0x6C
FIFO_COUNTH = 0x72
FIFO_COUNTL = 0x73
FIFO_R_W = 0x74
WHO_AM_I = 0x75
GYRO_OFFS = 0x13

_NOISE_N = 4096
_READ_ONLY = (WHO_AM_I, INT_STATUS, FIFO_COUNTH, FIFO_COUNTL)


def _s16(hi, lo):
    v = hi << 8 | lo
    return v - 0x10000 if v & 0x8000 else v


def _sat(x):
    v = int(math.floor(x + 0.5))
    if v > 32767:
        return 32767
    if v < -32768:
        return -32768
    return v


class _Rng:
    # 31-bit LCG: identical sequences on CPython and MicroPython for the same seed
    def __init__(self, seed):
        self.x = (seed * 2654435761 + 1) & 0x7FFFFFFF

    def next(self):
        self.x = (self.x * 1103515245 + 12345) & 0x7FFFFFFF
        return self.x

    def uniform(self, lo, hi):
        return lo + (hi - lo) * ((self.next() >> 7) / 16777216.0)


_TABLES = {}
_CPYTHON = sys.implementation.name == "cpython"


def _normal_table(seed):
    # a fixed table of standard normal deviates (Box-Muller), indexed per sample by the LCG;
    # cached per seed so building many simulated parts stays cheap
    tab = _TABLES.get(seed)
    if tab is None:
        rng = _Rng(seed + 7919)
        if _CPYTHON:
            tab = [0.0] * _NOISE_N
        elif _TABLES:
            # MicroPython: one table, refilled in place (a microcontroller's heap holds one)
            tab = _TABLES.popitem()[1]
        else:
            # an array of the port's own float width holds the same values as a list there, in a
            # quarter of the heap (4096 boxed floats alone would not fit a 140 KB heap)
            single = 1.0 + 1e-9 == 1.0
            tab = array("f" if single else "d", bytearray((4 if single else 8) * _NOISE_N))
        i = 0
        while i < _NOISE_N:
            u1 = (rng.next() + 1) / 2147483649.0
            u2 = rng.next() / 2147483648.0
            r = math.sqrt(-2.0 * math.log(u1))
            tab[i] = r * math.cos(2.0 * math.pi * u2)
            tab[i + 1] = r * math.sin(2.0 * math.pi * u2)
            i += 2
        # 4096 deviates have a sample mean of about 1/64 sigma: a part would keep that as a fixed
        # offset no average removes (3000 samples: 0.86 sigma of their mean). Centred and scaled,
        # the table's mean is 0 and its deviation 1, so mean_output() is the sample's expectation.
        m = 0.0
        for v in tab:
            m += v
        m /= _NOISE_N
        q = 0.0
        for v in tab:
            q += (v - m) * (v - m)
        k = 1.0 / math.sqrt(q / _NOISE_N)
        i = 0
        while i < _NOISE_N:
            tab[i] = (tab[i] - m) * k
            i += 1
        _TABLES[seed] = tab
    return tab


class MPU6xxxSim:
    """One simulated part; attach to a SimI2C at its address (0x68 or 0x69)."""

    def __init__(
        self,
        part="MPU-6500",
        seed=1,
        who_am_i=None,
        gyro_bias_dps=None,
        accel_bias_g=None,
        gyro_noise_dps=None,
        accel_noise_g=None,
        factory_trim=None,
        temp_c=25.0,
        bus_hz=400000,
    ):
        if part not in PARTS:
            raise ValueError("unknown simulated part %r" % (part,))
        (self.family, who, self.accel_base, self.stride, self.fifo_size, temp, self._pwr1_default,
         self._temp_always) = PARTS[part]
        self.part = part
        self.who = who if who_am_i is None else who_am_i
        self.temp_sens, self.temp_zero = temp
        rng = _Rng(seed)
        self._rng = rng
        if gyro_bias_dps is None:
            zro = 15.0 if self.family == 6050 else 4.5  # within the datasheet tolerance
            gyro_bias_dps = [rng.uniform(-zro, zro) for _ in range(3)]
        if accel_bias_g is None:
            accel_bias_g = [rng.uniform(-0.06, 0.06) for _ in range(3)]
        if factory_trim is None:
            factory_trim = [int(rng.uniform(-4000, 4000)) for _ in range(3)]
        if gyro_noise_dps is None:
            gyro_noise_dps = 0.05 if self.family == 6050 else 0.1
        if accel_noise_g is None:
            accel_noise_g = 0.004 if self.family == 6050 else 0.005
        # bias(T) = b0 + b1 (T - 25) + b2 (T - 25)**2 per axis (dps, g); b1/b2 via set_tc()
        self.gyro_bias = [[float(b), 0.0, 0.0] for b in gyro_bias_dps]
        self.accel_bias = [[float(b), 0.0, 0.0] for b in accel_bias_g]
        self.factory = [int(w) & 0xFFFF for w in factory_trim]  # words, bit 0 included
        self.gyro_noise = float(gyro_noise_dps)
        self.accel_noise = float(accel_noise_g)
        self.temp_c = float(temp_c)
        self.rate = [0.0, 0.0, 0.0]
        self.accel = [0.0, 0.0, 1.0]
        self._turn = None  # (start ns, gravity at the start) while turn() is in effect
        self.byte_ns = 9 * 1000000000 // bus_hz
        self.stuck = set()
        self.cross = None  # (N at 25 degC, its drift per degC), from set_cross()
        self.writes = 0  # register bytes written, for tests that count traffic
        self.oflow_events = 0
        self._noise = _normal_table(seed)
        self._schedule = []
        self.ns = 0
        self.regs = bytearray(128)
        self._fifo = bytearray(self.fifo_size)
        self.power_cycle()

    # ---- environment -------------------------------------------------------------------
    def place(self, face):
        """Lay the part still with axis ``face`` ("+x", "-z", ...) pointing up."""
        self.accel = list(FACES[face])
        self.rate = [0.0, 0.0, 0.0]
        self._turn = None

    def set_motion(self, rate_dps=(0.0, 0.0, 0.0), accel_g=(0.0, 0.0, 1.0)):
        self.rate = [float(v) for v in rate_dps]
        self.accel = [float(v) for v in accel_g]
        self._turn = None

    def turn(self, rate_dps):
        """Rotate steadily at rate_dps (x, y, z deg/s in the part's frame) from now on: the
        gyro sees the rate, and gravity turns the other way in the part's frame (a turn about
        the vertical leaves it where it is). place() or set_motion() stop it."""
        self.rate = [float(v) for v in rate_dps]
        self._turn = (self.ns, list(self.accel))

    def _gravity(self):
        # g(t) = R(-w t) g0 (Rodrigues): the part turns by w t, so gravity turns by -w t in it
        t = self._turn
        if t is None:
            return self.accel
        w = self.rate
        wn = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
        g = t[1]
        if wn == 0.0:
            return g
        a = -math.radians(wn) * (self.ns - t[0]) * 1e-9
        k = (w[0] / wn, w[1] / wn, w[2] / wn)
        c = math.cos(a)
        sn = math.sin(a)
        kd = k[0] * g[0] + k[1] * g[1] + k[2] * g[2]
        kx = (k[1] * g[2] - k[2] * g[1], k[2] * g[0] - k[0] * g[2], k[0] * g[1] - k[1] * g[0])
        return [g[j] * c + kx[j] * sn + k[j] * kd * (1.0 - c) for j in range(3)]

    def schedule(self, after_ms, rate_dps=(0.0, 0.0, 0.0), accel_g=None):
        """Change the motion ``after_ms`` of simulated time from now (a bump mid-capture)."""
        self._schedule.append((self.ns + int(after_ms * 1000000), rate_dps, accel_g))

    def set_tc(self, gyro=None, accel=None):
        """Temperature dependence: per axis (b1, b2) in dps/degC, dps/degC^2 (g for accel)."""
        if gyro is not None:
            for k in range(3):
                self.gyro_bias[k][1], self.gyro_bias[k][2] = gyro[k]
        if accel is not None:
            for k in range(3):
                self.accel_bias[k][1], self.accel_bias[k][2] = accel[k]

    def set_cross(self, n, tc=None):
        """Accelerometer cross-axis sensitivity: output = (I + N(T)) g, N(T) = n + tc (T - 25).

        n, tc: 3x3 (rows: output axis, columns: the acceleration's axis), off-diagonal only,
        tc per degC. Refused (ValueError) if any term leaves the datasheets' +-2 %
        (PS-MPU-6000A-00 table 6.2, PS-MPU-9250A-01 table 3.2: cross-axis sensitivity) anywhere
        in -40..85 degC. Not set: no cross-axis (the default, as before)."""
        n = [[float(v) for v in row] for row in n]
        tc = [[0.0] * 3 for _ in range(3)] if tc is None else [[float(v) for v in row] for row in tc]
        for i in range(3):
            if n[i][i] or tc[i][i]:
                raise ValueError("cross-axis N[%d][%d]: the diagonal is the sensitivity, not a cross-axis term" % (i, i))
            for j in range(3):
                for t in (-40.0, 85.0):  # linear in T: the extremes are at the ends
                    v = n[i][j] + tc[i][j] * (t - 25.0)
                    if abs(v) > 0.02:
                        raise ValueError("cross-axis N[%d][%d] = %.4f at %.0f degC is outside the datasheet's "
                                         "+-2 %%" % (i, j, v, t))
        self.cross = (n, tc)

    def power_cycle(self):
        """Power off and on: registers at reset values, factory trim reloaded, FIFO empty."""
        r = self.regs
        for i in range(len(r)):
            r[i] = 0
        r[WHO_AM_I] = self.who
        r[PWR_MGMT_1] = self._pwr1_default
        for k in range(3):
            a = self.accel_base + self.stride * k
            r[a] = self.factory[k] >> 8
            r[a + 1] = self.factory[k] & 0xFF
        self._head = 0
        self._count = 0
        self._next_ns = self.ns
        self._latest = None

    def glitch_trim(self, axis=1, word=None):
        """The part rewrites an accel trim register by itself (ICM-20602 field problem)."""
        a = self.accel_base + self.stride * axis
        if word is None:
            word = (_s16(self.regs[a], self.regs[a + 1]) + 600) & 0xFFFF
        self.regs[a] = (word >> 8) & 0xFF
        self.regs[a + 1] = word & 0xFF

    # ---- register views for tests (no bus traffic) -----------------------------------------
    def gyro_offsets(self):
        r = self.regs
        return tuple(_s16(r[GYRO_OFFS + 2 * k], r[GYRO_OFFS + 2 * k + 1]) for k in range(3))

    def accel_offsets(self):
        r = self.regs
        out = []
        for k in range(3):
            a = self.accel_base + self.stride * k
            out.append(_s16(r[a], r[a + 1]))
        return tuple(out)

    def config(self):
        """The user-visible configuration registers, as bytes, to compare before/after."""
        r = self.regs
        regs = (SMPLRT_DIV, CONFIG, GYRO_CONFIG, ACCEL_CONFIG, FIFO_EN, INT_ENABLE, USER_CTRL,
                PWR_MGMT_1, PWR_MGMT_2)
        if self.family == 6500:
            regs = regs + (ACCEL_CONFIG2,)
        return bytes([r[a] for a in regs])

    def temp_raw(self):
        return _sat((self.temp_c - self.temp_zero) * self.temp_sens)

    def gyro_fs(self):
        return (self.regs[GYRO_CONFIG] >> 3) & 3

    def accel_fs(self):
        return (self.regs[ACCEL_CONFIG] >> 3) & 3

    def mean_output(self):
        """Noise-free expected (ax, ay, az, gx, gy, gz) output codes, before rounding."""
        return self._clean()

    # ---- model ---------------------------------------------------------------------------
    def _bias(self, coeffs):
        d = self.temp_c - 25.0
        return coeffs[0] + coeffs[1] * d + coeffs[2] * d * d

    def _clean(self):
        r = self.regs
        gfs = self.gyro_fs()
        afs = self.accel_fs()
        gsens = 131.0 / (1 << gfs)
        asens = 16384.0 / (1 << afs)
        out = []
        acc = self._gravity()
        if self.cross is not None:
            n, tc = self.cross
            d = self.temp_c - 25.0
            acc = [acc[i] + sum((n[i][j] + tc[i][j] * d) * acc[j] for j in range(3)) for i in range(3)]
        for k in range(3):
            a = self.accel_base + self.stride * k
            word = _s16(r[a], r[a + 1])
            # bits 15..1 are the offset (2 LSB of the 2048 LSB/g word a step); bit 0 is reserved
            shift_g = ((word >> 1) - (_s16(self.factory[k] >> 8, self.factory[k] & 0xFF) >> 1)) / 1024.0
            out.append((acc[k] + self._bias(self.accel_bias[k]) + shift_g) * asens)
        for k in range(3):
            reg = _s16(r[GYRO_OFFS + 2 * k], r[GYRO_OFFS + 2 * k + 1])
            out.append((self.rate[k] + self._bias(self.gyro_bias[k])) * gsens + reg * 4.0 / (1 << gfs))
        return out

    def _sample(self):
        clean = self._clean()
        rng = self._rng
        noise = self._noise
        asig = self.accel_noise * 16384.0 / (1 << self.accel_fs())
        gsig = self.gyro_noise * 131.0 / (1 << self.gyro_fs())
        b = bytearray(14)
        for k in range(6):
            n = noise[(rng.next() >> 19) & (_NOISE_N - 1)]
            v = _sat(clean[k] + n * (asig if k < 3 else gsig))
            j = 2 * k if k < 3 else 2 * k + 2
            b[j] = (v >> 8) & 0xFF
            b[j + 1] = v & 0xFF
        t = self.temp_raw()
        b[6] = (t >> 8) & 0xFF
        b[7] = t & 0xFF
        return b

    def _period_ns(self):
        r = self.regs
        dlpf = r[CONFIG] & 7
        if self.family == 6500 and r[GYRO_CONFIG] & 3:
            base = 31250  # FCHOICE_B bypasses the DLPF: 32 kHz
        elif dlpf == 0 or dlpf == 7:
            base = 125000  # 8 kHz gyro output rate
        else:
            base = 1000000
        return base * (1 + r[SMPLRT_DIV])

    def _running(self):
        p = self.regs[PWR_MGMT_1]
        return not (p & 0x40) and (p & 7) != 7

    def _fifo_on(self):
        return self.regs[USER_CTRL] & 0x40 and self.regs[FIFO_EN] & 0xF8

    def _advance(self, nbytes):
        self.ns += nbytes * self.byte_ns
        while self._schedule and self._schedule[0][0] <= self.ns:
            _, rate, accel = self._schedule.pop(0)
            if self._turn is not None:  # a turn goes on at the new rate from where it got
                self._turn = (self.ns, self._gravity())
            self.rate = [float(v) for v in rate]
            if accel is not None:
                self.accel = [float(v) for v in accel]
                self._turn = None
        if not self._running():
            self._next_ns = self.ns
            return
        period = self._period_ns()
        while self._next_ns <= self.ns:
            if self._fifo_on():
                self._latest = self._sample()
                self._push(self._latest)
                self._next_ns += period
            else:
                # nothing buffers the samples in between: skip to the last one, made on read
                k = (self.ns - self._next_ns) // period + 1
                self._next_ns += k * period
                self._latest = None

    def _push(self, s):
        en = self.regs[FIFO_EN]
        pkt = bytearray()
        if self.part == "ICM-20602":
            if en & 0x08:
                pkt += s[0:6]
            if en & 0x18:
                pkt += s[6:8]
            if en & 0x10:
                pkt += s[8:14]
        else:
            if en & 0x08:
                pkt += s[0:6]
            if en & 0x80:
                pkt += s[6:8]
            for k in range(3):
                if en & (0x40 >> k):
                    pkt += s[8 + 2 * k:10 + 2 * k]
        n = len(pkt)
        size = self.fifo_size
        if self._count + n > size:
            self.regs[INT_STATUS] |= 0x10
            self.oflow_events += 1
            if self.family == 6500 and self.regs[CONFIG] & 0x40:
                return  # FIFO_MODE: a full FIFO takes no more samples
            drop = self._count + n - size
            self._head = (self._head + drop) % size
            self._count -= drop
        tail = (self._head + self._count) % size
        for i in range(n):
            self._fifo[(tail + i) % size] = pkt[i]
        self._count += n

    def _pop(self):
        if self._count == 0:
            return 0xFF
        v = self._fifo[self._head]
        self._head = (self._head + 1) % self.fifo_size
        self._count -= 1
        return v

    # ---- bus side (SimI2C calls these) ---------------------------------------------------------
    def read(self, reg, n):
        self._advance(n + 3)  # address+W, register, address+R, n data bytes
        out = bytearray(n)
        data = None
        count = self._count
        for i in range(n):
            if reg == FIFO_R_W:
                out[i] = self._pop()
                continue
            a = (reg + i) & 0x7F
            if DATA <= a <= 0x48:
                if data is None:
                    if self._latest is None and self._running():
                        self._latest = self._sample()
                    data = self._latest if self._latest is not None else bytes(14)
                out[i] = data[a - DATA]
            elif a == FIFO_COUNTH:
                out[i] = (count >> 8) & 0xFF
            elif a == FIFO_COUNTL:
                out[i] = count & 0xFF
            elif a == FIFO_R_W:
                out[i] = self._pop()
            else:
                out[i] = self.regs[a]
                if a == INT_STATUS:
                    self.regs[INT_STATUS] = 0  # cleared by reading it
        return bytes(out)

    def write(self, reg, data):
        self._advance(len(data) + 2)
        for i in range(len(data)):
            a = (reg + i) & 0x7F
            v = data[i]
            self.writes += 1
            if a in self.stuck or a in _READ_ONLY or DATA <= a <= 0x48:
                continue
            if a == FIFO_R_W:
                self._push(bytes([v]))
            elif a == USER_CTRL:
                if v & 0x04:
                    self._head = 0
                    self._count = 0
                self.regs[a] = v & ~0x07  # FIFO/I2C master/signal-path resets clear themselves
            elif a == PWR_MGMT_1:
                if v & 0x80:
                    self.power_cycle()
                    continue
                was = self._running()
                self.regs[a] = v
                if not was and self._running():
                    self._next_ns = self.ns
            else:
                self.regs[a] = v
