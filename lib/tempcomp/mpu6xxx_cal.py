"""Calibration captures of an MPU-6xxx: FIFO capture at rest, its checks, the offsets it writes.

Loaded on first use by ``MPU6xxx.calibrate()`` and ``MPU6xxx.bias_point()``, never at boot: a
board that only restores its offsets and reads compensated samples (``tempcomp.mpu6xxx``)
keeps this code and the capture buffers off its heap (docs/ram.md has the figures). Use the
methods of ``tempcomp.mpu6xxx.MPU6xxx``; ``Capture`` is its helper, one per part.
"""

from array import array

from tempcomp.mpu6xxx import (
    MAX_PACKETS,
    MIN_PACKETS,
    MPUError,
    _clamp_accel15,
    _clamp_gyro,
    _rdiv,
)
from tempcomp.mpu6xxx_parts import ACCEL_CONFIG2, FIFO_EN_BITS, FIFO_SIZE, GYRO_AT, PACKET

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


# Register map (RM-MPU-6000A / RM-MPU-9250)
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

_GYRO_LSB_DPS = const(131)  # +-250 dps: 131 LSB/dps
_ACCEL_LSB_G = const(16384)  # +-2 g
_GYRO_STEP = const(4)  # one +-1000 dps register LSB = 4 output LSB at +-250 dps
_ACCEL_STEP = const(8)  # one 2048 LSB/g word LSB = 8 output LSB at +-2 g

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


class Capture:
    """The capture state of one MPU6xxx ``m``: FIFO buffers, sums, min/max, configuration."""

    def __init__(self, m):
        self.m = m
        row = m._row
        self._dev = m._dev
        self._row = row
        self._b2 = m._b2
        self._w2 = m._w2
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
        self.m._write_u8(_FIFO_EN, 0)
        self.m._write_u8(_USER_CTRL, _USER_FIFO_RST)  # drop our packets from the FIFO
        d.write(_SMPLRT_DIV, cfg[:n])
        self.m._write_u8(_FIFO_EN, fifo_en)
        self.m._write_u8(_INT_ENABLE, int_en)
        self.m._write_u8(_USER_CTRL, ctl[0] & ~_USER_RESETS)
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
        self.m._write_u8(_INT_ENABLE, 0)
        self.m._write_u8(_FIFO_EN, 0)
        self.m._write_u8(_USER_CTRL, _USER_FIFO_RST)  # FIFO off and empty, I2C master off
        cfg = bytearray(5)  # SMPLRT_DIV 0, CONFIG, GYRO_CONFIG +-250 dps, ACCEL_CONFIG +-2 g
        cfg[1] = _CAL_CONFIG
        cfg[4] = _CAL_ACCEL2
        d.write(_SMPLRT_DIV, cfg[: self._ncfg])
        self.m._write_u8(_USER_CTRL, _USER_FIFO_EN)
        self.m._write_u8(_FIFO_EN, self._row[FIFO_EN_BITS])

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
            self.m._write_u8(_USER_CTRL, _USER_FIFO_EN | _USER_FIFO_RST)
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
        a = self.m.temp_raw()
        for _ in range(_READS):
            b = self.m.temp_raw()
            if -_T_AGREE <= b - a <= _T_AGREE:
                return b
            a = b
        raise MPUError("TEMP_OUT read differently %d times in a row (bus noise?)" % (_READS + 1))

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
        fac = self.m.factory
        m = [s[j] // n - ((cur[3 + j] >> 1) - (fac[j] >> 1)) * 2 * _ACCEL_STEP for j in range(3)]
        g = 0
        for j in (1, 2):
            if abs(m[j]) > abs(m[g]):
                g = j
        mg = [m[j] * 1000 // _ACCEL_LSB_G for j in range(3)]
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
            lim = self.m.zro_limit_dps(t)
        n = self._n
        for k in range(3):
            # output at +-250 dps = bias + 4 LSB per register LSB already in the part
            dps = (self._sum[3 + k] / n - _GYRO_STEP * cur[k]) / _GYRO_LSB_DPS
            if abs(dps) > lim:
                raise MPUError(
                    "gyro %s reads %+.1f deg/s at rest, more than this %s's zero-rate offset can be "
                    "(+-%.1f deg/s at %.1f degC): was the board turning? Nothing written. (A part outside "
                    "its datasheet: pass max_bias_dps=)" % ("xyz"[k], dps, self.m.part, lim,
                                                             self.m.temp_c100(t) / 100.0)
                )

    def _capture_at_rest(self, packets, settle_ms):
        # -> (temperature, offsets held); the offsets must not change during the capture (an
        # ICM-20602 rewriting its trim mid-capture would mix two biases)
        before = self.m._read_offsets()
        t = self._capture(packets, settle_ms)
        cur = self.m._read_offsets()
        if cur != before:
            self.m.trim_changes += 1
            raise MPUError(
                "offset registers changed during the capture (%r -> %r): the part rewrote its trim "
                "(a known ICM-20602 fault); nothing written, try again" % (before, cur)
            )
        return t, cur

    def calibrate(self, packets=1000, settle_ms=50, gyro_spread_dps=5, accel_spread_mg=150, max_tilt_mg=150,
                  max_bias_dps=None, max_turn_dps=1):
        """The body of ``MPU6xxx.calibrate`` (its docstring is the contract)."""
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
        self.m._write_offsets(words)
        self.m._target = words
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
