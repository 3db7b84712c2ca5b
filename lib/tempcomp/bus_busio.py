"""CircuitPython's and Blinka's ``busio``: the bus lock and I2C register access by write-then-read.

``busio.I2C`` has no register calls (only ``writeto``/``writeto_then_readfrom``) and every
transfer needs ``try_lock()``. ``tempcomp.bus.I2CDevice`` loads this module only for such a bus,
and ``tempcomp.bus_spi`` only for a ``busio.SPI``: a MicroPython board (``machine.I2C``,
``machine.SPI``) never holds it (docs/ram.md). It imports nothing of ours.

Errors: bus faults propagate as ``OSError``; a bus that stays locked by someone else raises
``OSError`` naming the bus after a bounded wait; a write longer than the preallocated buffer
raises ``ValueError``.
"""

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


_LOCK_TRIES = const(10000)
MAX_WRITE = const(32)  # register bytes one write() takes (the MPU offsets: 2)


def lock(bus):
    """Take a CircuitPython/Blinka bus's lock, waiting a bounded time (OSError naming the bus)."""
    n = 0
    while not bus.try_lock():
        n += 1
        if n >= _LOCK_TRIES:
            raise OSError("bus %r stayed locked by another user" % (bus,))


class Registers:
    """``read_into``/``write`` of register access to one address on a busio.I2C (allocation-free)."""

    def __init__(self, bus, address):
        self.bus = bus
        self.address = address
        self._reg = bytearray(1)
        self._wbuf = bytearray(MAX_WRITE + 1)

    def read_into(self, reg, buf):
        self._reg[0] = reg
        lock(self.bus)
        try:
            self.bus.writeto_then_readfrom(self.address, self._reg, buf)
        finally:
            self.bus.unlock()

    def write(self, reg, buf):
        n = len(buf)
        if n > MAX_WRITE:
            raise ValueError("write of %d bytes exceeds %d" % (n, MAX_WRITE))
        w = self._wbuf
        w[0] = reg
        w[1 : n + 1] = buf
        lock(self.bus)
        try:
            self.bus.writeto(self.address, w, end=n + 1)
        finally:
            self.bus.unlock()
