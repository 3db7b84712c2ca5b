"""Thin bus adapters so drivers never care which port they run on: I2C here, SPI in
``tempcomp.bus_spi``, so a board whose sensors are all on I2C never loads the SPI adapter, and
CircuitPython's busio in ``tempcomp.bus_busio``, so a MicroPython board never loads that
(docs/ram.md).

MicroPython's ``machine.I2C`` has ``readfrom_mem_into``/``writeto_mem``; CircuitPython's and
Blinka's ``busio.I2C`` have only ``writeto``/``writeto_then_readfrom`` and need ``try_lock()``
(``tempcomp.bus_busio``). The right methods are bound once in ``__init__``; after that a
register read allocates nothing (buffers are the caller's or preallocated here).

Usage::

    from tempcomp.bus import I2CDevice
    dev = I2CDevice(i2c, 0x68)
    dev.read_into(0x75, buf1)          # WHO_AM_I into a 1-byte bytearray
    dev.write(0x13, b"\\x00\\x10")

Errors: bus faults propagate as ``OSError`` (as both ports raise them); a bus that stays
locked by someone else raises ``OSError`` naming the bus after a bounded wait.
"""


class I2CDevice:
    """Register access to one I2C address on a machine.I2C or busio.I2C bus."""

    def __init__(self, bus, address):
        if not 0 <= address <= 0x7F:
            raise ValueError("I2C address must be 0..0x7F, got %r" % (address,))
        self.bus = bus
        self.address = address
        self._reg = bytearray(1)
        if hasattr(bus, "readfrom_mem_into"):
            self.read_into = self._mp_read_into
            self.write = self._mp_write
        elif hasattr(bus, "writeto_then_readfrom"):
            from tempcomp.bus_busio import Registers

            r = Registers(bus, address)
            self.read_into = r.read_into
            self.write = r.write
        else:
            raise TypeError("%r is not an I2C bus (needs readfrom_mem_into or writeto_then_readfrom)" % (bus,))

    def _mp_read_into(self, reg, buf):
        self.bus.readfrom_mem_into(self.address, reg, buf)

    def _mp_write(self, reg, buf):
        self.bus.writeto_mem(self.address, reg, buf)

    def read_u8(self, reg):
        """One register byte (allocation-free)."""
        r = self._reg
        self.read_into(reg, r)
        return r[0]
