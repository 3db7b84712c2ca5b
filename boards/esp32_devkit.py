"""ESP32 DevKitC (ESP32-WROOM-32), MicroPython ``machine``.

Wiring: MPU-6500 on I2C0 (GPIO21 SDA, GPIO22 SCL); MLX90609 on SPI2/HSPI (GPIO14 SCK,
GPIO13 MOSI, GPIO12 MISO, GPIO15 CS); analog gyro rate on GPIO36 (ADC1_CH0), its
temperature output on GPIO39 (ADC1_CH3). ADC1 only: ADC2 is unusable while Wi-Fi runs.
"""

from machine import ADC, I2C, SPI, Pin

NAME = "esp32_devkit"
# read_u16 is calibrated against the eFuse reference with 11 dB attenuation: about 0..3.1 V
ADC_VREF_MV = 3100
I2C_ID = 0
I2C_SDA = 21
I2C_SCL = 22
I2C_FREQ = 400000
SPI_ID = 2
SPI_SCK = 14
SPI_MOSI = 13
SPI_MISO = 12
MLX_CS = 15
ADC_PINS = {"rate": 36, "temp": 39}


def i2c():
    return I2C(I2C_ID, sda=Pin(I2C_SDA), scl=Pin(I2C_SCL), freq=I2C_FREQ)


def spi():
    return SPI(SPI_ID, baudrate=1000000, polarity=1, phase=1, sck=Pin(SPI_SCK), mosi=Pin(SPI_MOSI), miso=Pin(SPI_MISO))


def mlx_cs():
    return Pin(MLX_CS, Pin.OUT, value=1)


def adc(name):
    a = ADC(Pin(ADC_PINS[name]))
    a.atten(ADC.ATTN_11DB)
    return a
