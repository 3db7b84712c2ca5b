"""The MPU family's fault and warning messages, in words: imported when one is raised.

A message is a string object on the heap for as long as the module that holds it is loaded
(about 1.3 bytes of heap per character from ``.mpy``). The driver (``tempcomp.mpu6xxx``) and
``tempcomp.mpu6xxx_rt`` keep only the numbers of a fault and call the function named for it here,
so a boot that meets none never holds their text (1.6 KB of heap measured in the driver, about
0.4 KB in ``mpu6xxx_rt``; docs/ram.md); the store's reader does the same with
``tempcomp.store_check``. Each function returns the exception to raise, or the text of a warning
(the caller warns, so that the warning names the user's line).

The bottom of the family, beside ``tempcomp.mpu6xxx_parts`` (the part names, ``MPUError``).
"""

from tempcomp.mpu6xxx_parts import MPUError, names

# -- the driver (tempcomp.mpu6xxx) ----------------------------------------------------------


def unknown_part(address, who):
    return MPUError(
        "no known MPU-6xxx part at I2C address 0x%02x: WHO_AM_I is 0x%02x; for a clone name the part "
        "it copies, e.g. part='MPU-6500' (known: %s)" % (address, who, ", ".join(names())))


def unknown_name(part):
    return ValueError("unknown part %r; known: %s" % (part, ", ".join(names())))


def other_part(address, who, row_who, name):
    return ("part at 0x%02x answers WHO_AM_I 0x%02x, not 0x%02x: driving it with the %s layout as asked"
            % (address, who, row_who, name))


def unsteady_offsets(reads):
    return MPUError("offset registers read differently %d times in a row (bus noise? check pull-ups and "
                    "wiring); nothing written" % reads)


def read_back(reg, got, wrote):
    # got, wrote: the register pair's two bytes, high first
    return MPUError("register 0x%02x reads back 0x%02x%02x after writing 0x%02x%02x"
                    % (reg, got[0], got[1], wrote[0], wrote[1]))


def not_held(reg, held, written):
    return MPUError("offset register 0x%02x holds %d, not the %d written" % (reg, held, written))


def rollback_failed(e, bad):
    return MPUError("%s; restoring the previous offsets failed too (%s): power-cycle the part" % (e, bad))


def asleep():
    return MPUError("the part is asleep (PWR_MGMT_1.SLEEP): its temperature is stale")


def other_who_am_i(saved, who):
    return ValueError("saved offsets belong to a part with WHO_AM_I 0x%02x, this one is 0x%02x" % (saved, who))


def trim_rewritten(now, saved):
    return ("ICM-20602 accel y trim reads %d, saved factory value %d: the part changed it by itself (a known "
            "ICM-20602 fault); the saved offsets are written back, call check(every_ms=1000) from your loop "
            "to keep them" % (now, saved))


def other_factory(now, saved):
    return "factory trim %r differs from the saved %r: a different part?" % (now, saved)


def not_registers(what, v):
    if len(v) != 3:
        return ValueError("%s needs 3 values, got %r" % (what, v))
    return ValueError("%s values must be int16 register values, got %r" % (what, v))


def record_length(n):
    return ValueError("an MPU6xxx record has 10 ints, got %d" % n)


def not_one_of(what, opts, val):
    return ValueError("%s must be one of %r, got %r" % (what, opts, val))


def not_compensated():
    return ValueError("call compensate(model) first")


def bad_temp_avg(n):
    return ValueError("temp_avg must be an int from 1 to 127, got %r" % (n,))


# -- offset(T) resumed from record mpu_tcc (tempcomp.mpu6xxx_rt) -----------------------------


def tcc_malformed():
    return ValueError("mpu_tcc: not a compiled offset(T) record")


def tcc_other_model():
    return ValueError("mpu_tcc was not built from this mpu_tc model (a save cut short?): call compensate(model)")


def tcc_other_ranges(built, now):
    return ValueError("mpu_tcc was built for +-%d dps, +-%d g; the part is set to +-%d dps, +-%d g: "
                      "call compensate(model)" % (built[0], built[1], now[0], now[1]))


def tcc_other_offsets():
    return ValueError("mpu_tcc was built for other offset registers: restore() the offsets saved with it, "
                      "or call compensate(model)")
