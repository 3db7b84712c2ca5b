"""Simulated buses with the MicroPython ``machine`` API, in front of simulated devices.

Runs on CPython and inside the MicroPython VM (no CPython-only imports), so the same device
models serve pytest, the VM tests and the virtual board.

I2C device models implement ``read(reg, n) -> bytes`` and ``write(reg, data)`` (register
auto-increment is the model's business). SPI device models implement ``select()``,
``deselect()`` and ``transfer(out) -> bytes`` (one full-duplex chunk while CS is low), and
optionally ``transfer_into(out, into)``, which ``write_readinto`` then uses without allocating.

Fault injection: ``bus.fail_at = k`` makes the k-th transaction from now (0 = the next one)
raise ``OSError(errno.EIO)``, as a NACK does on real ports; ``bus.transactions`` counts them.
``bus.garble_at = k`` corrupts what the master receives on the k-th *read* from now (``bus.reads``
counts them) without any error, as noise or a marginal pull-up can: the device still sends (a
FIFO still pops), the caller gets ``bus.garble`` bytes instead: "random" (seeded by
``bus.garble_seed``), "flip" (one bit of one byte), "ones" (0xFF), "zeros" or "slip" (every
byte one position late, a lost clock).
"""

try:
    import errno

    _EIO = errno.EIO
    _ENODEV = errno.ENODEV
except (ImportError, AttributeError):
    _EIO = 5
    _ENODEV = 19


GARBLES = ("random", "flip", "ones", "zeros", "slip")


class _FaultCounter:
    def __init__(self):
        self.transactions = 0
        self.fail_at = None
        self.reads = 0
        self.garble_at = None
        self.garble = "random"
        self.garble_seed = 1
        self.garbled = 0  # reads corrupted so far

    def _garble(self, data):
        # data: what the device sent on one read; returns what the master receives
        n = self.reads
        self.reads = n + 1
        k = self.garble_at
        if k is None:
            return data
        if k > 0:
            self.garble_at = k - 1
            return data
        self.garble_at = None
        self.garbled += 1
        x = (self.garble_seed * 2654435761 + 12345) & 0x7FFFFFFF
        out = bytearray(data)
        m = len(out)
        kind = self.garble
        if kind == "random":
            for i in range(m):
                x = (x * 1103515245 + 12345) & 0x7FFFFFFF
                out[i] = (x >> 16) & 0xFF
        elif kind == "flip":
            x = (x * 1103515245 + 12345) & 0x7FFFFFFF
            out[(x >> 8) % m] ^= 1 << ((x >> 4) & 7)
        elif kind == "ones":
            for i in range(m):
                out[i] = 0xFF
        elif kind == "zeros":
            for i in range(m):
                out[i] = 0
        elif kind == "slip":
            for i in range(m - 1, 0, -1):
                out[i] = out[i - 1]
            out[0] = 0xFF
        else:
            raise ValueError("garble must be one of %s" % (", ".join(GARBLES),))
        return bytes(out)

    def _tick(self):
        n = self.transactions
        self.transactions = n + 1
        if self.fail_at is not None:
            if self.fail_at == 0:
                self.fail_at = None
                raise OSError(_EIO)
            self.fail_at -= 1


class SimI2C(_FaultCounter):
    """machine.I2C stand-in: readfrom_mem(_into), writeto_mem, writeto, readfrom_into, scan."""

    def __init__(self, devices=None):
        _FaultCounter.__init__(self)
        self.devices = dict(devices or {})
        self._pending_reg = {}

    def attach(self, address, device):
        self.devices[address] = device

    def _dev(self, addr):
        d = self.devices.get(addr)
        if d is None:
            raise OSError(_ENODEV)
        return d

    def scan(self):
        return sorted(self.devices)

    def readfrom_mem_into(self, addr, memaddr, buf, addrsize=8):
        self._tick()
        data = self._garble(self._dev(addr).read(memaddr, len(buf)))
        for i in range(len(buf)):
            buf[i] = data[i]

    def readfrom_mem(self, addr, memaddr, nbytes, addrsize=8):
        buf = bytearray(nbytes)
        self.readfrom_mem_into(addr, memaddr, buf)
        return bytes(buf)

    def writeto_mem(self, addr, memaddr, buf, addrsize=8):
        self._tick()
        self._dev(addr).write(memaddr, bytes(buf))

    # Plain transfers, as busio-style code uses: first written byte is the register pointer.
    def writeto(self, addr, buf, stop=True):
        self._tick()
        dev = self._dev(addr)
        b = bytes(buf)
        if not b:
            return 0
        if len(b) > 1:
            dev.write(b[0], b[1:])
        self._pending_reg[addr] = b[0]
        return len(b)

    def readfrom_into(self, addr, buf, stop=True):
        self._tick()
        dev = self._dev(addr)
        reg = self._pending_reg.get(addr, 0)
        data = self._garble(dev.read(reg, len(buf)))
        for i in range(len(buf)):
            buf[i] = data[i]


class SimPin:
    """machine.Pin stand-in: value()/value(v)/__call__, with listeners on level changes."""

    OUT = 1
    IN = 0

    def __init__(self, id=None, mode=None, value=1):
        self.id = id
        self._v = 1 if value is None else int(bool(value))
        self._listeners = []

    def listen(self, fn):
        self._listeners.append(fn)

    def value(self, v=None):
        if v is None:
            return self._v
        v = int(bool(v))
        if v != self._v:
            self._v = v
            for fn in self._listeners:
                fn(v)
        return None

    def __call__(self, v=None):
        return self.value(v)

    def on(self):
        self.value(1)

    def off(self):
        self.value(0)


class SimSPI(_FaultCounter):
    """machine.SPI stand-in driving one device per chip-select pin."""

    def __init__(self):
        _FaultCounter.__init__(self)
        self._selected = None
        self._cs = []

    def attach(self, cs_pin, device):
        """Wire device to cs_pin (a SimPin): CS low selects it, CS high deselects."""

        def on_level(v, device=device):
            if v == 0:
                self._selected = device
                device.select()
            else:
                if self._selected is device:
                    self._selected = None
                device.deselect()

        cs_pin.listen(on_level)
        self._cs.append(cs_pin)

    def _xfer(self, out):
        self._tick()
        dev = self._selected
        if dev is None:
            return b"\xff" * len(out)  # nobody drives MISO: pulled high
        return dev.transfer(bytes(out))

    def write_readinto(self, out, into):
        dev = self._selected
        if dev is not None and hasattr(dev, "transfer_into"):
            # models that fill the caller's buffer keep the whole chain allocation-free, so
            # the VM allocation proofs of drivers can run against them
            self._tick()
            dev.transfer_into(out, into)
            return
        data = self._xfer(out)
        for i in range(len(into)):
            into[i] = data[i]

    def readinto(self, buf, write=0):
        data = self._xfer(bytes([write]) * len(buf))
        for i in range(len(buf)):
            buf[i] = data[i]

    def read(self, n, write=0):
        buf = bytearray(n)
        self.readinto(buf, write)
        return bytes(buf)

    def write(self, buf):
        self._xfer(buf)

    def init(self, *args, **kwargs):
        pass

    def deinit(self):
        pass
