"""The facts of the InvenSense MPU-6050/6500 family that every layer of its code shares.

The bottom of the family (README "Layers"): it imports no other tempcomp module. Above it,
each importing only what lies below: ``tempcomp.mpu6xxx_rt`` (offset(T) resumed from record
``mpu_tcc``), ``tempcomp.mpu6xxx_cal`` (the FIFO capture at rest) and ``tempcomp.mpu6xxx_tc``
(``BiasModel``: offset(T) fitted, its fixed-point set-up); ``tempcomp.mpu6xxx`` (the driver)
on top, which hands them what they need (its bus device, this table's row, the offsets and
ranges it read) and applies what they compute.

Here: the part table, one row per part; detection is by WHO_AM_I (register 0x75), and a clone
that answers another id is driven by naming the part whose layout it copies. Sources:
sensor-facts.md (InvenSense section), RM-MPU-6000A, RM-MPU-9250 sec. 4, the Linux inv_mpu6050
driver's part table (FIFO sizes; the ICM-20602 always writes the temperature into its FIFO
packets). The datasheet conversions of a row (temperature, zero-rate tolerance), the family's
error and its warnings: what every boot needs. The offset registers' units and fields (what a
capture and a model compute in) are in ``tempcomp.mpu6xxx_units``, beside this one.

Usage::

    from tempcomp.mpu6xxx_parts import by_name, by_who_am_i, NAME
    row = by_who_am_i(0x70)
    row[NAME]     # 'MPU-6500'
"""

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


try:
    from warnings import warn as _warn  # pyright: ignore[reportMissingImports]
except ImportError:
    _warn = None


def warn(msg):
    """The family's warnings: warnings.warn on CPython (naming the caller's line), printed on the
    boards."""
    if _warn is None:
        print("tempcomp.mpu6xxx warning:", msg)
    else:
        _warn(msg, stacklevel=2)


class MPUError(OSError):
    """A bus fault, a read-back mismatch or an unusable capture on an MPU-6xxx part."""

    __module__ = "tempcomp.mpu6xxx"  # its public home: what users catch and tracebacks name


# The one register both the driver and the capture read (RM-MPU-6000A 4.18); each module keeps
# the registers only it uses as its own const()s
TEMP_OUT_H = const(0x41)

# column indices of a row
NAME = const(0)
WHO_AM_I = const(1)
ACCEL_OFFS = const(2)  # register of the X accel offset high byte
ACCEL_STRIDE = const(3)  # Y and Z follow at this stride
FIFO_SIZE = const(4)  # bytes
PACKET = const(5)  # FIFO bytes per sample with accel + gyro enabled
GYRO_AT = const(6)  # offset of gyro X inside a packet (accel X is at 0)
FIFO_EN_BITS = const(7)  # FIFO_EN value that enables accel + all gyro axes
TEMP_SENS = const(8)  # temperature sensitivity, hundredths of LSB per degC
TEMP_ZERO = const(9)  # temperature at raw 0, hundredths of degC
ACCEL_CONFIG2 = const(10)  # 1 if register 0x1D is ACCEL_CONFIG2 (accel DLPF)
ZRO_DPS = const(11)  # datasheet initial zero-rate output tolerance at 25 degC, +- deg/s
ZRO_SPAN_DPS = const(12)  # datasheet ZRO variation over -40..85 degC, +- deg/s

# T = raw / 340 + 36.53 (MPU-6050 PS 6.4), raw / 333.87 + 21 (MPU-6500/9250 PS),
# raw / 326.8 + 25 (ICM-20602/20608, Linux INV_ICM20608_TEMP_SCALE/OFFSET).
# Zero-rate output (gyro bias) the part may have at rest: a larger one means it was turning.
# [V] PS-MPU-6000A-00 rev 3.4 sec. 6.1: initial ZRO tolerance +-20 deg/s, variation over
# -40..85 degC +-20 deg/s (typical column). [V] PS-MPU-9250A-01 rev 1.0 sec. 3.1: +-5 and +-30.
# [U] MPU-6500, ICM-20608, ICM-20602: taken as the MPU-9250's (the same gyro generation; the
# ICM-20602 is specified tighter, about +-1 deg/s, so this errs towards accepting).
PARTS = (
    ("MPU-6050", 0x68, 0x06, 2, 1024, 12, 6, 0x78, 34000, 3653, 0, 20, 20),
    ("MPU-9150", 0x68, 0x06, 2, 1024, 12, 6, 0x78, 34000, 3653, 0, 20, 20),
    ("MPU-6500", 0x70, 0x77, 3, 512, 12, 6, 0x78, 33387, 2100, 1, 5, 30),
    ("MPU-9250", 0x71, 0x77, 3, 512, 12, 6, 0x78, 33387, 2100, 1, 5, 30),
    ("MPU-9255", 0x73, 0x77, 3, 512, 12, 6, 0x78, 33387, 2100, 1, 5, 30),
    ("ICM-20608", 0xAF, 0x77, 3, 512, 12, 6, 0x78, 32680, 2500, 1, 5, 30),
    # FIFO_EN bit 4 enables all gyro axes, bit 3 the accel; TEMP_OUT rides along (14 bytes)
    ("ICM-20602", 0x12, 0x77, 3, 1008, 14, 8, 0x18, 32680, 2500, 1, 5, 30),
)


def by_who_am_i(who):
    """The first row whose WHO_AM_I is ``who`` (MPU-6050 for 0x68), or None."""
    for row in PARTS:
        if row[WHO_AM_I] == who:
            return row
    return None


def by_name(name):
    """The row of part ``name`` (case and dashes ignored: "mpu6500" works), or None."""
    key = name.upper().replace("-", "").replace("_", "")
    for row in PARTS:
        if row[NAME].replace("-", "") == key:
            return row
    return None


def names():
    return tuple(row[NAME] for row in PARTS)


def celsius100(row, raw):
    """TEMP_OUT reading raw of part ``row`` in hundredths of a degC."""
    sens = row[TEMP_SENS]
    # |2 * raw * 10000| <= 6.6e8 < 2**30
    return (raw * 20000 + sens) // (2 * sens) + row[TEMP_ZERO]


def zro_limit(row, t_c100):
    """The gyro bias (deg/s) part ``row`` may have at rest at t_c100 (hundredths of a degC): its
    datasheet initial tolerance plus the variation over temperature away from 25 degC."""
    dt = abs(t_c100 - 2500) / 100.0
    return row[ZRO_DPS] + row[ZRO_SPAN_DPS] * dt / 60.0  # the span covers 25 -> -40/+85 degC
