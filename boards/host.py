"""The host computer through Adafruit Blinka (``board``/``busio`` on CPython).

On a PC with a USB bridge Blinka supports (FT232H, MCP2221, Pico u2if) these are the real
buses. With BLINKA_OS_AGNOSTIC=1 and no bridge, tempcomp's tests put simulated parts behind
these same busio classes (tools/sim/blinka.py).
"""

import board
import busio
import digitalio

NAME = "host"
ADC_VREF_MV = 3300
ADC_PINS = {"rate": "A0", "temp": "A1"}


def i2c():
    return busio.I2C(board.SCL, board.SDA)


def spi():
    return busio.SPI(board.SCK, board.MOSI, board.MISO)


def mlx_cs():
    return digitalio.DigitalInOut(board.CS)


def adc(name):
    import analogio

    return analogio.AnalogIn(getattr(board, ADC_PINS[name]))
