"""Adafruit Feather RP2040, CircuitPython ``board``/``busio``/``digitalio``/``analogio``.

Wiring: MPU-6500 on the STEMMA QT I2C (board.SDA/board.SCL); MLX90609 on board.SCK/MOSI/MISO
with CS on D5; analog gyro rate on A0 and its temperature output on A1.
Returned objects follow CircuitPython's API; tempcomp.bus adapts them.
"""

import analogio
import board
import busio
import digitalio

NAME = "feather_rp2040"
ADC_VREF_MV = 3300  # AnalogIn.reference_voltage is 3.3 on this board
ADC_PINS = {"rate": "A0", "temp": "A1"}


def i2c():
    return busio.I2C(board.SCL, board.SDA, frequency=400000)


def spi():
    return busio.SPI(board.SCK, MOSI=board.MOSI, MISO=board.MISO)


def mlx_cs():
    return digitalio.DigitalInOut(board.D5)


def adc(name):
    return analogio.AnalogIn(getattr(board, ADC_PINS[name]))
