"""The SPI adapter: chip-select framed full-duplex exchanges on machine.SPI or busio.SPI.

Beside ``tempcomp.bus`` (the I2C adapter); on ``tempcomp.bus_busio``'s ``lock`` for a busio.SPI
(loaded only then); loaded by the drivers of SPI parts (``tempcomp.mlx90609``) only. After ``__init__`` an exchange allocates nothing (the buffers are
the caller's).

Usage::

    from tempcomp.bus_spi import SPIDevice
    spi_dev = SPIDevice(spi, cs_pin)   # machine.Pin or digitalio.DigitalInOut
    spi_dev.exchange(out3, in3)        # CS low, full-duplex transfer, CS high

Errors: bus faults propagate as ``OSError``; a bus that stays locked by someone else raises
``OSError`` naming the bus after a bounded wait.
"""

class SPIDevice:
    """Chip-select framed full-duplex exchanges on a machine.SPI or busio.SPI bus.

    cs: a MicroPython ``machine.Pin`` (configured as output) or a CircuitPython
    ``digitalio.DigitalInOut``. On CircuitPython the bus is locked and configured with
    baudrate/polarity/phase for every exchange, as its design guide asks; on MicroPython the
    caller creates the SPI with those settings.
    """

    def __init__(self, bus, cs, baudrate=1000000, polarity=1, phase=1):
        self.bus = bus
        self.cs = cs
        self.baudrate = baudrate
        self.polarity = polarity
        self.phase = phase
        self._lock = None
        if hasattr(bus, "try_lock"):  # busio.SPI
            from tempcomp.bus_busio import lock

            self._lock = lock
        if hasattr(cs, "switch_to_output"):  # digitalio.DigitalInOut
            cs.switch_to_output(value=True)
            self._select = self._dio_select
        elif hasattr(cs, "value") and callable(cs.value):  # machine.Pin
            cs.value(1)
            self._select = self._pin_select
        else:
            raise TypeError("chip select %r is neither machine.Pin nor digitalio.DigitalInOut" % (cs,))

    def _pin_select(self, level):
        self.cs.value(level)

    def _dio_select(self, level):
        self.cs.value = bool(level)

    def exchange(self, out, into):
        """Send out while receiving into (same length) with CS held low."""
        bus = self.bus
        if self._lock is not None:
            self._lock(bus)
            try:
                bus.configure(baudrate=self.baudrate, polarity=self.polarity, phase=self.phase)
                self._select(0)
                try:
                    bus.write_readinto(out, into)
                finally:
                    self._select(1)
            finally:
                bus.unlock()
        else:
            self._select(0)
            try:
                bus.write_readinto(out, into)
            finally:
                self._select(1)
