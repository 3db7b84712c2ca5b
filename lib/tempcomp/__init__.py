"""tempcomp: temperature compensation for MEMS gyros and accelerometers.

Runs unchanged on MicroPython, CircuitPython and CPython. Modules, along the data path
sensor -> bus -> decode -> compensate -> store:

* ``bus``         one thin adapter over machine.I2C/SPI and busio.I2C/SPI
* ``fixedpoint``  integer offset/scale compensation, allocation-free per sample
"""

__version__ = "0.1.0"
