# `machine` for the virtual board: the MicroPython API, backed by vboard.board.
# Errors are raised as MicroPython ports raise them: OSError(ENODEV) when no
# device answers an I2C address, whatever the device model raises otherwise.
import errno
import time

from vboard import board as _board

PWRON_RESET = 1
HARD_RESET = 2
WDT_RESET = 3
DEEPSLEEP_RESET = 4
SOFT_RESET = 5

_FREQ = 125_000_000

# Board time a bus call takes (vboard.py, "Time"): the bits on the wire plus what the
# MicroPython call itself costs an MCU (tens of microseconds at 125 MHz).
_CALL_US = 20
_ADC_US = 10  # conversion (2 us on an RP2040) and the call


def reset():
    import js

    js.vboard_reset()
    raise SystemExit


def soft_reset():
    raise SystemExit


def reset_cause():
    return PWRON_RESET


def freq(hz=None):
    global _FREQ
    if hz is None:
        return _FREQ
    _FREQ = hz


def unique_id():
    return b"vboard\x00\x01"


def idle():
    _board.advance_us(1000)
    time.sleep_ms(1)


def lightsleep(ms=None):
    if ms:
        _board.advance_us(ms * 1000)
        time.sleep_ms(ms)


deepsleep = lightsleep


def disable_irq():
    return 0


def enable_irq(state=0):
    pass


def _pin_id(p):
    return p._id if isinstance(p, Pin) else p


class Pin:
    IN = 0
    OUT = 1
    OPEN_DRAIN = 2
    ALT = 3
    PULL_UP = 1
    PULL_DOWN = 2
    IRQ_FALLING = 4
    IRQ_RISING = 8

    def __init__(self, id, mode=-1, pull=-1, *, value=None):
        self._id = id
        self._mode = Pin.IN
        self._pull = None
        self._irq = None
        self.init(mode, pull, value=value)

    def init(self, mode=-1, pull=-1, *, value=None):
        if mode != -1:
            self._mode = mode
        if pull != -1:
            self._pull = pull
        if value is not None:
            _board.pin_write(self._id, 1 if value else 0)

    def value(self, v=None):
        if v is None:
            return _board.pin_read(self._id)
        _board.pin_write(self._id, 1 if v else 0)

    def __call__(self, v=None):
        return self.value(v)

    def on(self):
        _board.pin_write(self._id, 1)

    def off(self):
        _board.pin_write(self._id, 0)

    high = on
    low = off

    def toggle(self):
        _board.pin_write(self._id, 0 if _board.pin_read(self._id) else 1)

    def irq(self, handler=None, trigger=IRQ_FALLING | IRQ_RISING, hard=False):
        # Stored, never fired: the virtual board has no interrupt source.
        self._irq = handler

    def __repr__(self):
        return "Pin(%s)" % (self._id,)


class I2C:
    def __init__(self, id=0, *, scl=None, sda=None, freq=400_000, timeout=50_000):
        self._bus = id
        self._freq = freq
        self._mab = bytearray(1)

    def init(self, *, scl=None, sda=None, freq=400_000, timeout=50_000):
        self._freq = freq

    def deinit(self):
        pass

    def _wire(self, nbytes):
        # address byte + data, 9 clocks a byte
        _board.advance_us(_CALL_US + (nbytes + 1) * 9_000_000 // self._freq)

    def _dev(self, addr):
        dev = _board.i2c_device(self._bus, addr)
        if dev is None:
            raise OSError(errno.ENODEV)
        return dev

    def _memaddr(self, memaddr, addrsize):
        if addrsize == 8:
            self._mab[0] = memaddr & 0xFF
            return self._mab
        n = addrsize // 8
        return bytes((memaddr >> (8 * (n - 1 - i))) & 0xFF for i in range(n))

    def scan(self):
        return _board.i2c_scan(self._bus)

    def writeto(self, addr, buf, stop=True):
        self._wire(len(buf))
        self._dev(addr).write(buf)
        return len(buf)

    def writevto(self, addr, vector, stop=True):
        dev = self._dev(addr)
        n = 0
        data = bytearray()
        for b in vector:
            data.extend(b)
            n += len(b)
        self._wire(n)
        dev.write(data)
        return n

    def readfrom(self, addr, nbytes, stop=True):
        buf = bytearray(nbytes)
        self.readfrom_into(addr, buf)
        return bytes(buf)

    def readfrom_into(self, addr, buf, stop=True):
        self._wire(len(buf))
        self._dev(addr).read_into(buf)

    def readfrom_mem(self, addr, memaddr, nbytes, *, addrsize=8):
        buf = bytearray(nbytes)
        self.readfrom_mem_into(addr, memaddr, buf, addrsize=addrsize)
        return bytes(buf)

    def readfrom_mem_into(self, addr, memaddr, buf, *, addrsize=8):
        self._wire(addrsize // 8 + 1 + len(buf))  # register address, repeated start, data
        dev = self._dev(addr)
        dev.write(self._memaddr(memaddr, addrsize))
        dev.read_into(buf)

    def writeto_mem(self, addr, memaddr, buf, *, addrsize=8):
        self._wire(addrsize // 8 + len(buf))
        dev = self._dev(addr)
        dev.write(bytes(self._memaddr(memaddr, addrsize)) + bytes(buf))


class SoftI2C(I2C):
    pass


class SPI:
    CONTROLLER = 0
    MASTER = 0
    MSB = 0
    LSB = 1

    def __init__(self, id=0, baudrate=1_000_000, *, polarity=0, phase=0, bits=8,
                 firstbit=0, sck=None, mosi=None, miso=None):
        self._bus = id
        self.init(baudrate, polarity=polarity, phase=phase, bits=bits, firstbit=firstbit)

    def init(self, baudrate=1_000_000, *, polarity=0, phase=0, bits=8, firstbit=0,
             sck=None, mosi=None, miso=None):
        self.baudrate = baudrate
        self.polarity = polarity
        self.phase = phase
        self.bits = bits
        self.firstbit = firstbit

    def deinit(self):
        pass

    def _xfer(self, wbuf, rbuf):
        _board.advance_us(_CALL_US + len(wbuf) * 8_000_000 // self.baudrate)
        dev = _board.spi_selected(self._bus)
        if dev is not None:
            dev.transfer(wbuf, rbuf)
        elif rbuf is not None:
            # Nobody drives MISO: the line floats high.
            for i in range(len(rbuf)):
                rbuf[i] = 0xFF

    def write(self, buf):
        self._xfer(buf, None)

    def read(self, nbytes, write=0x00):
        buf = bytearray(nbytes)
        self.readinto(buf, write)
        return bytes(buf)

    def readinto(self, buf, write=0x00):
        self._xfer(bytes([write]) * len(buf), buf)

    def write_readinto(self, write_buf, read_buf):
        if len(write_buf) != len(read_buf):
            raise ValueError("buffers must be the same length")
        self._xfer(write_buf, read_buf)


class SoftSPI(SPI):
    pass


class ADC:
    CORE_TEMP = 4

    def __init__(self, pin, *, atten=None):
        ch = _pin_id(pin)
        # As on an RP2040: ADC(0..4) are channels, ADC(Pin(26..29)) the pins.
        self._ch = ch + 26 if isinstance(ch, int) and 0 <= ch <= 3 else ch

    def read_u16(self):
        _board.advance_us(_ADC_US)
        return _board.adc_read(self._ch)


class RTC:
    def __init__(self, id=0):
        self._offset = 0

    def datetime(self, dt=None):
        if dt is None:
            t = time.localtime(int(time.time()) + self._offset)
            # (year, month, day, weekday, hours, minutes, seconds, subseconds)
            return (t[0], t[1], t[2], t[6], t[3], t[4], t[5], 0)
        y, mo, d, _wd, h, mi, s = dt[:7]
        self._offset = time.mktime((y, mo, d, h, mi, s, 0, 0)) - int(time.time())


class WDT:
    def __init__(self, id=0, timeout=5000):
        pass

    def feed(self):
        pass
