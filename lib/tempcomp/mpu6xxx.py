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
"""

import time as _time
from array import array

from tempcomp.bus import I2CDevice
from tempcomp.fixedpoint import Compensator
from tempcomp.mpu6xxx_parts import (
    ACCEL_CONFIG2,
    ACCEL_OFFS,
    ACCEL_STRIDE,
    FIFO_EN_BITS,
    FIFO_SIZE,
    GYRO_AT,
    NAME,
    PACKET,
    TEMP_SENS,
    TEMP_ZERO,
    WHO_AM_I,
    ZRO_DPS,
    ZRO_SPAN_DPS,
    by_name,
    by_who_am_i,
    names,
)

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


try:
    from warnings import warn as _warn  # pyright: ignore[reportMissingImports]
except ImportError:

    def _warn(msg):
        print("tempcomp.mpu6xxx warning:", msg)


# a millisecond clock for check(every_ms=): MicroPython's ticks, CircuitPython's supervisor
# ticks (they wrap at 2**29), else the monotonic clock
try:
    import supervisor as _supervisor  # pyright: ignore[reportMissingImports]
except ImportError:
    _supervisor = None


def _ticks_ms():
    f = getattr(_time, "ticks_ms", None) or getattr(_supervisor, "ticks_ms", None)
    if f is not None:
        return f()
    return int(_time.monotonic() * 1000)  # pyright: ignore[reportAttributeAccessIssue]


def _ticks_diff(a, b):
    f = getattr(_time, "ticks_diff", None)
    if f is not None:
        return f(a, b)
    if _supervisor is not None:
        return ((a - b + 0x10000000) & 0x1FFFFFFF) - 0x10000000
    return a - b


# Register map (RM-MPU-6000A / RM-MPU-9250)
_XG_OFFS_USRH = const(0x13)  # gyro X/Y/Z offsets at 0x13, 0x15, 0x17 (high byte first)
_SMPLRT_DIV = const(0x19)  # followed by CONFIG, GYRO_CONFIG, ACCEL_CONFIG, ACCEL_CONFIG2
_GYRO_CONFIG = const(0x1B)
_ACCEL_CONFIG = const(0x1C)
_FIFO_EN = const(0x23)
_INT_ENABLE = const(0x38)
_ACCEL_XOUT_H = const(0x3B)  # 14 bytes: accel x y z, temperature, gyro x y z
_TEMP_OUT_H = const(0x41)
_USER_CTRL = const(0x6A)  # followed by PWR_MGMT_1, PWR_MGMT_2
_FIFO_COUNTH = const(0x72)
_FIFO_R_W = const(0x74)
_WHO_AM_I = const(0x75)

_USER_FIFO_EN = const(0x40)
_USER_RESETS = const(0x07)  # FIFO_RST, I2C_MST_RST, SIG_COND_RST: self-clearing
_USER_FIFO_RST = const(0x04)
_PWR_PLL = const(0x01)  # awake, gyro PLL clock, temperature sensor on
_CAL_CONFIG = const(0x01)  # DLPF_CFG 1 (188/184 Hz): 1 kHz internal rate; SMPLRT_DIV 0 keeps it
_CAL_ACCEL2 = const(0x01)  # MPU-6500 family A_DLPF_CFG 1: accel at 1 kHz, 184 Hz

_GYRO_LSB_DPS = const(131)  # +-250 dps: 131 LSB/dps
_ACCEL_LSB_G = const(16384)  # +-2 g
_GYRO_STEP = const(4)  # one +-1000 dps register LSB = 4 output LSB at +-250 dps
_ACCEL_STEP = const(8)  # one 2048 LSB/g word LSB = 8 output LSB at +-2 g

MIN_PACKETS = const(20)
# |sum| <= 32768 * 16000 < 2**29 and |sum - 16384 * packets| < 2**30: small ints on 32-bit
# MicroPython, and no long ints at all on CircuitPython builds without them
MAX_PACKETS = const(16000)
_BATCH = const(16)  # packets per FIFO read: 224 bytes at most
_MAX_IDLE = const(5000)  # FIFO_COUNT polls without a new packet before giving up
_MAX_RESETS = const(4)
_RETRIES = const(3)
_T_QUANT = const(8)  # per-sample temperature compensation steps of 8 LSB (~0.024 degC)
# Plausibility of what is read during calibration (issue 17: one corrupted, not NACKed, read
# must not become a wrong calibration). Registers are re-read until two reads agree.
_READS = const(4)  # re-reads after the first before giving up
_T_AGREE = const(64)  # two temperature reads agree within 64 LSB (~0.2 degC)
# A sample is an outlier when it lies farther on one side of the mean than 4x the farthest one
# on the other side, plus 16 LSB (0.12 deg/s, 1 mg): Gaussian noise never does that (0 of
# 20,000 simulated captures of 20..1000 samples), a corrupted read or a knock does.
_OUTLIER_RATIO = const(4)
_OUTLIER_FLOOR = const(16)


class MPUError(OSError):
    """A bus fault, a read-back mismatch or an unusable capture on an MPU-6xxx part."""


def _s16(hi, lo):
    v = hi << 8 | lo
    if v & 0x8000:
        v -= 0x10000
    return v


def _rdiv(num, den):
    # num / den rounded half up, exactly, for den > 0; intermediates no larger than num
    q, r = divmod(num, den)
    return q + 1 if 2 * r >= den else q


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
                raise MPUError(
                    "no known MPU-6xxx part at I2C address 0x%02x: WHO_AM_I is 0x%02x; for a "
                    "clone name the part it copies, e.g. part='MPU-6500' (known: %s)"
                    % (address, who, ", ".join(names()))
                )
        else:
            row = by_name(part)
            if row is None:
                raise ValueError("unknown part %r; known: %s" % (part, ", ".join(names())))
            if row[WHO_AM_I] != who:
                _warn(
                    "part at 0x%02x answers WHO_AM_I 0x%02x, not 0x%02x: driving it with the %s "
                    "layout as asked" % (address, who, row[WHO_AM_I], row[NAME])
                )
        self.part = row[NAME]
        self._row = row
        self._pkt = row[PACKET]
        self._gyro_at = row[GYRO_AT]
        self._fifo_limit = row[FIFO_SIZE] - 2 * row[PACKET]
        self._ncfg = 5 if row[ACCEL_CONFIG2] else 4
        a0 = row[ACCEL_OFFS]
        st = row[ACCEL_STRIDE]
        self._oregs = (_XG_OFFS_USRH, _XG_OFFS_USRH + 2, _XG_OFFS_USRH + 4, a0, a0 + st, a0 + 2 * st)
        self._b2 = bytearray(2)
        self._w2 = bytearray(2)
        self._w1 = bytearray(1)
        self._cfg = bytearray(5)
        self._ctl = bytearray(3)
        self._chk = bytearray(5)
        self._d14 = bytearray(14)
        self._fifo = bytearray(_BATCH * self._pkt)
        mv = memoryview(self._fifo)
        # one view per packet count so a FIFO read never slices (slicing allocates)
        self._views = [mv[: k * self._pkt] for k in range(_BATCH + 1)]
        self._sum = array("i", [0] * 6)
        self._sum1 = array("i", [0] * 6)  # sums of the first half of a capture (turn check)
        self._n1 = 0
        self._min = array("i", [0] * 6)
        self._max = array("i", [0] * 6)
        self._n = 0
        self._got = 0
        self._need = 0
        self._settle = 0
        self._idle = 0
        self._resets = 0
        self._ca = None
        self._cg = None
        self._follow_t = None
        self._target = None
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
        raise MPUError(
            "offset registers read differently %d times in a row (bus noise? check pull-ups and "
            "wiring); nothing written" % (_READS + 1)
        )

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
            raise MPUError(
                "register 0x%02x reads back 0x%02x%02x after writing 0x%02x%02x" % (reg, b[0], b[1], w[0], w[1])
            )

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
                    raise MPUError(
                        "offset register 0x%02x holds %d, not the %d written"
                        % (self._oregs[i], now[i], words[i])
                    )
        except BaseException as e:
            bad = self._rollback(old, done)
            if bad is not None:
                raise MPUError(
                    "%s; restoring the previous offsets failed too (%s): power-cycle the part"
                    % (e, bad)
                )
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
        self._target = words
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
        want = self._target
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
    def _read_config(self):
        d = self._dev
        d.read_into(_SMPLRT_DIV, memoryview(self._cfg)[: self._ncfg])
        d.read_into(_USER_CTRL, self._ctl)
        fifo_en = d.read_u8(_FIFO_EN)
        int_en = d.read_u8(_INT_ENABLE)
        return (bytes(self._cfg), bytes(self._ctl), fifo_en, int_en)

    def _save_config(self):
        # what is given back after the capture: two reads in a row must agree
        prev = self._read_config()
        for _ in range(_READS):
            cur = self._read_config()
            if cur == prev:
                return cur
            prev = cur
        raise MPUError("configuration registers read differently %d times in a row (bus noise?); "
                       "nothing changed" % (_READS + 1))

    def _write_u8(self, reg, v):
        self._w1[0] = v
        self._dev.write(reg, self._w1)

    def _restore_once(self, saved):
        cfg, ctl, fifo_en, int_en = saved
        d = self._dev
        n = self._ncfg
        self._write_u8(_FIFO_EN, 0)
        self._write_u8(_USER_CTRL, _USER_FIFO_RST)  # drop our packets from the FIFO
        d.write(_SMPLRT_DIV, cfg[:n])
        self._write_u8(_FIFO_EN, fifo_en)
        self._write_u8(_INT_ENABLE, int_en)
        self._write_u8(_USER_CTRL, ctl[0] & ~_USER_RESETS)
        d.write(_USER_CTRL + 1, ctl[1:3])  # power management last: it may put the part to sleep
        chk = memoryview(self._chk)
        d.read_into(_SMPLRT_DIV, chk[:n])
        ok = bytes(chk[:n]) == cfg[:n]
        d.read_into(_USER_CTRL, chk[:3])
        ok = ok and chk[0] == ctl[0] & ~_USER_RESETS and chk[1] == ctl[1] & 0x7F and chk[2] == ctl[2]
        ok = ok and d.read_u8(_FIFO_EN) == fifo_en and d.read_u8(_INT_ENABLE) == int_en
        if not ok:
            raise MPUError("configuration registers did not read back as restored")

    def _restore_config(self, saved):
        err = None
        for _ in range(_RETRIES):
            try:
                self._restore_once(saved)
                return None
            except OSError as e:
                err = e
        return err

    def _start_capture(self):
        d = self._dev
        self._w2[0] = _PWR_PLL
        self._w2[1] = 0
        d.write(_USER_CTRL + 1, self._w2)  # PWR_MGMT_1 awake on the PLL, PWR_MGMT_2 all axes on
        self._write_u8(_INT_ENABLE, 0)
        self._write_u8(_FIFO_EN, 0)
        self._write_u8(_USER_CTRL, _USER_FIFO_RST)  # FIFO off and empty, I2C master off
        cfg = bytearray(5)  # SMPLRT_DIV 0, CONFIG, GYRO_CONFIG +-250 dps, ACCEL_CONFIG +-2 g
        cfg[1] = _CAL_CONFIG
        cfg[4] = _CAL_ACCEL2
        d.write(_SMPLRT_DIV, cfg[: self._ncfg])
        self._write_u8(_USER_CTRL, _USER_FIFO_EN)
        self._write_u8(_FIFO_EN, self._row[FIFO_EN_BITS])

    def _begin(self, packets, settle):
        s = self._sum
        for j in range(6):
            s[j] = 0
            self._min[j] = 32767
            self._max[j] = -32768
        self._n = 0
        self._got = 0
        self._need = settle + packets
        self._settle = settle
        self._idle = 0
        self._resets = 0

    def _poll(self):
        # One FIFO_COUNT read and at most one FIFO read: returns the packets taken.
        # Allocation-free (preallocated views, small-int state), proven in the VM.
        d = self._dev
        b = self._b2
        d.read_into(_FIFO_COUNTH, b)
        c = (b[0] & 0x1F) << 8 | b[1]  # 13-bit count on the MPU-6500 family, < 1024 on the 6050
        if c >= self._fifo_limit or c % self._pkt:
            # beyond the FIFO or not whole packets: a corrupted read? ask again before acting
            d.read_into(_FIFO_COUNTH, b)
            c = (b[0] & 0x1F) << 8 | b[1]
        if c >= self._fifo_limit:
            # near full: a FIFO that overflows drops bytes and the packets lose alignment
            self._resets += 1
            if self._resets > _MAX_RESETS:
                raise MPUError("FIFO overflowed %d times: read it faster (bus too slow?)" % self._resets)
            self._write_u8(_USER_CTRL, _USER_FIFO_EN | _USER_FIFO_RST)
            return 0
        pkt = self._pkt
        k = c // pkt
        if k == 0:
            self._idle += 1
            if self._idle > _MAX_IDLE:
                raise MPUError(
                    "FIFO stopped filling after %d of %d packets" % (self._got, self._need)
                )
            return 0
        self._idle = 0
        if k > _BATCH:
            k = _BATCH
        left = self._need - self._got
        if k > left:
            k = left
        d.read_into(_FIFO_R_W, self._views[k])
        first = self._settle - self._got  # packets still to discard while the filters settle
        if first < 0:
            first = 0
        if first < k:
            self._accumulate(first, k)
        self._got += k
        return k

    def _accumulate(self, first, k):
        # Sum and min/max of packets first..k-1 in self._fifo. |sum| <= 32768 * MAX_PACKETS
        # < 2**30; no allocation per packet.
        b = self._fifo
        s = self._sum
        lo = self._min
        hi = self._max
        pkt = self._pkt
        p = first * pkt
        end = k * pkt
        ga = self._gyro_at - 6
        while p < end:
            j = 0
            q = p
            while j < 6:
                if j == 3:
                    q += ga
                v = b[q] << 8 | b[q + 1]
                if v & 0x8000:
                    v -= 0x10000
                s[j] += v
                if v < lo[j]:
                    lo[j] = v
                if v > hi[j]:
                    hi[j] = v
                j += 1
                q += 2
            p += pkt
        self._n += k - first

    def _capture(self, packets, settle_ms):
        if not MIN_PACKETS <= packets <= MAX_PACKETS:
            raise ValueError("packets must be %d..%d, got %r" % (MIN_PACKETS, MAX_PACKETS, packets))
        if not 0 <= settle_ms <= 1000:
            raise ValueError("settle_ms must be 0..1000, got %r" % (settle_ms,))
        saved = self._save_config()
        try:
            self._start_capture()
            self._begin(packets, settle_ms)  # 1 kHz: one packet a millisecond
            self._n1 = 0
            half = packets // 2
            while self._got < self._need:
                self._poll()
                if self._n1 == 0 and self._n >= half:
                    self._split()
            t = self._temp_agreed()
        except BaseException as e:
            bad = self._restore_config(saved)
            if bad is not None:
                raise MPUError("%s; restoring the sensor configuration failed too (%s)" % (e, bad))
            raise
        bad = self._restore_config(saved)
        if bad is not None:
            raise bad
        if self._n < MIN_PACKETS:
            raise MPUError("only %d packets captured, at least %d needed" % (self._n, MIN_PACKETS))
        return t

    def _split(self):
        # sums so far: the first part of the capture, for the turn check in _analyse
        for j in range(6):
            self._sum1[j] = self._sum[j]
        self._n1 = self._n

    def _temp_agreed(self):
        a = self.temp_raw()
        for _ in range(_READS):
            b = self.temp_raw()
            if -_T_AGREE <= b - a <= _T_AGREE:
                return b
            a = b
        raise MPUError("TEMP_OUT read differently %d times in a row (bus noise?)" % (_READS + 1))

    def zro_limit_dps(self, t_raw=None):
        """The gyro bias (deg/s) this part may have at rest at TEMP_OUT reading t_raw (default:
        read now, the part awake): its datasheet initial tolerance plus the variation over
        temperature away from 25 degC (mpu6xxx_parts ZRO_DPS, ZRO_SPAN_DPS)."""
        row = self._row
        dt = abs(self.temp_c100(t_raw) - 2500) / 100.0
        return row[ZRO_DPS] + row[ZRO_SPAN_DPS] * dt / 60.0  # the span covers 25 -> -40/+85 degC

    def _analyse(self, cur, gyro_spread_dps, accel_spread_mg, max_tilt_mg, t=None, max_bias_dps=None,
                 max_turn_dps=1):
        # -> (gravity axis, its expected output at +-2 g); raises on an unusable capture.
        # Gravity and tilt are judged on what the part reads with its factory trim, so
        # offsets written earlier (even far off) don't hide the face it lies on.
        n = self._n
        s = self._sum
        axes = ("accel x", "accel y", "accel z", "gyro x", "gyro y", "gyro z")
        for j in range(6):
            if self._min[j] == -32768 or self._max[j] == 32767:
                raise MPUError(
                    "%s output saturated during capture; if offsets were written by hand, "
                    "start from imu.apply((0, 0, 0), imu.factory)" % axes[j]
                )
        for j in range(6):
            spread = self._max[j] - self._min[j]
            if j < 3:
                lim = accel_spread_mg * _ACCEL_LSB_G // 1000
                shown, unit, limit = spread * 1000 // _ACCEL_LSB_G, "mg", accel_spread_mg
            else:
                lim = gyro_spread_dps * _GYRO_LSB_DPS
                shown, unit, limit = spread // _GYRO_LSB_DPS, "dps", gyro_spread_dps
            if spread > lim:
                raise MPUError(
                    "the part moved during capture (or a bus read was corrupted): %s spread %d %s "
                    "(limit %d); keep it still and try again; nothing written" % (axes[j], shown, unit, limit)
                )
        for j in range(6):
            # a lone sample far on one side: a corrupted read (or a knock) the spread allows
            mean = s[j] / n
            up = self._max[j] - mean
            dn = mean - self._min[j]
            far, near = (up, dn) if up > dn else (dn, up)
            if far > _OUTLIER_RATIO * near + _OUTLIER_FLOOR:
                raise MPUError(
                    "%s: one sample lies %d LSB from the mean while the others stay within %d: "
                    "a corrupted bus read or a knock; nothing written, try again"
                    % (axes[j], far, near)
                )
        fac = self.factory
        m = [s[j] // n - ((cur[3 + j] >> 1) - (fac[j] >> 1)) * 2 * _ACCEL_STEP for j in range(3)]
        g = 0
        for j in (1, 2):
            if abs(m[j]) > abs(m[g]):
                g = j
        mg = [m[j] * 1000 // _ACCEL_LSB_G for j in range(3)]
        if not 850 <= abs(mg[g]) <= 1150:
            raise MPUError(
                "gravity reads %d mg on accel %s (expected about 1000): not at rest?" % (mg[g], "xyz"[g])
            )
        for j in range(3):
            if j != g and abs(mg[j]) > max_tilt_mg:
                raise MPUError(
                    "not lying on a face: accel x/y/z read %d/%d/%d mg; lay it flat (limit %d mg off-axis)"
                    % (mg[0], mg[1], mg[2], max_tilt_mg)
                )
        self._check_turn(g, max_turn_dps)
        self._check_bias(cur, t, max_bias_dps)
        return g, (_ACCEL_LSB_G if m[g] > 0 else -_ACCEL_LSB_G)

    def _check_turn(self, g, max_turn_dps):
        # A steady turn has no spread to speak of, but gravity moves in the part's frame: compare
        # the accel mean of the two parts of the capture on the axes across gravity. Noise: a
        # sample's sigma is at most half the spread, so the difference of the two means has
        # sigma <= spread/2 * sqrt(1/n1 + 1/n2); four of those are allowed. (A turn about the
        # vertical leaves gravity alone: _check_bias and a second face catch that one.)
        if max_turn_dps is None:
            return
        n1 = self._n1
        n2 = self._n - n1
        if n1 <= 0 or n2 <= 0:
            return
        s = self._sum
        s1 = self._sum1
        d2 = 0.0
        v2 = 0.0
        for j in range(3):
            if j != g:
                d = (s[j] - s1[j]) / n2 - s1[j] / n1
                d2 += d * d
                v2 += ((self._max[j] - self._min[j]) / 2.0) ** 2 * (1.0 / n1 + 1.0 / n2)
        d = d2**0.5
        if d * d <= 16.0 * v2:
            return
        dps = d / _ACCEL_LSB_G * 57.29578 / (self._n / 2000.0)  # the two parts' centres are n/2 ms apart
        if dps > max_turn_dps:
            raise MPUError(
                "the part turned during capture: gravity moved %.2f deg in %.2f s (%.1f deg/s, limit "
                "%s); keep it still; nothing written" % (d / _ACCEL_LSB_G * 57.29578, self._n / 2000.0, dps,
                                                       max_turn_dps)
            )

    def _check_bias(self, cur, t, max_bias_dps):
        # A turn about the vertical shows only as a gyro bias no part at rest has (datasheet
        # ZRO tolerance, widened with the temperature away from 25 degC).
        lim = max_bias_dps
        if lim is None:
            lim = self.zro_limit_dps(t)
        n = self._n
        for k in range(3):
            # output at +-250 dps = bias + 4 LSB per register LSB already in the part
            dps = (self._sum[3 + k] / n - _GYRO_STEP * cur[k]) / _GYRO_LSB_DPS
            if abs(dps) > lim:
                raise MPUError(
                    "gyro %s reads %+.1f deg/s at rest, more than this %s's zero-rate offset can be "
                    "(+-%.1f deg/s at %.1f degC): was the board turning? Nothing written. (A part outside "
                    "its datasheet: pass max_bias_dps=)" % ("xyz"[k], dps, self.part, lim,
                                                             self.temp_c100(t) / 100.0)
                )

    def _capture_at_rest(self, packets, settle_ms):
        # -> (temperature, offsets held); the offsets must not change during the capture (an
        # ICM-20602 rewriting its trim mid-capture would mix two biases)
        before = self._read_offsets()
        t = self._capture(packets, settle_ms)
        cur = self._read_offsets()
        if cur != before:
            self.trim_changes += 1
            raise MPUError(
                "offset registers changed during the capture (%r -> %r): the part rewrote its trim "
                "(a known ICM-20602 fault); nothing written, try again" % (before, cur)
            )
        return t, cur

    def calibrate(self, packets=1000, settle_ms=50, gyro_spread_dps=5, accel_spread_mg=150, max_tilt_mg=150,
                  max_bias_dps=None, max_turn_dps=1):
        """Capture ``packets`` samples at rest (1 kHz), write and verify the offsets.

        Lay the part still on any face (up or down). Returns ((gx, gy, gz), (ax, ay, az))
        register values as ``offsets()`` reads them. Raises MPUError if it moved (spread over
        the limits), turned (gravity moved by more than max_turn_dps, or a gyro bias beyond the
        part's datasheet range, ``zro_limit_dps()``, or max_bias_dps), is not lying on a face,
        a read was implausible, or the bus failed: the previous offsets and the sensor
        configuration are then left in place.
        """
        t, cur = self._capture_at_rest(packets, settle_ms)
        g, e = self._analyse(cur, gyro_spread_dps, accel_spread_mg, max_tilt_mg, t, max_bias_dps, max_turn_dps)
        n = self._n
        s = self._sum
        words = [0] * 6
        for k in range(3):
            # the output already includes the current register: new = current - bias
            words[k] = _clamp_gyro(k, cur[k] + _rdiv(-s[3 + k], _GYRO_STEP * n))
            d = s[k] - (e * n if k == g else 0)  # bias * n in +-2 g output LSB: |d| < 2**30
            # the 15-bit field (bits 15..1) counts 2 word LSB = 16 output LSB at +-2 g
            t15 = (cur[3 + k] >> 1) + _rdiv(-d, 2 * _ACCEL_STEP * n)
            words[3 + k] = _clamp_accel15(k, t15) * 2 | (cur[3 + k] & 1)
        self._write_offsets(words)
        self._target = words
        return (tuple(words[:3]), tuple(words[3:]))

    def bias_point(self, packets=1000, settle_ms=50, gyro_spread_dps=5, accel_spread_mg=150, max_tilt_mg=150,
                   max_bias_dps=None, max_turn_dps=1):
        """Capture at rest at the present temperature; write nothing.

        Returns (t_raw, (gx, gy, gz), (ax, ay, az)): the raw temperature reading and, as floats,
        the register values that would zero the bias now (gyro register LSB, accel word LSB).
        Collect points at several temperatures for ``tempcomp.mpu6xxx_tc.BiasModel``. The
        capture is checked as calibrate() checks it.
        """
        t, cur = self._capture_at_rest(packets, settle_ms)
        g, e = self._analyse(cur, gyro_spread_dps, accel_spread_mg, max_tilt_mg, t, max_bias_dps, max_turn_dps)
        n = self._n
        s = self._sum
        gy = tuple(cur[k] - s[3 + k] / (_GYRO_STEP * n) for k in range(3))
        ac = tuple(
            (cur[3 + k] & ~1) - (s[k] - (e * n if k == g else 0)) / (_ACCEL_STEP * n) for k in range(3)
        )
        return (t, gy, ac)

    # ---- data ----------------------------------------------------------------------------
    def temp_raw(self):
        """TEMP_OUT as a signed integer (the reading offset(T) polynomials use)."""
        b = self._b2
        self._dev.read_into(_TEMP_OUT_H, b)
        return _s16(b[0], b[1])

    def temp_c100(self, raw=None):
        """Temperature in hundredths of a degC (allocation-free when read from the part)."""
        if raw is None:
            raw = self.temp_raw()
        sens = self._row[TEMP_SENS]
        # |2 * raw * 10000| <= 6.6e8 < 2**30
        return (raw * 20000 + sens) // (2 * sens) + self._row[TEMP_ZERO]

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
                raise ValueError("%s must be one of %r, got %r" % (what, opts, val))
            r = self._dev.read_u8(reg)
            self._write_u8(reg, (r & ~0x18) | opts.index(val) << 3)

    # ---- temperature-dependent bias ---------------------------------------------------------
    def compensate(self, model):
        """Software offset(T): set up read_compensated() for the present ranges and offsets.

        ``model`` is a ``tempcomp.mpu6xxx_tc.BiasModel``. The offsets the part holds now are
        taken as the base: keep them (and the ranges) unchanged while using read_compensated().
        """
        gdps, ag = self.ranges()
        cur = self._read_offsets()
        gfs = gdps // 250
        afs = ag // 2
        k_g = _GYRO_STEP / gfs  # output LSB per gyro register LSB
        k_a = _ACCEL_STEP / afs  # output LSB per accel word LSB
        offs_g = [model.offset_poly(k, cur[k], k_g) for k in range(3)]
        offs_a = [model.offset_poly(3 + k, cur[3 + k] & ~1, k_a) for k in range(3)]
        t_cal = model.t_cal
        self._cg = Compensator(offs_g, [[_GYRO_LSB_DPS / gfs]] * 3, t_cal, out_scale=1000, t_ref=model.t_ref, policy=model.policy)
        self._ca = Compensator(offs_a, [[_ACCEL_LSB_G / afs]] * 3, t_cal, out_scale=1000, t_ref=model.t_ref, policy=model.policy)

    def read_compensated(self, out):
        """out[0..2] accel mg, out[3..5] gyro mdps, out[6] degC/100; zero allocation."""
        ca = self._ca
        cg = self._cg
        if ca is None or cg is None:
            raise ValueError("call compensate(model) first")
        b = self._d14
        self._dev.read_into(_ACCEL_XOUT_H, b)
        t = _s16(b[6], b[7])
        tq = t - t % _T_QUANT
        ca.update(tq)
        cg.update(tq)
        i = 0
        while i < 3:
            out[i] = ca.apply(_s16(b[2 * i], b[2 * i + 1]), i)
            out[3 + i] = cg.apply(_s16(b[8 + 2 * i], b[9 + 2 * i]), i)
            i += 1
        out[6] = self.temp_c100(t)

    def follow(self, model, step_c100=50):
        """Hardware offset(T): re-write the offsets when the temperature moved by step_c100.

        Call it periodically with the part awake (asleep, TEMP_OUT does not update); returns
        True when it wrote (verified, all-or-nothing).
        """
        if self._dev.read_u8(_USER_CTRL + 1) & 0x40:
            raise MPUError("the part is asleep (PWR_MGMT_1.SLEEP): its temperature is stale")
        t = self.temp_raw()
        step = step_c100 * self._row[TEMP_SENS] // 10000
        last = self._follow_t
        if last is not None and abs(t - last) < step:
            return False
        g, a = model.targets(t)
        self.apply(
            [_clamp_gyro(k, g[k]) for k in range(3)],
            [_clamp_accel15(k, a[k] >> 1) * 2 for k in range(3)],
        )
        self._follow_t = t
        return True

    # ---- persistence --------------------------------------------------------------------------
    def to_ints(self):
        """[WHO_AM_I, gyro x y z, accel x y z, factory x y z]: what a coefficient store keeps.

        The offsets are the ones last written (and verified) when there are any, so a trim the
        part changed by itself since (ICM-20602) is never saved; else what the part holds.
        """
        o = list(self._target) if self._target is not None else self._read_offsets()
        return [self.who_am_i] + o + list(self.factory)

    def apply_ints(self, ints):
        """Re-apply a to_ints() record (one call at boot); returns the offsets written."""
        if len(ints) != 10:
            raise ValueError("an MPU6xxx record has 10 ints, got %d" % len(ints))
        if ints[0] != self.who_am_i:
            raise ValueError(
                "saved offsets belong to a part with WHO_AM_I 0x%02x, this one is 0x%02x"
                % (ints[0], self.who_am_i)
            )
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
                _warn("ICM-20602 accel y trim reads %d, saved factory value %d: the part changed it by "
                      "itself (a known ICM-20602 fault); the saved offsets are written back, call "
                      "check(every_ms=1000) from your loop to keep them" % (self.factory[1], fac[1]))
            else:
                _warn("factory trim %r differs from the saved %r: a different part?" % (self.factory, fac))
        return self.apply(ints[1:4], ints[4:7])

    def save(self, store, name="mpu6xxx"):
        """store.save(name, to_ints()) with a tempcomp.store.Store, after check()."""
        self.check()
        store.save(name, self.to_ints())

    def restore(self, store, name="mpu6xxx"):
        """Re-apply offsets saved with save() (verified); returns them.

        Compares the factory trim the part loaded with the saved one first (apply_ints), and
        starts the clock of check(every_ms=...), which keeps them from then on.
        """
        out = self.apply_ints(store.load(name))
        self._checked = _ticks_ms()
        return out


def _clamp_gyro(axis, v):
    if -32768 <= v <= 32767:
        return v
    _warn("gyro %s offset %d clamped to the int16 register" % ("xyz"[axis], v))
    return -32768 if v < 0 else 32767


def _clamp_accel15(axis, t15):
    # bits 15..1 of the accel word: a signed 15-bit field
    if -16384 <= t15 <= 16383:
        return t15
    _warn("accel %s offset %d clamped to the 15-bit field" % ("xyz"[axis], t15 * 2))
    return -16384 if t15 < 0 else 16383


def _check3(what, v):
    if len(v) != 3:
        raise ValueError("%s needs 3 values, got %r" % (what, v))
    for x in v:
        if not isinstance(x, int) or not -32768 <= x <= 32767:
            raise ValueError("%s values must be int16 register values, got %r" % (what, v))
    return v
