"""Calibration captures of an MPU-6xxx: FIFO capture at rest, its checks, the offsets it computes.

Loaded on first use by ``MPU6xxx.calibrate()`` and ``MPU6xxx.bias_point()``, never at boot: a
board that only restores its offsets and reads compensated samples (``tempcomp.mpu6xxx``)
keeps this code and the capture buffers off its heap (docs/ram.md has the figures). Use the
methods of ``tempcomp.mpu6xxx.MPU6xxx``; ``Capture`` is its helper, one per part.

Beside the driver, below it: it stands on ``tempcomp.mpu6xxx_parts`` and
``tempcomp.mpu6xxx_units`` alone. The driver hands it
its bus device and part row, reads the offset registers before and after a capture, hands over
what they hold and the factory trim, and writes (verified) the offsets computed here.
"""

from array import array

from tempcomp.mpu6xxx_parts import (
    ACCEL_CONFIG2,
    FIFO_EN_BITS,
    FIFO_SIZE,
    GYRO_AT,
    NAME,
    PACKET,
    TEMP_OUT_H,
    MPUError,
    celsius100,
    zro_limit,
)
from tempcomp.mpu6xxx_units import (
    ACCEL_LSB_G,
    ACCEL_STEP,
    GYRO_LSB_DPS,
    GYRO_STEP,
    clamp_accel15,
    clamp_gyro,
)

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


MIN_PACKETS = const(20)
# |sum| <= 32768 * 16000 < 2**29 and |sum - 16384 * packets| < 2**30: small ints on 32-bit
# MicroPython, and no long ints at all on CircuitPython builds without them
MAX_PACKETS = const(16000)

# Register map (RM-MPU-6000A / RM-MPU-9250): the registers only the capture uses
_SMPLRT_DIV = const(0x19)  # followed by CONFIG, GYRO_CONFIG, ACCEL_CONFIG, ACCEL_CONFIG2
_FIFO_EN = const(0x23)
_INT_ENABLE = const(0x38)
_USER_CTRL = const(0x6A)  # followed by PWR_MGMT_1, PWR_MGMT_2
_FIFO_COUNTH = const(0x72)
_FIFO_R_W = const(0x74)

_USER_FIFO_EN = const(0x40)
_USER_RESETS = const(0x07)  # FIFO_RST, I2C_MST_RST, SIG_COND_RST: self-clearing
_USER_FIFO_RST = const(0x04)
_PWR_PLL = const(0x01)  # awake, gyro PLL clock, temperature sensor on
_CAL_CONFIG = const(0x01)  # DLPF_CFG 1 (188/184 Hz): 1 kHz internal rate; SMPLRT_DIV 0 keeps it
_CAL_ACCEL2 = const(0x01)  # MPU-6500 family A_DLPF_CFG 1: accel at 1 kHz, 184 Hz


_BATCH = const(16)  # packets per FIFO read: 224 bytes at most
_MAX_IDLE = const(5000)  # FIFO_COUNT polls without a new packet before giving up
_MAX_RESETS = const(4)
_RETRIES = const(3)
# Plausibility of what is read during calibration (issue 17: one corrupted, not NACKed, read
# must not become a wrong calibration). Registers are re-read until two reads agree.
_READS = const(4)  # re-reads after the first before giving up
_T_AGREE = const(64)  # two temperature reads agree within 64 LSB (~0.2 degC)
# A sample is an outlier when it lies farther on one side of the mean than 4x the farthest one
# on the other side, plus 16 LSB (0.12 deg/s, 1 mg): Gaussian noise never does that (0 of
# 20,000 simulated captures of 20..1000 samples), a corrupted read or a knock does.
_OUTLIER_RATIO = const(4)
_OUTLIER_FLOOR = const(16)


def _rdiv(num, den):
    # num / den rounded half up, exactly, for den > 0; intermediates no larger than num
    q, r = divmod(num, den)
    return q + 1 if 2 * r >= den else q


class Capture:
    """The capture state of one part, on bus device ``dev`` (tempcomp.bus.I2CDevice) with the
    parts-table ``row``: FIFO buffers, sums, min/max, configuration."""

    def __init__(self, dev, row):
        self._dev = dev
        self._row = row
        self._b2 = bytearray(2)
        self._w2 = bytearray(2)
        self._w1 = bytearray(1)
        self._pkt = row[PACKET]
        self._gyro_at = row[GYRO_AT]
        self._fifo_limit = row[FIFO_SIZE] - 2 * row[PACKET]
        self._ncfg = 5 if row[ACCEL_CONFIG2] else 4
        self._cfg = bytearray(5)
        self._ctl = bytearray(3)
        self._chk = bytearray(5)
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

    def _write_u8(self, reg, v):
        self._w1[0] = v
        self._dev.write(reg, self._w1)

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

    def capture(self, packets, settle_ms):
        """Capture ``packets`` samples at rest (1 kHz) after settle_ms; the part's configuration is
        given back after it. Returns the temperature reading (two reads that agree)."""
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

    def _temp_raw(self):
        b = self._b2
        self._dev.read_into(TEMP_OUT_H, b)
        v = b[0] << 8 | b[1]
        return v - 0x10000 if v & 0x8000 else v

    def _temp_agreed(self):
        a = self._temp_raw()
        for _ in range(_READS):
            b = self._temp_raw()
            if -_T_AGREE <= b - a <= _T_AGREE:
                return b
            a = b
        raise MPUError("TEMP_OUT read differently %d times in a row (bus noise?)" % (_READS + 1))

    def _analyse(self, cur, factory, t, gyro_spread_dps, accel_spread_mg, max_tilt_mg, max_bias_dps, max_turn_dps):
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
                lim = accel_spread_mg * ACCEL_LSB_G // 1000
                shown, unit, limit = spread * 1000 // ACCEL_LSB_G, "mg", accel_spread_mg
            else:
                lim = gyro_spread_dps * GYRO_LSB_DPS
                shown, unit, limit = spread // GYRO_LSB_DPS, "dps", gyro_spread_dps
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
        m = [s[j] // n - ((cur[3 + j] >> 1) - (factory[j] >> 1)) * 2 * ACCEL_STEP for j in range(3)]
        g = 0
        for j in (1, 2):
            if abs(m[j]) > abs(m[g]):
                g = j
        mg = [m[j] * 1000 // ACCEL_LSB_G for j in range(3)]
        # the tilt first: tilted 30 degrees, the vertical axis reads 866 mg, and a part's own
        # zero-g offset (tens of mg) can take that below 850: still a tilt, not motion
        for j in range(3):
            if j != g and abs(mg[j]) > max_tilt_mg:
                raise MPUError(
                    "not lying on a face: accel x/y/z read %d/%d/%d mg; lay it flat (limit %d mg off-axis)"
                    % (mg[0], mg[1], mg[2], max_tilt_mg)
                )
        if not 850 <= abs(mg[g]) <= 1150:
            raise MPUError(
                "gravity reads %d mg on accel %s (expected about 1000): not at rest?" % (mg[g], "xyz"[g])
            )
        self._check_turn(g, max_turn_dps)
        self._check_bias(cur, t, max_bias_dps)
        return g, (ACCEL_LSB_G if m[g] > 0 else -ACCEL_LSB_G)

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
        dps = d / ACCEL_LSB_G * 57.29578 / (self._n / 2000.0)  # the two parts' centres are n/2 ms apart
        if dps > max_turn_dps:
            raise MPUError(
                "the part turned during capture: gravity moved %.2f deg in %.2f s (%.1f deg/s, limit "
                "%s); keep it still; nothing written" % (d / ACCEL_LSB_G * 57.29578, self._n / 2000.0, dps,
                                                       max_turn_dps)
            )

    def _check_bias(self, cur, t, max_bias_dps):
        # A turn about the vertical shows only as a gyro bias no part at rest has (datasheet
        # ZRO tolerance, widened with the temperature away from 25 degC).
        tc = celsius100(self._row, t)
        lim = max_bias_dps
        if lim is None:
            lim = zro_limit(self._row, tc)
        n = self._n
        for k in range(3):
            # output at +-250 dps = bias + 4 LSB per register LSB already in the part
            dps = (self._sum[3 + k] / n - GYRO_STEP * cur[k]) / GYRO_LSB_DPS
            if abs(dps) > lim:
                raise MPUError(
                    "gyro %s reads %+.1f deg/s at rest, more than this %s's zero-rate offset can be "
                    "(+-%.1f deg/s at %.1f degC): was the board turning? Nothing written. (A part outside "
                    "its datasheet: pass max_bias_dps=)" % ("xyz"[k], dps, self._row[NAME], lim, tc / 100.0)
                )

    def trim_changed(self, before, after):
        """The error for offset registers that changed during a capture (read before and after)."""
        return MPUError(
            "offset registers changed during the capture (%r -> %r): the part rewrote its trim "
            "(a known ICM-20602 fault); nothing written, try again" % (before, after)
        )

    def calibrate(self, cur, factory, t, gyro_spread_dps, accel_spread_mg, max_tilt_mg, max_bias_dps, max_turn_dps):
        """After ``capture()``: the offset words [gx, gy, gz, ax, ay, az] that zero the bias, from
        the offsets the part held during it (cur) and its factory trim; raises MPUError on a
        capture that is not usable (the contract is ``MPU6xxx.calibrate``'s docstring)."""
        g, e = self._analyse(cur, factory, t, gyro_spread_dps, accel_spread_mg, max_tilt_mg, max_bias_dps,
                             max_turn_dps)
        n = self._n
        s = self._sum
        words = [0] * 6
        for k in range(3):
            # the output already includes the current register: new = current - bias
            words[k] = clamp_gyro(k, cur[k] + _rdiv(-s[3 + k], GYRO_STEP * n))
            d = s[k] - (e * n if k == g else 0)  # bias * n in +-2 g output LSB: |d| < 2**30
            # the 15-bit field (bits 15..1) counts 2 word LSB = 16 output LSB at +-2 g
            t15 = (cur[3 + k] >> 1) + _rdiv(-d, 2 * ACCEL_STEP * n)
            words[3 + k] = clamp_accel15(k, t15) * 2 | (cur[3 + k] & 1)
        return words

    def bias_point(self, cur, factory, t, gyro_spread_dps, accel_spread_mg, max_tilt_mg, max_bias_dps,
                   max_turn_dps):
        """After ``capture()``, checked as calibrate() checks it: (t, (gx, gy, gz), (ax, ay, az)),
        the register values as floats that would zero the bias now (``MPU6xxx.bias_point``)."""
        g, e = self._analyse(cur, factory, t, gyro_spread_dps, accel_spread_mg, max_tilt_mg, max_bias_dps,
                             max_turn_dps)
        n = self._n
        s = self._sum
        gy = tuple(cur[k] - s[3 + k] / (GYRO_STEP * n) for k in range(3))
        ac = tuple(
            (cur[3 + k] & ~1) - (s[k] - (e * n if k == g else 0)) / (ACCEL_STEP * n) for k in range(3)
        )
        return (t, gy, ac)
