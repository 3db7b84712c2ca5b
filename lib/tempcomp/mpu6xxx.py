"""InvenSense MPU-6050/6500/9250 family: bias capture and hardware offset registers (I2C).

The part subtracts its offset registers before the data registers, the FIFO and the DMP see a
sample, so a calibrated part reads zero rate and exactly 1 g at rest with no work per sample.
The registers are volatile: save what ``calibrate()`` returns and re-apply it at every boot.

Usage (the board lying still on any face, any side up)::

    from machine import I2C, Pin
    from tempcomp.mpu6xxx import MPU6xxx
    imu = MPU6xxx(I2C(0, scl=Pin(5), sda=Pin(4)))   # detects the part by WHO_AM_I
    gyro, accel = imu.calibrate()    # captures ~1 s, writes and verifies the offsets
    imu.offsets()                    # what the part now holds: the same two tuples
    imu.apply(gyro, accel)           # at boot: write saved offsets (verified)
    imu.written                      # the six words last written here (None before any)

Units: gyro offset registers count 1/32.8 dps (the +-1000 dps unit) whatever the range; accel
offset registers are 16-bit words in 2048 LSB/g (bits 15..1, 0.98 mg a step) whose bit 0 is
reserved and always kept as the part holds it. Temperatures are hundredths of a degC.

Errors: ``OSError`` (``MPUError``) for bus faults, a part that moved, turned (gravity moving,
or a gyro bias beyond its datasheet zero-rate range) or is not lying on a face during capture,
reads that are implausible or do not agree when repeated, or a read-back that differs from
what was written; ``ValueError`` for bad arguments. A failure while writing offsets restores
the previous ones before raising, and the user's sensor configuration is restored after every
capture. ``check(every_ms=1000)`` in a loop keeps the offsets on parts that change their trim
by themselves (ICM-20602).

Heap: this module holds what every boot needs (restore, check, compensated reads); the FIFO
capture behind ``calibrate()``/``bias_point()`` lives in ``tempcomp.mpu6xxx_cal`` and is loaded
by the first capture only (docs/ram.md).

The top of the family (README "Layers"): it stands on ``tempcomp.bus`` and
``tempcomp.mpu6xxx_parts``, and hands ``tempcomp.mpu6xxx_cal`` (the capture),
``tempcomp.mpu6xxx_rt`` (offset(T) resumed from a record) and a ``BiasModel``
(``tempcomp.mpu6xxx_tc``) what they need - its bus device, its part's row, the offsets and
ranges it read - then applies what they compute. None of them calls back into it.
"""

import time as _time

from tempcomp.bus import I2CDevice
from tempcomp.mpu6xxx_parts import (
    ACCEL_OFFS,
    ACCEL_STRIDE,
    NAME,
    TEMP_OUT_H,
    TEMP_SENS,
    TEMP_ZERO,
    WHO_AM_I,
    MPUError,  # noqa: F401  (re-exported: tempcomp.mpu6xxx.MPUError is what users catch)
    by_name,
    by_who_am_i,
    celsius100,
    warn,
    zro_limit,
)

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


# a millisecond clock for check(every_ms=), bound once: MicroPython's ticks, CircuitPython's
# supervisor ticks (they wrap at 2**29), else the monotonic clock (CPython). The fallbacks are
# defined only where they are used: a MicroPython board never holds them.
try:
    from time import ticks_diff as _ticks_diff  # pyright: ignore[reportAssignmentType]
    from time import ticks_ms as _ticks_ms
except ImportError:
    try:
        from supervisor import ticks_ms as _ticks_ms  # pyright: ignore[reportMissingImports]

        def _ticks_diff(a, b):
            return ((a - b + 0x10000000) & 0x1FFFFFFF) - 0x10000000

    except ImportError:

        def _ticks_ms():
            return int(_time.monotonic() * 1000)  # pyright: ignore[reportAttributeAccessIssue]

        def _ticks_diff(a, b):
            return a - b


# Register map (RM-MPU-6000A / RM-MPU-9250): the registers only the driver uses; the capture's
# are in mpu6xxx_cal, TEMP_OUT_H (both read it) in mpu6xxx_parts
_XG_OFFS_USRH = const(0x13)  # gyro X/Y/Z offsets at 0x13, 0x15, 0x17 (high byte first)
_GYRO_CONFIG = const(0x1B)
_ACCEL_CONFIG = const(0x1C)
_ACCEL_XOUT_H = const(0x3B)  # 14 bytes: accel x y z, temperature, gyro x y z
_PWR_MGMT_1 = const(0x6B)
_WHO_AM_I = const(0x75)

_RETRIES = const(3)
_T_MASK = const(-8)  # per-sample compensation steps of 8 LSB (~0.024 degC): t & _T_MASK == t - t % 8
# read_compensated's temperature block in one int: (sum of readings) * 128 + readings still to
# come, so temp_avg < 128; |sum| < 127 * 2**15 < 2**22, so |state| < 2**29 stays a small int
_T_CNT = const(127)
_READS = const(4)  # offsets are re-read until two reads agree, this many times at most


def _s16(hi, lo):
    v = hi << 8 | lo
    if v & 0x8000:
        v -= 0x10000
    return v


class MPU6xxx:
    """One MPU-6050/6500/9250-family part on an I2C bus (machine.I2C or busio.I2C)."""

    def __init__(self, i2c, address=0x68, part=None):
        self._dev = I2CDevice(i2c, address)
        self.address = address
        who = self._dev.read_u8(_WHO_AM_I)
        self.who_am_i = who
        if part is None:
            row = by_who_am_i(who)
            if row is None:
                from tempcomp.mpu6xxx_faults import unknown_part

                raise unknown_part(address, who)
        else:
            row = by_name(part)
            if row is None:
                from tempcomp.mpu6xxx_faults import unknown_name

                raise unknown_name(part)
            if row[WHO_AM_I] != who:
                from tempcomp.mpu6xxx_faults import other_part

                warn(other_part(address, who, row[WHO_AM_I], row[NAME]))
        self.part = row[NAME]
        self._row = row
        a0 = row[ACCEL_OFFS]
        st = row[ACCEL_STRIDE]
        self._oregs = (_XG_OFFS_USRH, _XG_OFFS_USRH + 2, _XG_OFFS_USRH + 4, a0, a0 + st, a0 + 2 * st)
        self._b2 = bytearray(2)
        self._w2 = bytearray(2)
        self._w1 = bytearray(1)
        self._d14 = bytearray(14)
        self._capture = None  # tempcomp.mpu6xxx_cal.Capture, made by the first capture
        self.temp_avg = 16  # read_compensated: temperature readings averaged per update
        self._comp_set(None, None)
        self._tsens = row[TEMP_SENS]  # read_compensated's temperature, inline
        self._tsens2 = 2 * row[TEMP_SENS]
        self._tzero = row[TEMP_ZERO]
        self._follow_t = None
        self.written = None  # the six offset words last written here and verified (check() keeps them)
        self._checked = None  # ticks_ms of the last check(every_ms=...)
        self.trim_changes = 0  # offset registers the part changed by itself, found by check()
        # the accel offsets hold the factory trim after power-on: read it once, here
        self.factory = self.offsets()[1]

    # ---- offsets ----------------------------------------------------------------------------
    def _read_offsets_once(self, out):
        b = self._b2
        for i in range(6):
            self._dev.read_into(self._oregs[i], b)
            out[i] = _s16(b[0], b[1])

    def _read_offsets(self):
        # Every offset written is computed from, or checked against, what is read here: read
        # until two reads in a row agree, so one corrupted read cannot become the base.
        a = [0] * 6
        b = [0] * 6
        self._read_offsets_once(a)
        for _ in range(_READS):
            self._read_offsets_once(b)
            if a == b:
                return a
            a, b = b, a
        from tempcomp.mpu6xxx_faults import unsteady_offsets

        raise unsteady_offsets(_READS + 1)

    def offsets(self):
        """((gx, gy, gz), (ax, ay, az)) the part holds: signed register values."""
        o = self._read_offsets()
        return (tuple(o[:3]), tuple(o[3:]))

    def _write_pair(self, reg, word):
        w = self._w2
        w[0] = (word >> 8) & 0xFF
        w[1] = word & 0xFF
        self._dev.write(reg, w)
        b = self._b2
        self._dev.read_into(reg, b)
        if b[0] != w[0] or b[1] != w[1]:
            self._dev.read_into(reg, b)  # a corrupted read-back is not a failed write: ask again
        if b[0] != w[0] or b[1] != w[1]:
            from tempcomp.mpu6xxx_faults import read_back

            raise read_back(reg, b, w)

    def _write_offsets(self, words):
        # words: gyro x y z, accel x y z (signed). All or nothing: on any fault the registers
        # written so far get their previous values back before the error propagates.
        old = self._read_offsets()
        done = 0
        try:
            for i in range(6):
                if words[i] != old[i]:
                    done = i + 1  # counted before writing: a write may fail half done
                    self._write_pair(self._oregs[i], words[i])
            now = self._read_offsets()  # clones that spill into the next register show here
            for i in range(6):
                if now[i] != words[i]:
                    done = 6
                    from tempcomp.mpu6xxx_faults import not_held

                    raise not_held(self._oregs[i], now[i], words[i])
        except BaseException as e:
            bad = self._rollback(old, done)
            if bad is not None:
                from tempcomp.mpu6xxx_faults import rollback_failed

                raise rollback_failed(e, bad)
            raise

    def _rollback(self, old, upto):
        for i in range(upto):
            err = None
            for _ in range(_RETRIES):
                try:
                    self._write_pair(self._oregs[i], old[i])
                    err = None
                    break
                except OSError as e:
                    err = e
            if err is not None:
                return err
        return None

    def apply(self, gyro_regs, accel_regs):
        """Write saved offsets (register values), verified; accel bit 0 kept as the part has it."""
        g = _check3("gyro_regs", gyro_regs)
        a = _check3("accel_regs", accel_regs)
        cur = self._read_offsets()
        words = [g[0], g[1], g[2], 0, 0, 0]
        for k in range(3):
            words[3 + k] = (a[k] & ~1) | (cur[3 + k] & 1)  # bit 0 is reserved: keep the part's
        self._write_offsets(words)
        self.written = words
        return (tuple(words[:3]), tuple(words[3:]))

    def check(self, every_ms=None):
        """Re-write offsets the part changed by itself (ICM-20602); return how many it had changed.

        Compares with what was last written, or with the factory trim read at start-up if
        nothing was written yet. With every_ms, call it from your loop as often as you like:
        it reads the part only when every_ms have passed since its last check (else returns 0).
        """
        if every_ms is not None:
            now = _ticks_ms()
            last = self._checked
            if last is not None and _ticks_diff(now, last) < every_ms:
                return 0
            self._checked = now
        cur = self._read_offsets()
        want = self.written
        if want is None:
            want = cur[:3] + list(self.factory)
        n = 0
        for i in range(6):
            if cur[i] != want[i]:
                n += 1
        if n:
            self._write_offsets(want)
            self.trim_changes += n
        return n

    # ---- capture ----------------------------------------------------------------------------
    def _write_u8(self, reg, v):
        self._w1[0] = v
        self._dev.write(reg, self._w1)

    def zro_limit_dps(self, t_raw=None):
        """The gyro bias (deg/s) this part may have at rest at TEMP_OUT reading t_raw (default:
        read now, the part awake): its datasheet initial tolerance plus the variation over
        temperature away from 25 degC (mpu6xxx_parts ZRO_DPS, ZRO_SPAN_DPS)."""
        return zro_limit(self._row, self.temp_c100(t_raw))

    def _cal(self):
        # The capture machinery (FIFO buffers, sums, checks) is loaded on the first capture:
        # a board that only restores offsets at boot never has it on its heap (docs/ram.md).
        c = self._capture
        if c is None:
            from tempcomp.mpu6xxx_cal import Capture

            c = self._capture = Capture(self._dev, self._row)
        return c

    def _captured(self, packets, settle_ms):
        # -> (capture, temperature, offsets held). The offsets must not change during the capture
        # (an ICM-20602 rewriting its trim mid-capture would mix two biases).
        c = self._cal()
        cur = self._read_offsets()
        t = c.capture(packets, settle_ms)
        now = self._read_offsets()
        if now != cur:
            self.trim_changes += 1
            raise c.trim_changed(cur, now)
        return c, t, cur

    def calibrate(self, packets=1000, settle_ms=50, gyro_spread_dps=5, accel_spread_mg=150, max_tilt_mg=150,
                  max_bias_dps=None, max_turn_dps=1):
        """Capture ``packets`` samples at rest (1 kHz), write and verify the offsets.

        Lay the part still on any face (up or down). Returns ((gx, gy, gz), (ax, ay, az))
        register values as ``offsets()`` reads them. Raises MPUError if it moved (spread over
        the limits), turned (gravity moved by more than max_turn_dps, or a gyro bias beyond the
        part's datasheet range, ``zro_limit_dps()``, or max_bias_dps), is not lying on a face,
        a read was implausible, or the bus failed: the previous offsets and the sensor
        configuration are then left in place. (Code in tempcomp.mpu6xxx_cal, loaded now.)
        """
        c, t, cur = self._captured(packets, settle_ms)
        words = c.calibrate(cur, self.factory, t, gyro_spread_dps, accel_spread_mg, max_tilt_mg, max_bias_dps,
                            max_turn_dps)
        self._write_offsets(words)
        self.written = words
        return (tuple(words[:3]), tuple(words[3:]))

    def bias_point(self, packets=1000, settle_ms=50, gyro_spread_dps=5, accel_spread_mg=150, max_tilt_mg=150,
                   max_bias_dps=None, max_turn_dps=1):
        """Capture at rest at the present temperature; write nothing.

        Returns (t_raw, (gx, gy, gz), (ax, ay, az)): the raw temperature reading and, as floats,
        the register values that would zero the bias now (gyro register LSB, accel word LSB).
        Collect points at several temperatures for ``tempcomp.mpu6xxx_tc.BiasModel``. The
        capture is checked as calibrate() checks it.
        """
        c, t, cur = self._captured(packets, settle_ms)
        return c.bias_point(cur, self.factory, t, gyro_spread_dps, accel_spread_mg, max_tilt_mg, max_bias_dps,
                            max_turn_dps)

    # ---- data ----------------------------------------------------------------------------
    def temp_raw(self):
        """TEMP_OUT as a signed integer (the reading offset(T) polynomials use)."""
        b = self._b2
        self._dev.read_into(TEMP_OUT_H, b)
        return _s16(b[0], b[1])

    def temp_c100(self, raw=None):
        """Temperature in hundredths of a degC (allocation-free when read from the part)."""
        if raw is None:
            raw = self.temp_raw()
        return celsius100(self._row, raw)

    def read_raw(self, out):
        """Data registers into out[0..6]: accel x y z, temperature, gyro x y z (raw codes)."""
        b = self._d14
        self._dev.read_into(_ACCEL_XOUT_H, b)
        i = 0
        while i < 7:
            v = b[2 * i] << 8 | b[2 * i + 1]
            if v & 0x8000:
                v -= 0x10000
            out[i] = v
            i += 1

    def ranges(self):
        """(gyro full scale dps, accel full scale g) as configured in the part."""
        d = self._dev
        gfs = (d.read_u8(_GYRO_CONFIG) >> 3) & 3
        afs = (d.read_u8(_ACCEL_CONFIG) >> 3) & 3
        return (250 << gfs, 2 << afs)

    def set_ranges(self, gyro_dps=None, accel_g=None):
        """Select full-scale ranges: gyro 250/500/1000/2000 dps, accel 2/4/8/16 g."""
        for val, opts, reg, what in (
            (gyro_dps, (250, 500, 1000, 2000), _GYRO_CONFIG, "gyro_dps"),
            (accel_g, (2, 4, 8, 16), _ACCEL_CONFIG, "accel_g"),
        ):
            if val is None:
                continue
            if val not in opts:
                from tempcomp.mpu6xxx_faults import not_one_of

                raise not_one_of(what, opts, val)
            r = self._dev.read_u8(reg)
            self._write_u8(reg, (r & ~0x18) | opts.index(val) << 3)

    # ---- temperature-dependent bias ---------------------------------------------------------
    def compensate(self, model, check=None):
        """Software offset(T): set up read_compensated() for the present ranges and offsets.

        ``model`` is a ``tempcomp.mpu6xxx_tc.BiasModel``: the offsets the part holds now are
        taken as the base; keep them (and the ranges) unchanged while using read_compensated().
        Or ``model`` is the record ``mpu_tcc`` (``tempcomp.mpu6xxx_tc.compiled``), the same
        set-up computed at calibration, and ``check`` the ``mpu_tc`` record it was built from:
        a boot then loads no fixed-point set-up code (``tempcomp.mpu6xxx_rt``, docs/ram.md).
        """
        ranges = self.ranges()
        offs = self._read_offsets()
        if hasattr(model, "compensators"):
            ca, cg = model.compensators(ranges, offs)  # the model's fixed-point set-up
        else:
            # imported here: a board that never compensates never loads it
            from tempcomp.mpu6xxx_rt import resume

            ca, cg = resume(model, check, ranges, offs)
        self._comp_set(ca, cg)

    def compensating(self):
        """True once compensate() has set up read_compensated() (software offset(T))."""
        return self._cg is not None

    def _comp_set(self, ca, cg):
        # the Compensators read_compensated() uses; its temperature block starts again, so the
        # first reading after compensate() is applied at once
        self._ca = ca
        self._cg = cg
        self._tq = None
        self._tdiv = 1
        self._tp = 1  # sum 0, one reading to come

    def read_compensated(self, out):
        """out[0..2] accel mg, out[3..5] gyro mdps, out[6] degC/100; zero allocation.

        The compensation's temperature is the mean of each block of ``temp_avg`` readings
        (default 16; 1 to 127), applied from the sample that completes the block; the first
        reading after compensate() is applied at once. out[6] is this sample's own reading.
        """
        ca = self._ca
        cg = self._cg
        if ca is None or cg is None:
            from tempcomp.mpu6xxx_faults import not_compensated

            raise not_compensated()
        b = self._d14
        self._dev.read_into(_ACCEL_XOUT_H, b)
        t = ((b[6] << 8 | b[7]) ^ 0x8000) - 0x8000
        p = self._tp + (t << 7) - 1
        if p & _T_CNT:
            self._tp = p
        else:
            # a block is complete. The die temperature moves far slower than samples come, and
            # one TEMP_OUT reading is noisy (docs/mpu6xxx.md: a new 8-LSB step on most samples
            # of a real log): the block mean is quieter, and update() runs at most once a block
            tq = ((p >> 7) // self._tdiv) & _T_MASK
            if tq != self._tq:
                ca.update(tq)
                cg.update(tq)
                self._tq = tq
            n = self.temp_avg
            if n is not self._tdiv:
                # 'is': equal ints below 128 are one object (MicroPython: immediate; CPython:
                # cached), so only a new value, a float or a bool is checked here, once
                if type(n) is not int or not 0 < n <= _T_CNT:
                    from tempcomp.mpu6xxx_faults import bad_temp_avg

                    raise bad_temp_avg(n)
                self._tdiv = n
            self._tp = n
        # both Compensators' 3-axis numbers (fixedpoint's burst path: gain limbs, offset term
        # with the rounding half, K = 15, S), unrolled as in Compensator._be16_3 and with its
        # bound: |v*g| <= 2**28, |(v*l) >> 15| < 2**15, |c| <= 2**29 + 2**23
        g0, l0, c0, g1, l1, c1, g2, l2, c2, k, s = ca.burst3  # type: ignore[misc]  # 3 int16 axes
        v = ((b[0] << 8 | b[1]) ^ 0x8000) - 0x8000
        out[0] = (v * g0 + ((v * l0) >> k) - c0) >> s
        v = ((b[2] << 8 | b[3]) ^ 0x8000) - 0x8000
        out[1] = (v * g1 + ((v * l1) >> k) - c1) >> s
        v = ((b[4] << 8 | b[5]) ^ 0x8000) - 0x8000
        out[2] = (v * g2 + ((v * l2) >> k) - c2) >> s
        g0, l0, c0, g1, l1, c1, g2, l2, c2, k, s = cg.burst3  # type: ignore[misc]
        v = ((b[8] << 8 | b[9]) ^ 0x8000) - 0x8000
        out[3] = (v * g0 + ((v * l0) >> k) - c0) >> s
        v = ((b[10] << 8 | b[11]) ^ 0x8000) - 0x8000
        out[4] = (v * g1 + ((v * l1) >> k) - c1) >> s
        v = ((b[12] << 8 | b[13]) ^ 0x8000) - 0x8000
        out[5] = (v * g2 + ((v * l2) >> k) - c2) >> s
        # temp_c100(t) inline: |2 * t * 10000| <= 6.6e8 < 2**30
        out[6] = (t * 20000 + self._tsens) // self._tsens2 + self._tzero

    def follow(self, model, step_c100=50):
        """Hardware offset(T): re-write the offsets when the temperature moved by step_c100.

        Call it periodically with the part awake (asleep, TEMP_OUT does not update); returns
        True when it wrote (verified, all-or-nothing) what ``model.registers(t)`` gives.
        """
        if self._dev.read_u8(_PWR_MGMT_1) & 0x40:  # SLEEP (RM-MPU-6000A 4.28)
            from tempcomp.mpu6xxx_faults import asleep

            raise asleep()
        t = self.temp_raw()
        last = self._follow_t
        if last is not None and abs(t - last) < step_c100 * self._tsens // 10000:
            return False
        g, a = model.registers(t)
        self.apply(g, a)
        self._follow_t = t
        return True

    # ---- persistence --------------------------------------------------------------------------
    def to_ints(self):
        """[WHO_AM_I, gyro x y z, accel x y z, factory x y z]: what a coefficient store keeps.

        The offsets are the ones last written (and verified) when there are any, so a trim the
        part changed by itself since (ICM-20602) is never saved; else what the part holds.
        """
        o = list(self.written) if self.written is not None else self._read_offsets()
        return [self.who_am_i] + o + list(self.factory)

    def apply_ints(self, ints):
        """Re-apply a to_ints() record (one call at boot); returns the offsets written."""
        if len(ints) != 10:
            from tempcomp.mpu6xxx_faults import record_length

            raise record_length(len(ints))
        if ints[0] != self.who_am_i:
            from tempcomp.mpu6xxx_faults import other_who_am_i

            raise other_who_am_i(ints[0], self.who_am_i)
        fac = tuple(ints[7:10])
        if fac != tuple(self.factory):
            held = tuple(self._read_offsets()[3:])
            diff = [k for k in range(3) if fac[k] != self.factory[k]]
            if held == tuple(ints[4:7]):
                # warm restart: the part kept our offsets, so what we read as factory was not
                self.factory = fac
            elif self.part == "ICM-20602" and diff == [1]:
                # the known fault: the part rewrote its Y trim (now, or when the record was
                # made). The saved offsets are absolute words, right whatever the register held.
                self.trim_changes += 1
                from tempcomp.mpu6xxx_faults import trim_rewritten

                warn(trim_rewritten(self.factory[1], fac[1]))
            else:
                from tempcomp.mpu6xxx_faults import other_factory

                warn(other_factory(self.factory, fac))
        return self.apply(ints[1:4], ints[4:7])

    def save(self, store, name="mpu6xxx"):
        """to_ints() into a tempcomp.store.Store, as kind KIND_MPU_POLY (2) for this part, after check()."""
        self.check()
        store.save_record(name, self.to_ints(), part=self.part, kind=2)

    def restore(self, store, name="mpu6xxx"):
        """Re-apply offsets saved with save() (verified); returns them.

        Compares the factory trim the part loaded with the saved one first (apply_ints), and
        starts the clock of check(every_ms=...), which keeps them from then on.
        """
        out = self.apply_ints(store.load(name))
        self._checked = _ticks_ms()
        return out


def _check3(what, v):
    ok = len(v) == 3
    for x in v:
        ok = ok and isinstance(x, int) and -32768 <= x <= 32767
    if not ok:
        from tempcomp.mpu6xxx_faults import not_registers

        raise not_registers(what, v)
    return v
