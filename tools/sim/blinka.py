"""Put simulated buses behind the real Adafruit Blinka ``busio`` classes (CPython only).

With BLINKA_OS_AGNOSTIC=1, ``busio.I2C(board.SCL, board.SDA)`` and
``busio.SPI(board.SCK, board.MOSI, board.MISO)`` build Blinka's generic back-ends; we replace
that back-end object (``_i2c``/``_spi``) with an adapter onto a SimI2C/SimSPI, so Blinka's own
locking, ``configure`` and ``writeto(..., start=, end=)`` slicing code runs unchanged. CS is a
real ``digitalio.DigitalInOut`` whose level changes are forwarded to the simulated pin.
"""

import os

os.environ.setdefault("BLINKA_OS_AGNOSTIC", "1")

import board  # noqa: E402
import busio  # noqa: E402
import digitalio  # noqa: E402


def _sl(buf, start, end):
    return buf[start : len(buf) if end is None else end]


class _I2CBackend:
    def __init__(self, sim):
        self.sim = sim

    def scan(self):
        return self.sim.scan()

    def writeto(self, address, buffer, *, start=0, end=None, stop=True):
        self.sim.writeto(address, _sl(buffer, start, end))

    def readfrom_into(self, address, buffer, *, start=0, end=None, stop=True):
        view = memoryview(buffer)[start : len(buffer) if end is None else end]
        tmp = bytearray(len(view))
        self.sim.readfrom_into(address, tmp)
        view[:] = tmp

    def writeto_then_readfrom(self, address, buffer_out, buffer_in, *, out_start=0, out_end=None,
                              in_start=0, in_end=None, stop=False):
        out = bytes(_sl(buffer_out, out_start, out_end))
        view = memoryview(buffer_in)[in_start : len(buffer_in) if in_end is None else in_end]
        tmp = bytearray(len(view))
        if len(out) == 1:
            # a register read: one bus transaction on the simulated part, as on a real bus
            self.sim.readfrom_mem_into(address, out[0], tmp)
        else:
            self.sim.writeto(address, out)
            self.sim.readfrom_into(address, tmp)
        view[:] = tmp


class _SPIBackend:
    def __init__(self, sim):
        self.sim = sim
        self.baudrate = None
        self.polarity = None
        self.phase = None

    def init(self, baudrate=100000, polarity=0, phase=0, bits=8, firstbit=None, sck=None, mosi=None, miso=None):
        self.baudrate, self.polarity, self.phase = baudrate, polarity, phase

    def write(self, buf, start=0, end=None):
        self.sim.write(_sl(buf, start, end))

    def readinto(self, buf, start=0, end=None, write_value=0):
        view = memoryview(buf)[start : len(buf) if end is None else end]
        tmp = bytearray(len(view))
        self.sim.readinto(tmp, write_value)
        view[:] = tmp

    def write_readinto(self, buffer_out, buffer_in, out_start=0, out_end=None, in_start=0, in_end=None):
        out = bytes(_sl(buffer_out, out_start, out_end))
        view = memoryview(buffer_in)[in_start : len(buffer_in) if in_end is None else in_end]
        tmp = bytearray(len(view))
        self.sim.write_readinto(out, tmp)
        view[:] = tmp


def i2c(sim):
    """A real busio.I2C whose transfers reach the SimI2C sim."""
    bus = busio.I2C(board.SCL, board.SDA)
    bus._i2c = _I2CBackend(sim)
    return bus


def spi(sim):
    """A real busio.SPI whose transfers reach the SimSPI sim."""
    bus = busio.SPI(board.SCK, board.MOSI, board.MISO)
    bus._spi = _SPIBackend(sim)
    return bus


class _ForwardingDIO(digitalio.DigitalInOut):
    def __init__(self, pin, sim_pin):
        super().__init__(pin)
        self._sim_pin = sim_pin

    @property
    def value(self):
        return bool(self._sim_pin.value())

    @value.setter
    def value(self, v):
        self._sim_pin.value(1 if v else 0)


def cs_pin(sim_pin, pin=None):
    """A real digitalio.DigitalInOut whose level drives sim_pin (a SimPin)."""
    return _ForwardingDIO(pin if pin is not None else board.Dx_OUTPUT, sim_pin)
