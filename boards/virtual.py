"""The virtual board (tools/vboard): a MicroPython VM on the host.

Pins and buses as wired in tools/vboard/vm/vboard_devices.py: the MPU-6500
on I2C0, the MLX90609 on SPI0 with its chip select on GP17, and the analog
gyro's rate and temperature outputs on ADC pins 26 and 27 (RP2040 numbering,
so this module also reads naturally next to the Pico's).
"""

from machine import ADC, I2C, SPI, Pin

NAME = "virtual"

I2C_ID = 0
I2C_SDA = 4
I2C_SCL = 5
I2C_FREQ = 400_000
MPU6500_ADDR = 0x68

SPI_ID = 0
SPI_SCK = 18
SPI_MOSI = 19
SPI_MISO = 16
SPI_BAUD = 1_000_000
MLX90609_CS = 17

ADC_RATE = 26
ADC_TEMP = 27
ADC_PINS = {"rate": ADC_RATE, "temp": ADC_TEMP}
ADC_VREF_MV = 3300  # the simulated RP2040-style ADC: read_u16 full scale is 3.3 V
ADC_DIVIDER = 2.0  # the 5 V analog gyro reaches the ADC through a 1:2 divider
ADXRS_MV_PER_DPS = 6.0  # the analog gyro's nominal scale factor (ADXRS620: 6 mV per deg/s)


def i2c():
    return I2C(I2C_ID, sda=Pin(I2C_SDA), scl=Pin(I2C_SCL), freq=I2C_FREQ)


def spi():
    # MLX90609: SPI mode 3, at most 1 MHz (datasheet p.9)
    return SPI(SPI_ID, baudrate=SPI_BAUD, polarity=1, phase=1, sck=Pin(SPI_SCK), mosi=Pin(SPI_MOSI),
               miso=Pin(SPI_MISO))


def mlx_cs():
    return Pin(MLX90609_CS, Pin.OUT, value=1)


def adc(name):
    return ADC(Pin(ADC_PINS[name]))


def setup():
    """Build the bus objects; returns a dict of them by role."""
    i2c = I2C(I2C_ID, sda=Pin(I2C_SDA), scl=Pin(I2C_SCL), freq=I2C_FREQ)
    spi = SPI(
        SPI_ID,
        baudrate=SPI_BAUD,
        polarity=0,
        phase=0,
        sck=Pin(SPI_SCK),
        mosi=Pin(SPI_MOSI),
        miso=Pin(SPI_MISO),
    )
    cs = Pin(MLX90609_CS, Pin.OUT, value=1)
    return {
        "i2c": i2c,
        "spi": spi,
        "mlx_cs": cs,
        "adc_rate": ADC(Pin(ADC_RATE)),
        "adc_temp": ADC(Pin(ADC_TEMP)),
    }
