# The simulated sensors on the virtual board, and the world they sit in.
#
# The parts themselves are the register-level models in tools/sim (MLX90609,
# MPU-6500, analog gyro); this module only adapts them to the board's
# transaction-level device interface (see vboard.py) and feeds them the
# physics: the board's temperature (board time through the profile), its
# orientation and its rotation.  Runs in the VM (the models are copied in
# next to this file) and on CPython (tests build the same parts with PARTS).
#
# A script, a test or `make demo` plays the user's hands through `world`:
#
#     import vboard_sensors
#     vboard_sensors.world.place("-x")          # lay the board with -x up
#     vboard_sensors.world.spin((0, 0, 10.0))   # a turntable at 10 deg/s about z
#     vboard_sensors.world.bump(after_ms=50)    # knock it for a second
#     vboard_sensors.world.heat([(0, 20), (30, 50)])  # warm it from 20 to 50 degC in 30 s
#
# Time: temperature and motion follow board.clock_ms(), the board's own simulated
# time (vboard.py, "Time": bus transfers and sleeps move it, the host's clock does
# not), and the MPU-6500 model's sample clock runs on its own bus traffic (9 clocks
# a byte at 400 kHz): a capture sees the same world on an idle or a loaded host.

import math

from analog_gyro_sim import AnalogGyroSim
from mlx90609_sim import MLX90609Sim
from mpu6xxx_sim import FACES, MPU6xxxSim

# The parts on this board: every constant here is a "true" property of the
# simulated hardware, used by the end-to-end tests as the reference.
MPU_PART = "MPU-6500"
MPU_SEED = 7
MPU_GYRO_BIAS_DPS = (2.5, -1.8, 0.9)  # at 25 degC
MPU_ACCEL_BIAS_G = (0.03, -0.02, 0.04)
# gyro bias(T) = b0 + b1 (T - 25) + b2 (T - 25)**2: (b1 dps/degC, b2 dps/degC^2) per axis
MPU_GYRO_TC = ((0.06, 0.002), (-0.05, 0.0015), (0.08, -0.001))
MPU_GYRO_NOISE_DPS = 0.05

MLX_FULL_SCALE_DPS = 150
MLX_ZRO_MV = (2440.0, 2500.0, 2570.0)  # at -40, 25, 85 degC, as written in its EEPROM
MLX_SUPPLY_SHIFT_MV = 8.0  # this board's supply moves the ZRO off the factory table

ADXRS_VREF_MV = 3300.0
ADXRS_DIVIDER = 2.0  # 5 V sensor into a 3.3 V ADC through a 1:2 divider
ADXRS_NULL_MV = (2500.0, 0.08, 2.0e-4)  # null(VT) quadratic in VT - 2500 mV
ADXRS_SCALE_MV = (6.0, -4.0e-4, 1.5e-6)  # mV per deg/s, quadratic in VT - 2500 mV
ADXRS_NOISE_MV = 0.5


def make_parts():
    """(mpu, mlx, adxrs): the simulated parts of this board, freshly powered."""
    mpu = MPU6xxxSim(MPU_PART, seed=MPU_SEED, gyro_bias_dps=MPU_GYRO_BIAS_DPS,
                     accel_bias_g=MPU_ACCEL_BIAS_G, gyro_noise_dps=MPU_GYRO_NOISE_DPS)
    mpu.set_tc(gyro=MPU_GYRO_TC)
    mlx = MLX90609Sim(version=2, full_scale_dps=MLX_FULL_SCALE_DPS, zro_mv=MLX_ZRO_MV,
                      supply_shift_mv=MLX_SUPPLY_SHIFT_MV)
    adxrs = AnalogGyroSim(vref_mv=ADXRS_VREF_MV, divider=ADXRS_DIVIDER, null_mv=ADXRS_NULL_MV,
                          scale_mv=ADXRS_SCALE_MV, noise_mv=ADXRS_NOISE_MV, seed=3)
    return mpu, mlx, adxrs


class World:
    """Where the board is: temperature from the board's profile, orientation, rotation."""

    def __init__(self, board):
        self.board = board
        self.face = "+z"
        self.rate = (0.0, 0.0, 0.0)
        self._bump = None  # (start ms, end ms, rate)

    def place(self, face):
        """Lay the board still with axis face ("+x", "-z", ...) pointing up."""
        if face not in FACES:
            raise ValueError("face must be one of %s" % ", ".join(sorted(FACES)))
        self.face = face
        self.rate = (0.0, 0.0, 0.0)

    def spin(self, rate_dps):
        """Turn the board at a constant rate (x, y, z deg/s), keeping its face up."""
        self.rate = (float(rate_dps[0]), float(rate_dps[1]), float(rate_dps[2]))

    def bump(self, rate_dps=(60.0, -45.0, 80.0), after_ms=0, for_ms=1000):
        """Knock the board: a half-sine of rotation peaking at rate_dps (x, y, z deg/s),
        lasting for_ms of board time and starting after_ms from now."""
        t = self.board.clock_ms() + after_ms
        self._bump = (t, t + for_ms, rate_dps)

    def rate_now(self):
        b = self._bump
        if b is not None:
            t = self.board.clock_ms()
            if b[0] <= t < b[1]:
                k = math.sin(math.pi * (t - b[0]) / (b[1] - b[0]))
                r = self.rate
                p = b[2]
                return (r[0] + k * p[0], r[1] + k * p[1], r[2] + k * p[2])
            if t >= b[1]:
                self._bump = None
        return self.rate

    def heat(self, points):
        """Start a temperature programme now (a heater, a chamber): [(s from now, degC), ...]."""
        now = self.board.clock_ms() / 1000.0
        self.board.set_profile([(now + s, c) for s, c in points])

    def temperature_c(self):
        return self.board.temperature_c()


class MPUOnI2C:
    """The register model behind the I2C transaction interface (write / read_into)."""

    def __init__(self, sim, world):
        self.sim = sim
        self.world = world
        self._reg = 0

    def _physics(self):
        s = self.sim
        w = self.world
        s.temp_c = w.temperature_c()
        r = w.rate_now()
        s.rate = [r[0], r[1], r[2]]
        g = FACES[w.face]
        s.accel = [g[0], g[1], g[2]]

    def write(self, buf):
        # the first byte sets the register pointer; the rest are data (auto-increment)
        if not len(buf):
            return
        self._physics()
        self._reg = buf[0]
        if len(buf) > 1:
            self.sim.write(self._reg, bytes(buf[1:]))

    def read_into(self, buf):
        self._physics()
        data = self.sim.read(self._reg, len(buf))
        for i in range(len(buf)):
            buf[i] = data[i]


class MLXOnSPI:
    """The MLX90609 model behind the SPI transaction interface (transfer, select/deselect)."""

    AXIS = 2  # a yaw-rate part: it senses rotation about the board's z axis

    def __init__(self, sim, world):
        self.sim = sim
        self.world = world
        self._state = None
        self._scratch = bytearray(8)

    def select(self):
        # the state a conversion samples: changes only when the world did (0.01 degC steps)
        w = self.world
        st = (w.rate_now()[self.AXIS], int(w.temperature_c() * 100))
        if st != self._state:
            self._state = st
            self.sim.set_state(st[0], st[1] / 100.0)
        self.sim.select()

    def deselect(self):
        self.sim.deselect()

    def transfer(self, wbuf, rbuf):
        if rbuf is None:
            if len(self._scratch) < len(wbuf):
                self._scratch = bytearray(len(wbuf))
            rbuf = memoryview(self._scratch)[: len(wbuf)]
        self.sim.transfer_into(wbuf, rbuf)


class AnalogChannel:
    """One ADC input wired to the analog gyro's rate (0) or temperature (1) output."""

    AXIS = 2

    def __init__(self, sim, world, which):
        self.sim = sim
        self.world = world
        self.which = which

    def read_u16(self):
        s = self.sim
        s.temp_c = self.world.temperature_c()
        s.rate_dps = self.world.rate_now()[self.AXIS]
        return s.code(self.which)


world = None
parts = None


def wire(board, i2c_bus, mpu_addr, spi_bus, mlx_cs, adc_rate, adc_temp):
    """Put this board's parts on the buses; returns the World that moves them."""
    global world, parts
    world = World(board)
    mpu, mlx, adxrs = make_parts()
    parts = {"mpu": mpu, "mlx": mlx, "adxrs": adxrs}
    board.add_i2c(i2c_bus, mpu_addr, MPUOnI2C(mpu, world))
    board.add_spi(spi_bus, mlx_cs, MLXOnSPI(mlx, world))
    board.add_adc(adc_rate, AnalogChannel(adxrs, world, 0))
    board.add_adc(adc_temp, AnalogChannel(adxrs, world, 1))
    return world
