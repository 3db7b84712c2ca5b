# The virtual board's hardware: pins, buses and the simulated devices on them.
#
# `machine` (machine.py next to this file) is the MCU side; this module is the
# PCB side.  Device models are plain MicroPython classes registered by
# vboard_devices.setup(board), which the host copies in at every boot.
#
# Device interfaces (duck-typed; raise OSError(errno.EIO) to NACK / fail):
#
#   I2C device   write(buf)         bytes the controller sent after the address
#                                   (for *_mem calls: the register address,
#                                   then for writeto_mem the data)
#                read_into(buf)     fill buf with what the device sends back
#   SPI device   transfer(wbuf, rbuf)
#                                   one full-duplex transfer while the device's
#                                   chip select is low; rbuf is None for
#                                   write-only calls, same length otherwise
#                select() / deselect()   optional, on chip-select edges
#   ADC source   read_u16()         0..65535, or any callable returning that
#
# Time: board.clock_ms() counts milliseconds of simulated time since the
# host started the board (it continues across soft and hard resets, as the
# physics of a board would), scaled by VBOARD_TIME_SCALE.  A temperature
# profile maps that time to degrees Celsius: board.temperature_c().
#
# Simulated time is the board's own: it advances by what the code on the board
# does - each bus transfer by its time on the wire plus a fixed MCU cost, each
# time.sleep*() by the time asked for - and not by the host's clock.  So a
# capture sees the same world whether the host is idle or loaded (a knock of
# 300 ms lasts the same number of samples, a heater does not run on during a
# slow capture), and the world stands still while the REPL waits for a key.
import vboard_config


class Profile:
    # Piecewise-linear temperature against time, held flat after the last
    # point: [(seconds, degC), ...] with increasing seconds.
    def __init__(self, points):
        if not points:
            raise ValueError("profile needs at least one (seconds, degC) point")
        last = None
        for t, _ in points:
            if last is not None and t <= last:
                raise ValueError("profile times must increase")
            last = t
        self.points = [(int(t * 1000), c) for t, c in points]

    def at_ms(self, ms):
        pts = self.points
        if ms <= pts[0][0]:
            return pts[0][1]
        for i in range(1, len(pts)):
            t1, c1 = pts[i]
            if ms <= t1:
                t0, c0 = pts[i - 1]
                return c0 + (c1 - c0) * (ms - t0) / (t1 - t0)
        return pts[-1][1]


class Board:
    def __init__(self):
        self._levels = {}
        self._i2c = {}
        self._spi = {}
        self._adc = {}
        self._cs = {}
        self.profile = Profile([(0, 25.0)])
        self._scale = vboard_config.TIME_SCALE
        self._us = int(vboard_config.CLOCK_US)

    # -- time and temperature
    def advance_us(self, us):
        """Let us microseconds of board time pass (bus transfers, sleeps)."""
        if us > 0:
            self._us += int(us)

    def clock_us(self):
        """Unscaled board time, microseconds since the host started the board."""
        return self._us

    def clock_s(self):
        # for the host, which keeps the clock across resets (a float: no big ints over the bridge)
        return self._us / 1000000

    def clock_ms(self):
        return self.clock_ms_at(self._us)

    def clock_ms_at(self, us):
        """clock_ms() when clock_us() was us (the virtual Pico's host asks about past times)."""
        ms = int(us) // 1000
        return int(ms * self._scale) if self._scale != 1 else ms

    def set_profile(self, points):
        self.profile = points if hasattr(points, "at_ms") else Profile(points)

    def temperature_c(self):
        return self.profile.at_ms(self.clock_ms())

    # -- wiring (called from vboard_devices.setup)
    def add_i2c(self, bus, addr, device):
        self._i2c.setdefault(bus, {})[addr] = device

    def add_spi(self, bus, cs_pin, device):
        self._spi.setdefault(bus, []).append((cs_pin, device))
        self._cs[cs_pin] = device
        self._levels.setdefault(cs_pin, 1)  # chip selects idle high

    def add_adc(self, channel, source):
        self._adc[channel] = source

    def set_input(self, pin, level_or_callable):
        # A pin driven by the outside world (a data-ready line, a button).
        self._levels[pin] = level_or_callable

    # -- used by machine
    def pin_read(self, pin):
        v = self._levels.get(pin, 0)
        return v() if callable(v) else v

    def pin_write(self, pin, v):
        old = self._levels.get(pin, 0)
        self._levels[pin] = v
        dev = self._cs.get(pin)
        if dev is not None and old != v:
            hook = getattr(dev, "deselect" if v else "select", None)
            if hook:
                hook()

    def i2c_device(self, bus, addr):
        return self._i2c.get(bus, {}).get(addr)

    def i2c_scan(self, bus):
        return sorted(self._i2c.get(bus, {}))

    def spi_selected(self, bus):
        # Devices whose chip select is low now.  Two at once is a wiring or
        # driver bug; the bus reports it rather than guessing.
        sel = [d for cs, d in self._spi.get(bus, ()) if not self.pin_read(cs)]
        if len(sel) > 1:
            raise OSError(5)
        return sel[0] if sel else None

    def adc_read(self, channel):
        src = self._adc.get(channel)
        if src is None:
            return 0  # floating input reads near ground here
        v = src.read_u16() if hasattr(src, "read_u16") else src()
        return 0 if v < 0 else 65535 if v > 65535 else int(v)


board = Board()


def _wire():
    # A broken device model must not take `machine` down with it: report it
    # at boot, as a board with a dead sensor still boots.
    try:
        import vboard_devices

        vboard_devices.setup(board)
    except Exception as e:
        import sys

        print("virtual board: device set-up failed:")
        sys.print_exception(e)


_wire()
