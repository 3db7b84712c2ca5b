# The virtual Pico's PCB, run in a MicroPython VM beside the emulated RP2040 (world.mjs).
#
# The board, the parts and their world are the virtual board's own (tools/vboard/vm: vboard.py,
# vboard_devices.py, vboard_sensors.py, and the register models in tools/sim): one world, two
# boards. This module only turns the RP2040 peripherals' byte-level traffic into the
# transactions of vboard.py's device interface, and sets the board's clock from the RP2040's
# (every call passes its time since the RP2040 started, in seconds as a float: the bridge carries
# 32-bit ints; temperature and motion follow the emulated CPU).
import binascii

import vboard
import vboard_sensors

board = vboard.board
_base_us = board.clock_us()  # the world's time when the RP2040 started (it goes on over resets)


def _at(s):
    d = _base_us + int(s * 1000000 + 0.5) - board.clock_us()
    if d > 0:
        board.advance_us(d)


def reset(s):
    # the RP2040 restarted (machine.reset(), a watchdog): its clock starts from 0 again, the
    # world's does not
    global _base_us
    _base_us = board.clock_us() - int(s * 1000000 + 0.5)


def clock_s():
    return board.clock_us() / 1000000


def i2c_present(bus, addr):
    return board.i2c_device(bus, addr) is not None


def i2c_write(bus, addr, hexdata, s):
    _at(s)
    board.i2c_device(bus, addr).write(binascii.unhexlify(hexdata))


def i2c_read(bus, addr, n, s):
    _at(s)
    buf = bytearray(n)
    board.i2c_device(bus, addr).read_into(buf)
    return binascii.hexlify(buf).decode()


def cs_pins():
    return ",".join(str(p) for p in sorted(board._cs))


def pin(p, level, s):
    _at(s)
    board.pin_write(p, level)


_w = bytearray(1)
_r = bytearray(1)


def spi_exchange(bus, byte, s):
    _at(s)
    dev = board.spi_selected(bus)
    if dev is None:
        return 0xFF  # nobody drives MISO: the pull-up
    _w[0] = byte
    dev.transfer(_w, _r)
    return _r[0]


def adc(channel, s):
    # ADC0..ADC3 are GP26..GP29 (RP2040 datasheet 4.9)
    _at(s)
    return board.adc_read(26 + channel)


def world(src, s):
    # a line from the test rig on UART0 (pico_rig.py): an expression on vboard_sensors.world
    _at(s)
    try:
        return repr(eval(src, {"world": vboard_sensors.world, "board": board}))
    except Exception as e:  # the rig answers errors too, it never stops the world
        return "!%s: %s" % (type(e).__name__, e)
