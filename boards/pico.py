"""Raspberry Pi Pico / Pico W (RP2040), MicroPython ``machine``.

Wiring: MPU-6500 on I2C0 (GP4 SDA, GP5 SCL); MLX90609 on SPI0 (GP18 SCK, GP19 MOSI,
GP16 MISO, GP17 CS); analog gyro rate on GP26/ADC0 and its temperature output on GP27/ADC1,
each through a 1:2 divider (ADC_DIVIDER: change it to match yours).
"""

from machine import ADC, I2C, SPI, Pin

NAME = "pico"
ADC_VREF_MV = 3300  # RP2040 ADC reference is the 3.3 V rail (datasheet 4.9.1)
I2C_ID = 0
I2C_SDA = 4
I2C_SCL = 5
I2C_FREQ = 400000
SPI_ID = 0
SPI_SCK = 18
SPI_MOSI = 19
SPI_MISO = 16
MLX_CS = 17
ADC_PINS = {"rate": 26, "temp": 27}
ADC_DIVIDER = 2.0  # a 5 V analog gyro reaches the 3.3 V ADC through a 1:2 divider (as on the virtual Pico)
ADXRS_MV_PER_DPS = 6.0  # the analog gyro's nominal scale factor (ADXRS620: 6 mV per deg/s)


def i2c():
    return I2C(I2C_ID, sda=Pin(I2C_SDA), scl=Pin(I2C_SCL), freq=I2C_FREQ)


def spi():
    # MLX90609: SPI mode 3, at most 1 MHz (datasheet p.9)
    return SPI(SPI_ID, baudrate=1000000, polarity=1, phase=1, sck=Pin(SPI_SCK), mosi=Pin(SPI_MOSI), miso=Pin(SPI_MISO))


def mlx_cs():
    return Pin(MLX_CS, Pin.OUT, value=1)


def adc(name):
    return ADC(Pin(ADC_PINS[name]))
