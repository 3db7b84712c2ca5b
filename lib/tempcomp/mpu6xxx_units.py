"""The MPU-6xxx offset registers as numbers: their units and their fields.

At the bottom of the family, on ``tempcomp.mpu6xxx_parts`` (its warnings), for the two modules
that compute offsets: the capture (``tempcomp.mpu6xxx_cal``) and the temperature model
(``tempcomp.mpu6xxx_tc``). A boot, which only writes saved offsets back, never loads it.

Units (RM-MPU-6000A 4.2, 4.11; AN-MPU-6000A-00 "Accelerometer and Gyroscope Offset Registers"):
gyro offset registers count 1/32.8 dps, the +-1000 dps output LSB, whatever the range; the accel
offset words count 2048 LSB/g (0.98 mg) in bits 15..1, bit 0 reserved (the part's).
"""

from tempcomp.mpu6xxx_parts import warn

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


GYRO_LSB_DPS = const(131)  # output LSB per dps at +-250 dps
ACCEL_LSB_G = const(16384)  # output LSB per g at +-2 g
GYRO_STEP = const(4)  # one gyro offset register LSB = 4 output LSB at +-250 dps
ACCEL_STEP = const(8)  # one accel offset word LSB = 8 output LSB at +-2 g


# The fields: a gyro offset is an int16 register; the accel word's bits 15..1 are a signed 15-bit
# field. A value beyond its field is clamped to the field's end, with a warning.
def clamp_gyro(axis, v):
    if -32768 <= v <= 32767:
        return v
    warn("gyro %s offset %d clamped to the int16 register" % ("xyz"[axis], v))
    return -32768 if v < 0 else 32767


def clamp_accel15(axis, t15):
    if -16384 <= t15 <= 16383:
        return t15
    warn("accel %s offset %d clamped to the 15-bit field" % ("xyz"[axis], t15 * 2))
    return -16384 if t15 < 0 else 16383
