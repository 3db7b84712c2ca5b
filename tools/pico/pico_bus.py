# The virtual Pico's PCB, run in a MicroPython VM beside the emulated RP2040 (world.mjs).
#
# The board, the parts and their world are the virtual board's own (tools/vboard/vm: vboard.py,
# vboard_devices.py, vboard_sensors.py, and the register models in tools/sim): one world, two
# boards. This module only turns the RP2040 peripherals' byte-level traffic into the
# transactions of vboard.py's device interface, and sets the board's clock from the RP2040's
# (every call passes its time since the RP2040 started, in seconds as a float: the bridge carries
# 32-bit ints; temperature and motion follow the emulated CPU).
import binascii
import json

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


def adc_divider():
    # the analog gyro's divider on this PCB (boards/pico.py must say the same: boot.mjs)
    return vboard_sensors.ADXRS_DIVIDER


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


def _state(s):
    w = vboard_sensors.world
    return {"rp2040_ms": s * 1000, "world_ms": board.clock_ms(), "temperature_c": w.temperature_c(),
            "face": w.face, "rate": list(w.rate)}


def control(req, s):
    # A request of the host's world control (control.mjs checked its verb and numbers), as JSON
    # text, done at the RP2040's time s; the answer as JSON text. Fixed verbs on the world's
    # own methods, nothing evaluated.
    _at(s)
    w = vboard_sensors.world
    try:
        r = json.loads(req)
        cmd = r["cmd"]
        if cmd == "place":
            w.place(r["face"])
        elif cmd == "spin":
            w.spin(r["rate"])
        elif cmd == "bump":
            w.bump(tuple(r.get("rate", (60.0, -45.0, 80.0))), r["after_ms"], r["for_ms"])
        elif cmd == "heat":
            w.heat([(p[0], p[1]) for p in r["points"]])
        elif cmd == "temperature":
            # the programme in force now, at those RP2040 times (ms since it started)
            temps = [board.profile.at_ms(board.clock_ms_at(_base_us + int(ms * 1000 + 0.5))) for ms in r["at_ms"]]
            return json.dumps({"ok": True, "temperature_c": temps})
        elif cmd != "state":
            raise ValueError("unknown cmd %r" % (cmd,))
    except Exception as e:  # a bad request is answered, it never stops the world
        return json.dumps({"ok": False, "error": "%s: %s" % (type(e).__name__, e)})
    return json.dumps({"ok": True, "state": _state(s)})
