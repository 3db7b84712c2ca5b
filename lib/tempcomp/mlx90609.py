"""Melexis MLX90609 angular rate sensor over SPI, compensated with its factory EEPROM table.

The part stores three "triplets" {TEMPOUT, ZRO, SF} measured at -40, 25 and 85 degC in its
EEPROM (Melexis application note AN2, "Temperature compensation improvement"). This module
reads the 128 cells with the EER instruction, decodes them exactly as AN2 section 3 lays
them out (majority-voted RANGE, VERSION and TC fields, single-copy EE_ZRO/EE_SF bytes), puts
ZRO(TEMPOUT) and SF(TEMPOUT) (AN2 equations 3-13: the quadratic through the three triplets)
into the fixed-point core once, and then returns Omega = (OUT - ZRO) / SF per sample with
integer arithmetic and zero allocation.

Usage (MicroPython; on CircuitPython pass ``busio.SPI`` and ``digitalio.DigitalInOut``)::

    from machine import SPI, Pin
    from tempcomp.mlx90609 import MLX90609
    spi = SPI(0, baudrate=1000000, polarity=1, phase=1, sck=Pin(18), mosi=Pin(19), miso=Pin(16))
    gyro = MLX90609(spi, Pin(17, Pin.OUT, value=1))
    gyro.rate_dps()        # degrees per second, float (REPL convenience)
    gyro.rate()            # milli-degrees per second (1/out_scale), int, zero allocation
    gyro.rezero()          # at rest: removes the supply-voltage ZRO shift (AN2 section 4 note)
    from tempcomp.store import Store
    gyro.save(Store("/tempcomp.cal"))   # table + re-zero; gyro.load(store) re-applies them

A part with VERSION 0 (early 2006 lots) has no table: the driver still reads raw codes
(``rate_code()``, ``tempout_mv()``) for the three-point calibration tools, and the
compensated reads raise ``ValueError`` saying so.

Bounds: AN2's closed forms (equations 5-10) multiply four millivolt-sized values, e.g.
ZRO0*T1*TC1*TC2 ~ 2500 * 600 * 2500 * 3100 ~ 1.2e13 ~ 2**43.4 (2**44 with TC near 4 V), and
even the denominator T0*T1*T2 ~ 650 * 600 * 1250 ~ 2**28.9 nearly fills a 32-bit MicroPython
small int (2**30): an integer evaluation would need 46-bit arithmetic. We never
form them: ``fixedpoint.quadratic_through`` builds the same quadratic from divided differences
(no product of more than two values, about t_ref = TC1 so no cancellation either), at set-up
in float; the per-sample path is the core's, every intermediate below 2**30 (see
``fixedpoint``). The tests compare it with a float64 evaluation of equations 3-13 as printed.
"""

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


# fixedpoint first: from .py its compile (the largest source, 41 KB) is the import's peak, and on
# the 140 KB Cortex-M3 heap, with the files read over mpremote's mount (the RAM bench's route), it
# found no free block once the SPI adapter was compiled before it (MemoryError; 4 KB to spare in
# this order). Read in place as from flash, either order has over 25 KB to spare (docs/ram.md,
# host_tests/interp/test_ram.py).
from tempcomp.fixedpoint import EXTRAPOLATE, Compensator, quadratic_through

# isort: split
from tempcomp.bus_spi import SPIDevice

# --- EEPROM map, AN2 figure 3 and sections 3.1-3.4 (first cell of a field holds its LSB) ---
CELLS = const(128)
_EE_ZRO_FIRST = const(0x20)  # EE_ZRO0..2: bit 6 of 0x20..0x37, 8 cells each (single copy)
_EE_SF_FIRST = const(0x38)  # EE_SF0..2: bit 6 of 0x38..0x4F, 8 cells each (single copy)
_EE_BIT = const(6)
_TC_FIRST = const(0x38)  # TC0..2: bits 0..2 of 0x38..0x67, 16 cells each, voted
_TC_SHIFT = const(0)
_VERSION_FIRST = const(0x60)  # VERSION: bits 3..5 of 0x60..0x67, voted
_VERSION_SHIFT = const(3)
_RANGE_FIRST = const(0x68)  # RANGE: bits 0..2 of 0x68..0x6F, voted; full scale = 5 * RANGE
_RANGE_SHIFT = const(0)
_RANGE_UNIT_DPS = const(5)
_MAJORITY = const(0xE8)  # bit v set when the 3-bit copy pattern v has two or more ones
_KNOWN_VERSIONS = (1, 2, 3, 255)
_VOTED_BITS = const(64)  # RANGE 8 + VERSION 8 + TC 3 x 16
# Vote health: one flipped copy per voted bit is what voting corrects; many disagreeing bits
# mean a failing EEPROM or no table at all (a random image has 48 +- 3.5 of 64). With d
# disagreements out of 64, the expected number of bits whose majority is itself wrong is about
# d**2 / 192 (two of three copies flipped): 0.08 at d = 4, 0.33 at d = 8.
MAX_DISAGREE = const(4)

# --- SPI instructions, datasheet rev 007 p.13 (see reference/sensor-facts.md) ---
_STATR = const(0x88)
_ADCC_RATE = const(0x94)  # 0b1001_CHAN_ADEN_00, CHAN 0 (rate), ADEN 1
_ADCC_TEMP = const(0x9C)  # CHAN 1 (temperature), ADEN 1
_ADCC_SLEEP = const(0x90)
_ADCR = const(0x80)
_EER_MASK = const(0x7F)  # EER: the 7-bit cell address with bit 7 clear
_REFUSED = const(0x8000)  # only a refusal answer has bit 15 set
_EOC = const(0x2000)  # ADCR answer bit 13: conversion finished
_CODE_MASK = const(0x7FF)  # ADCR bits 11..1

# --- transfer functions (reference/sensor-facts.md) ---
# rate mV = 25/12 * code + 400; TEMPOUT mV = 25/16 * code + 300 (rounded to the nearest mV)
_TEMP_NUM = const(25)
_TEMP_SHIFT = const(4)
_TEMP_OFFSET_MV = const(300)
_CODE_MAX = const(2047)
_SWING_MV = const(2000)  # full scale swings the output +-2 V around 2.5 V
_DIGITAL_PER_MV = 12.0 / 25.0  # rate LSB per mV

# --- plausibility of a table (reference/sensor-facts.md; AN2 sections 3.1 and 3.3) ---
# TC0..2 are TEMPOUT in mV at -40, 25 and 85 degC: 2.5 V at 25 degC rising 10 mV/K [C, U].
# They must lie where the part's own TEMPOUT conversion reads (25/16 * code + 300 mV, code
# 0..2047: 300..3498 mV), rise with temperature at a slope within a factor of two of 10 mV/K on
# each step, and put 25 degC within 500 mV (50 K) of 2.5 V.
_TEMPOUT_MIN_MV = const(300)
_TEMPOUT_MAX_MV = const(3498)
_TC_TEMPS = (-40, 25, 85)
_TC_SLOPE_MIN = const(5)  # mV/K
_TC_SLOPE_MAX = const(20)
_TC1_NOMINAL_MV = const(2500)
_TC1_TOLERANCE_MV = const(500)
# Full scale = 5 * RANGE: AN2's ordering table has 75, 150 and 300 deg/s parts; 50..400 leaves
# room for a custom trim and refuses what no MLX90609 is.
_FS_MIN_DPS = const(50)
_FS_MAX_DPS = const(400)

_RETRIES = const(8)  # refusal answers tolerated per instruction
_POLLS = const(200)  # ADCR polls before a conversion counts as stuck (~115 us needed)
_MARGIN_MV = const(150)  # extrapolate 15 K beyond the table, then hold (see compensator())
_CAL_FORMAT = const(1)
_SHIFT_Q = const(256)  # re-zero stored in 1/256 output LSB


class MLX90609Error(OSError):
    """The part refused, did not answer, or did not finish a conversion."""


def _voted(cells, first, n, shift):
    """n-bit value from 2-of-3 voted copies (bits shift..shift+2 of n cells, LSB first)."""
    # accumulators start at 0: AN2's C leaves range/ver/TCnum uninitialised and only works
    # because every bit happens to be shifted through
    value = 0
    disagree = 0
    for k in range(n):
        v = (cells[first + k] >> shift) & 7
        if (_MAJORITY >> v) & 1:
            value |= 1 << k
        if v != 0 and v != 7:
            disagree += 1
    return value, disagree


def _single(cells, first, n, bit):
    value = 0
    for k in range(n):
        if (cells[first + k] >> bit) & 1:
            value |= 1 << k
    return value


class LookupTable:
    """The decoded AN2 table: version, full scale, TC (mV), EE_ZRO and EE_SF bytes."""

    def __init__(self, version, full_scale_dps, tc, ee_zro, ee_sf, vote_disagreements=0):
        self.version = version
        self.full_scale_dps = full_scale_dps
        self.tc = tuple(tc)
        self.ee_zro = tuple(ee_zro)
        self.ee_sf = tuple(ee_sf)
        self.vote_disagreements = vote_disagreements

    def _damage(self):
        d = self.vote_disagreements
        return "; %d voted EEPROM bits disagree (EEPROM damage?)" % d if d else ""

    def check(self):
        """Raise ValueError unless the table can define ZRO(TEMPOUT) and SF(TEMPOUT)."""
        v = self.version
        if v == 0:
            raise ValueError(
                "MLX90609 EEPROM has VERSION 0: this part has no look-up table (early 2006 lot); "
                "calibrate it with the three-point tools (tempcomp three-point calibration) "
                "instead%s" % self._damage()
            )
        if v not in _KNOWN_VERSIONS:
            raise ValueError(
                "MLX90609 EEPROM VERSION %d is unknown (AN2 defines 0, 1, 2, 3 and 255); "
                "ask Melexis for its formulas%s" % (v, self._damage())
            )
        tc = self.tc
        for i, j in ((0, 1), (1, 2), (0, 2)):
            if tc[i] == tc[j]:
                raise ValueError(
                    "degenerate MLX90609 table: TC%d = TC%d = %d mV, so T0*T1*T2 = 0 in AN2 "
                    "equations 5-13 and no quadratic passes through the triplets%s" % (i, j, tc[i], self._damage())
                )
        for i in range(3):
            if not _TEMPOUT_MIN_MV <= tc[i] <= _TEMPOUT_MAX_MV:
                raise ValueError(
                    "implausible MLX90609 table: TC%d = %d mV (TEMPOUT at %d degC) is outside what the "
                    "part's TEMPOUT spans (%d..%d mV)%s"
                    % (i, tc[i], _TC_TEMPS[i], _TEMPOUT_MIN_MV, _TEMPOUT_MAX_MV, self._damage())
                )
        for i in (0, 1):
            dk = _TC_TEMPS[i + 1] - _TC_TEMPS[i]
            slope = (tc[i + 1] - tc[i]) / dk
            if not _TC_SLOPE_MIN <= slope <= _TC_SLOPE_MAX:
                raise ValueError(
                    "implausible MLX90609 table: TEMPOUT goes from %d mV (TC%d, %d degC) to %d mV (TC%d, "
                    "%d degC), %.1f mV/K; the sensor rises about 10 mV/K (accepted %d..%d)%s"
                    % (tc[i], i, _TC_TEMPS[i], tc[i + 1], i + 1, _TC_TEMPS[i + 1], slope, _TC_SLOPE_MIN,
                       _TC_SLOPE_MAX, self._damage())
                )
        if abs(tc[1] - _TC1_NOMINAL_MV) > _TC1_TOLERANCE_MV:
            raise ValueError(
                "implausible MLX90609 table: TC1 = %d mV at 25 degC; TEMPOUT is about %d mV there "
                "(accepted +-%d)%s" % (tc[1], _TC1_NOMINAL_MV, _TC1_TOLERANCE_MV, self._damage())
            )
        fs = self.full_scale_dps
        if not _FS_MIN_DPS <= fs <= _FS_MAX_DPS:
            raise ValueError(
                "implausible MLX90609 table: RANGE gives a full scale of %d deg/s; parts are made for "
                "75, 150 or 300 (accepted %d..%d)%s" % (fs, _FS_MIN_DPS, _FS_MAX_DPS, self._damage())
            )
        for name, vals in (("ee_zro", self.ee_zro), ("ee_sf", self.ee_sf)):
            for x in vals:
                if not 0 <= x <= 255:
                    raise ValueError("%s byte %r outside 0..255" % (name, x))

    def zro(self, output="digital"):
        """(ZRO0, ZRO1, ZRO2): mV for output "analog", ADC LSB for "digital" (AN2 section 3.4)."""
        e = self.ee_zro
        if self.version == 1:
            if output == "analog":
                return (2400.0 + e[0], 2400.0 + e[1], 2400.0 + e[2])
            if output == "digital":
                return (960.0 + e[0] * 12 / 25.0, 960.0 + e[1] * 12 / 25.0, 960.0 + e[2] * 12 / 25.0)
        else:
            self.check()
            if output == "analog":
                return (2300.0 + 400 * e[0] / 255.0, 2300.0 + 400 * e[1] / 255.0, 2300.0 + 400 * e[2] / 255.0)
            if output == "digital":
                return (912.0 + 192 * e[0] / 255.0, 912.0 + 192 * e[1] / 255.0, 912.0 + 192 * e[2] / 255.0)
        raise ValueError('output must be "analog" (mV) or "digital" (LSB), got %r' % (output,))

    def sf(self, s0):
        """(SF0, SF1, SF2) = (0.95 + EE_SF/2560) * s0, in s0's unit (AN2 section 3.4)."""
        self.check()
        e = self.ee_sf
        return ((0.95 + e[0] / 2560.0) * s0, (0.95 + e[1] / 2560.0) * s0, (0.95 + e[2] / 2560.0) * s0)

    def s0(self, output="digital"):
        """Typical scale factor for this RANGE: mV/(deg/s) analog, LSB/(deg/s) digital."""
        fs = self.full_scale_dps
        if fs <= 0:
            raise ValueError("MLX90609 RANGE is 0: no full scale to derive the scale factor from")
        s = _SWING_MV / fs
        if output == "analog":
            return s
        if output == "digital":
            return s * _DIGITAL_PER_MV
        raise ValueError('output must be "analog" (mV) or "digital" (LSB), got %r' % (output,))

    def to_ints(self):
        """The table as ints (for tempcomp.store): version, full scale, TC x3, EE_ZRO x3, EE_SF x3."""
        return (self.version, self.full_scale_dps) + self.tc + self.ee_zro + self.ee_sf

    @classmethod
    def from_ints(cls, ints):
        """Inverse of to_ints(); raises ValueError on a wrong length or an unusable table."""
        if len(ints) != 11:
            raise ValueError("an MLX90609 table is 11 ints, got %d" % len(ints))
        t = cls(ints[0], ints[1], ints[2:5], ints[5:8], ints[8:11])
        t.check()
        return t


def decode_eeprom(cells, max_disagree=MAX_DISAGREE):
    """Decode the 128 EEPROM bytes (cell i at index i) into a LookupTable (AN2 section 3).

    Raises ValueError for VERSION 0 (no table), an unknown VERSION, more than max_disagree of
    the 64 voted bits not unanimous, or a table no MLX90609 has (TC outside TEMPOUT's span,
    not rising about 10 mV/K, full scale outside 50..400 deg/s, degenerate).
    ``vote_disagreements`` counts voted bits whose three copies were not unanimous: 0 on a
    healthy part; a growing count means the EEPROM is degrading (one flipped copy is still
    corrected, two are not).
    """
    if len(cells) != CELLS:
        raise ValueError("need the %d MLX90609 EEPROM cells, got %d" % (CELLS, len(cells)))
    rng, d = _voted(cells, _RANGE_FIRST, 8, _RANGE_SHIFT)
    version, dv = _voted(cells, _VERSION_FIRST, 8, _VERSION_SHIFT)
    d += dv
    tc = []
    for i in range(3):
        v, dv = _voted(cells, _TC_FIRST + 16 * i, 16, _TC_SHIFT)
        tc.append(v)
        d += dv
    ee_zro = [_single(cells, _EE_ZRO_FIRST + 8 * i, 8, _EE_BIT) for i in range(3)]
    ee_sf = [_single(cells, _EE_SF_FIRST + 8 * i, 8, _EE_BIT) for i in range(3)]
    if d > max_disagree:
        raise ValueError(
            "MLX90609 EEPROM: %d of the %d voted bits (RANGE, VERSION, TC) disagree between their "
            "three copies (accepted %d): the EEPROM is failing or holds no AN2 table; calibrate with "
            "the three-point tools instead" % (d, _VOTED_BITS, max_disagree)
        )
    table = LookupTable(version, rng * _RANGE_UNIT_DPS, tc, ee_zro, ee_sf, d)
    table.check()
    return table


def _quadratics(table, output):
    tc = table.tc
    z = table.zro(output)
    s = table.sf(table.s0(output))
    off = quadratic_through((tc[0], z[0]), (tc[1], z[1]), (tc[2], z[2]), tc[1])
    sc = quadratic_through((tc[0], s[0]), (tc[1], s[1]), (tc[2], s[2]), tc[1])
    return off, sc


def compensator(table, output="digital", out_scale=1000, margin_mv=_MARGIN_MV):
    """A fixedpoint.Compensator giving out_scale * (OUT - ZRO(t)) / SF(t), t = TEMPOUT in mV.

    OUT is the ADC code (0..2047) for "digital" or millivolts (0..5000) for "analog". Between
    TC0 and TC2 the quadratic is the table's; up to margin_mv beyond it is extrapolated; farther
    out ZRO and SF are held at that edge and ``Compensator.clamped`` counts the readings.
    """
    off, sc = _quadratics(table, output)
    lo = min(table.tc)
    hi = max(table.tc)
    raw_range = (0, _CODE_MAX) if output == "digital" else (0, 5000)
    return Compensator(
        [off],
        [sc],
        t_cal=(lo, hi),
        t_in=(lo - margin_mv, hi + margin_mv),
        out_scale=out_scale,
        raw_range=raw_range,
        policy=EXTRAPOLATE,
        t_ref=table.tc[1],
    )


class MLX90609:
    """MLX90609 on an SPI bus (mode 3, <= 1 MHz) with chip select cs.

    Reads the EEPROM table at construction. ``rate()`` returns compensated rate in
    1/out_scale deg/s (default milli-deg/s) and reads TEMPOUT every ``temp_every`` samples.
    """

    def __init__(self, spi, cs, out_scale=1000, baudrate=1000000, retries=_RETRIES):
        self._dev = SPIDevice(spi, cs, baudrate, 1, 1)
        self._out = bytearray(3)
        self._in = bytearray(3)
        self.retries = retries
        self.refusals = 0
        self.out_scale = out_scale
        self.temp_every = 1
        self._count = 0
        self.zro_shift = 0.0  # re-zero, ADC LSB added to ZRO(TEMPOUT)
        self.cells = bytearray(CELLS)
        self.read_eeprom(self.cells)
        self._comp = None
        self._zro_q = None
        self.table = None
        self.table_error = None  # why the EEPROM gave no table (a ValueError), None when it did
        try:
            table = decode_eeprom(self.cells)
        except ValueError as e:
            self.table_error = e
        else:
            self.use_table(table)

    # --- bus ---
    def _word(self, instr):
        o = self._out
        o[0] = instr
        i = self._in
        self._dev.exchange(o, i)
        return i[1] << 8 | i[2]

    def _answer(self, instr):
        # retried refusals; -1 after self.retries of them (the caller names what was refused)
        n = 0
        while True:
            w = self._word(instr)
            if not w & _REFUSED:
                return w
            self.refusals += 1
            n += 1
            if n > self.retries:
                return -1

    def read_eeprom(self, cells):
        """Read all 128 cells with EER into cells (a bytearray of 128)."""
        for a in range(CELLS):
            w = self._answer(a & _EER_MASK)
            if w < 0:
                raise MLX90609Error(
                    "MLX90609 refused EER of EEPROM cell 0x%02X %d times (or no part answers "
                    "on this chip select: MISO reads all ones)" % (a, self.retries + 1)
                )
            cells[a] = w & 0xFF

    def _convert(self, adcc):
        if self._answer(adcc) < 0:
            raise MLX90609Error("MLX90609 refused ADCC 0x%02X %d times" % (adcc, self.retries + 1))
        n = 0
        while n < _POLLS:
            w = self._word(_ADCR)
            if w & _REFUSED:
                self.refusals += 1
            elif w & _EOC:
                return (w >> 1) & _CODE_MASK
            n += 1
        raise MLX90609Error("MLX90609 ADC conversion (ADCC 0x%02X) not finished after %d ADCR polls" % (adcc, _POLLS))

    def rate_code(self):
        """Raw 11-bit rate ADC code (0..2047; 25/12 mV per code + 400 mV)."""
        return self._convert(_ADCC_RATE)

    def temperature_code(self):
        """Raw 11-bit TEMPOUT ADC code."""
        return self._convert(_ADCC_TEMP)

    def tempout_mv(self):
        """TEMPOUT in mV (integer, the unit of the table's TC values)."""
        return ((self._convert(_ADCC_TEMP) * _TEMP_NUM + 8) >> _TEMP_SHIFT) + _TEMP_OFFSET_MV

    def sleep(self):
        """Put the ADC to sleep (ADCC with ADEN 0); the next conversion wakes it."""
        if self._answer(_ADCC_SLEEP) < 0:
            raise MLX90609Error("MLX90609 refused ADCC sleep")

    # --- compensation ---
    def use_table(self, table, zro_shift=0.0):
        """Compensate with table (a LookupTable) plus a re-zero shift in LSB; atomic."""
        comp = compensator(table, "digital", self.out_scale)
        if zro_shift:
            comp.shift_offset(0, zro_shift)
        off, _ = _quadratics(table, "digital")
        # all checks passed: switch over in one step
        self._comp = comp
        self._zro_q = off
        self.table = table
        self.table_error = None
        self.zro_shift = float(zro_shift)
        self._count = 0

    def _need_table(self):
        if self._comp is None:
            raise ValueError(str(self.table_error) if self.table_error else "MLX90609: no table")
        return self._comp

    def _table(self):
        t = self.table
        if t is None:
            self._need_table()
            raise ValueError("MLX90609: no table")
        return t

    def rate(self):
        """Compensated rate in 1/out_scale deg/s (int); zero allocation."""
        comp = self._comp
        if comp is None:
            comp = self._need_table()
        self._count -= 1
        if self._count <= 0:
            self._count = self.temp_every
            comp.update(self.tempout_mv())
        return comp.apply(self._convert(_ADCC_RATE))

    def rate_dps(self):
        """Compensated rate in deg/s (float: allocates; for the REPL)."""
        return self.rate() / self.out_scale

    def zro_at(self, tempout_mv):
        """ZRO(TEMPOUT) in LSB including the re-zero shift (float, set-up use)."""
        u = tempout_mv - self._table().tc[1]
        c = self._zro_q or (0.0, 0.0, 0.0)
        return c[0] + (c[1] + c[2] * u) * u + self.zro_shift

    def rezero(self, samples=64):
        """At zero rate: measure OUT and add OUT - ZRO(TEMPOUT) to ZRO from now on (AN2 note).

        Returns the shift in LSB. The part must be still. A bus fault leaves the old zero.
        """
        comp = self._need_table()
        if samples < 1:
            raise ValueError("samples must be >= 1, got %r" % (samples,))
        st = 0
        so = 0
        for _ in range(samples):
            st += self.tempout_mv()
            so += self._convert(_ADCC_RATE)
        t = st / samples
        delta = so / samples - self.zro_at(t)
        comp.shift_offset(0, delta)
        self.zro_shift += delta
        return delta

    def health(self):
        """dict: voted EEPROM bits not unanimous, refusals seen, TEMPOUT readings out of range."""
        return {
            "vote_disagreements": self.table.vote_disagreements if self.table else None,
            "refusals": self.refusals,
            "tempout_clamped": self._comp.clamped if self._comp else 0,
        }

    # --- persistence (tempcomp.store takes a name and a sequence of int32) ---
    def calibration_ints(self):
        """(format, table ints..., re-zero in 1/256 LSB) for Store.save()."""
        table = self._table()
        q = self.zro_shift * _SHIFT_Q
        q = int(q + 0.5) if q >= 0 else -int(-q + 0.5)
        return (_CAL_FORMAT,) + table.to_ints() + (q,)

    def save(self, store, name="mlx90609"):
        """Save table and re-zero through a tempcomp.store.Store, as kind KIND_MLX_REZERO (1)."""
        store.save_record(name, self.calibration_ints(), part="MLX90609", kind=1)

    def load(self, store, name="mlx90609"):
        """Re-apply what save() stored (KeyError if never saved; ValueError keeps the old state)."""
        self.apply_calibration_ints(store.load(name))

    def apply_calibration_ints(self, ints):
        """Re-apply what calibration_ints() returned; ValueError (old state kept) if unusable."""
        if len(ints) != 13 or ints[0] != _CAL_FORMAT:
            raise ValueError("not an MLX90609 calibration record (format %d, 13 ints)" % _CAL_FORMAT)
        table = LookupTable.from_ints(ints[1:12])
        self.use_table(table, ints[12] / _SHIFT_Q)
