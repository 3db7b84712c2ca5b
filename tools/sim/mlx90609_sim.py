"""Register-accurate simulated Melexis MLX90609 (SPI model for tools/sim/buses.SimSPI).

MicroPython-compatible (no CPython-only imports) so it runs in pytest, in the MicroPython VM
and on the virtual board. Written from the AN2 note and reference/sensor-facts.md, NOT from
tempcomp.mlx90609: the EEPROM encoder below places bits by AN2 figure 3 and the
conversion answers follow the part's transfer function, so decoding and compensation are
tested against an independent model.

The simulated part is described by physical values: TEMPOUT (mV) at -40, 25 and 85 degC,
ZRO (mV) and SF (relative to S0) at those temperatures, an extra between-point curvature
(a cubic that vanishes at the three table temperatures, as a real part's drift is not exactly
quadratic), a supply shift of the ZRO (mV), and a true rate and temperature. ::

    sim = MLX90609Sim(version=2, full_scale_dps=150)
    spi, cs = on_simspi(sim)          # a buses.SimSPI and the SimPin wired as its chip select
    sim.set_state(rate_dps=10.0, temp_c=60.0)
    sim.refuse(3)                     # the next 3 instructions are refused
    sim.flip(0x45, 1)                 # flip EEPROM bit 1 of cell 0x45

Conversions: ADCC samples the state (or the next entry of a schedule of states, precomputed
to integer codes so the transfer path allocates nothing) and EOC rises after
``conversion_exchanges`` further instructions (~24 us each at 1 MHz: 5 ~ the 115 us of the
datasheet). Answers: 24-bit frames, instruction byte then a 16-bit answer MSB first.
"""

# --- AN2 figure 3, field by field: (first cell, cells, bit positions holding copies) ---
LAYOUT = {
    "EE_ZRO0": (0x20, 8, (6,)),
    "EE_ZRO1": (0x28, 8, (6,)),
    "EE_ZRO2": (0x30, 8, (6,)),
    "EE_SF0": (0x38, 8, (6,)),
    "EE_SF1": (0x40, 8, (6,)),
    "EE_SF2": (0x48, 8, (6,)),
    "TC0": (0x38, 16, (0, 1, 2)),
    "TC1": (0x48, 16, (0, 1, 2)),
    "TC2": (0x58, 16, (0, 1, 2)),
    "VERSION": (0x60, 8, (3, 4, 5)),
    "RANGE": (0x68, 8, (0, 1, 2)),
}
VOTED = ("TC0", "TC1", "TC2", "VERSION", "RANGE")

REFUSAL = 0x8400  # bit 15 (refusal) with BUSY (bit 10), datasheet p.13
EOC = 0x2000
STATR = 0x88
ADCR = 0x80
TABLE_TEMPS_C = (-40.0, 25.0, 85.0)  # AN2 section 3: T0, T1, T2


def owned_bits():
    """bytearray(128): per cell, the bits AN2 assigns to a look-up-table field."""
    m = bytearray(128)
    for name in LAYOUT:
        first, n, copies = LAYOUT[name]
        for k in range(n):
            for p in copies:
                m[first + k] |= 1 << p
    return m


def encode_eeprom(version, range_code, tc, ee_zro, ee_sf, seed=12345):
    """EEPROM image (bytearray 128): the fields written where AN2 figure 3 puts them.

    Every bit AN2 does not assign (user area, unused bits of shared cells, cells 0..0x1F)
    gets pseudo-random filler from seed, as real parts carry other data there.
    """
    img = bytearray(128)
    x = seed & 0x7FFFFFFF
    for a in range(128):
        x = (1103515245 * x + 12345) & 0x7FFFFFFF
        img[a] = (x >> 16) & 0xFF
    values = {
        "VERSION": version,
        "RANGE": range_code,
        "TC0": tc[0],
        "TC1": tc[1],
        "TC2": tc[2],
        "EE_ZRO0": ee_zro[0],
        "EE_ZRO1": ee_zro[1],
        "EE_ZRO2": ee_zro[2],
        "EE_SF0": ee_sf[0],
        "EE_SF1": ee_sf[1],
        "EE_SF2": ee_sf[2],
    }
    for name in values:
        first, n, copies = LAYOUT[name]
        v = values[name]
        if not 0 <= v < (1 << n):
            raise ValueError("%s = %r does not fit in %d bits" % (name, v, n))
        for k in range(n):
            bit = (v >> k) & 1
            for p in copies:
                img[first + k] = (img[first + k] & ~(1 << p)) | (bit << p)
    return img


# --- AN2 section 3.4, typed from the note's table ---
def note_zro(version, ee, output):
    """Physical ZRO of an EE_ZRO byte: mV (analog) or LSB (digital), AN2 section 3.4."""
    if version == 1:
        return 2400 + ee if output == "analog" else 960 + ee * 12 / 25
    return 2300 + 400 * ee / 255 if output == "analog" else 912 + 192 * ee / 255


def note_sf(ee, s0):
    return (0.95 + ee / 2560) * s0


def ee_from_zro_mv(version, zro_mv):
    """The factory's encoding of a measured ZRO (mV) into EE_ZRO (inverse of the note's formula)."""
    if version == 1:
        e = int(round(zro_mv - 2400))
    else:
        e = int(round((zro_mv - 2300) * 255 / 400))
    if not 0 <= e <= 255:
        raise ValueError("ZRO %r mV is not representable in version %d" % (zro_mv, version))
    return e


def ee_from_sf_rel(sf_rel):
    e = int(round((sf_rel - 0.95) * 2560))
    if not 0 <= e <= 255:
        raise ValueError("SF/S0 = %r is not representable (0.95 .. 1.0496)" % (sf_rel,))
    return e


def an2_quadratic(tc, y, t):
    """AN2 equations 3-13 exactly as printed, in float (the reference for the tests).

    tc: (TC0, TC1, TC2); y: (Y0, Y1, Y2) the ZRO or SF triplet values; t: TEMPOUT (a number
    or a numpy array). Returns A*t**2 + B*t + C.
    """
    TC0, TC1, TC2 = float(tc[0]), float(tc[1]), float(tc[2])
    Y0, Y1, Y2 = y
    T0 = TC1 - TC0  # (11)
    T1 = TC2 - TC1  # (12)
    T2 = TC0 - TC2  # (13)
    D = T0 * T1 * T2
    A = -(Y0 * T1 + Y1 * T2 + Y2 * T0) / D  # (5), (8)
    B = (Y0 * T1 * (TC2 + TC1) + Y1 * T2 * (TC0 + TC2) + Y2 * T0 * (TC1 + TC0)) / D  # (6), (9)
    C = -(Y0 * T1 * TC1 * TC2 + Y1 * T2 * TC2 * TC0 + Y2 * T0 * TC0 * TC1) / D  # (7), (10)
    return A * t * t + B * t + C  # (3), (4)


def _lagrange(xs, ys, x):
    x0, x1, x2 = xs
    y0, y1, y2 = ys
    return (
        y0 * (x - x1) * (x - x2) / ((x0 - x1) * (x0 - x2))
        + y1 * (x - x0) * (x - x2) / ((x1 - x0) * (x1 - x2))
        + y2 * (x - x0) * (x - x1) / ((x2 - x0) * (x2 - x1))
    )


class MLX90609Sim:
    """One simulated MLX90609: EEPROM, ADC, refusals and bit flips (SPI model)."""

    def __init__(
        self,
        version=2,
        full_scale_dps=75,
        tc_mv=(1850, 2500, 3100),
        zro_mv=(2478.0, 2500.0, 2531.0),
        sf_rel=(0.972, 1.0, 1.021),
        zro_bump_mv=1.5,
        sf_bump_rel=0.002,
        supply_shift_mv=0.0,
        conversion_exchanges=5,
        seed=12345,
    ):
        self.version = version
        self.full_scale_dps = full_scale_dps
        self.tc_mv = tuple(tc_mv)
        self.zro_mv = tuple(zro_mv)
        self.sf_rel = tuple(sf_rel)
        self.zro_bump_mv = zro_bump_mv
        self.sf_bump_rel = sf_bump_rel
        self.supply_shift_mv = supply_shift_mv
        self.conversion_exchanges = conversion_exchanges
        self.s0_mv = 2000.0 / full_scale_dps  # +-2 V swing at full scale
        ee_z = [ee_from_zro_mv(version, z) if version in (1, 2, 3, 255) else 0 for z in zro_mv]
        ee_s = [ee_from_sf_rel(s) for s in sf_rel]
        self.ee_zro = tuple(ee_z)
        self.ee_sf = tuple(ee_s)
        self.ee = encode_eeprom(version, full_scale_dps // 5, self.tc_mv, ee_z, ee_s, seed)
        # cubic through zero at the three TEMPOUT points, scaled to peak 1 between TC0 and TC2
        lo, hi = min(self.tc_mv), max(self.tc_mv)
        peak = 0.0
        for i in range(201):
            u = lo + (hi - lo) * i / 200
            peak = max(peak, abs(self._cubic(u)))
        self._bump_norm = peak if peak > 0 else 1.0
        self.refusals = 0
        self.refuse_instr = None
        self._pos = 0
        self._answer = 0
        self._busy = 0
        self._result = 0
        self._eoc = False
        self._aden = False
        self.instructions = 0
        self.set_state(0.0, 25.0)

    # --- physics ---
    def _cubic(self, u):
        t0, t1, t2 = self.tc_mv
        return (u - t0) * (u - t1) * (u - t2)

    def tempout_mv(self, temp_c):
        """TEMPOUT (mV, float) at temp_c: through the table's TC at -40/25/85 degC."""
        return _lagrange(TABLE_TEMPS_C, self.tc_mv, temp_c)

    def zro_true_mv(self, u):
        """The part's true ZRO (mV) at TEMPOUT u mV, including the supply shift."""
        b = self._cubic(u) / self._bump_norm
        return _lagrange(self.tc_mv, self.zro_mv, u) + self.zro_bump_mv * b + self.supply_shift_mv

    def sf_true_mv(self, u):
        """The part's true scale factor, mV per deg/s, at TEMPOUT u mV."""
        b = self._cubic(u) / self._bump_norm
        return (_lagrange(self.tc_mv, self.sf_rel, u) + self.sf_bump_rel * b) * self.s0_mv

    def output_mv(self, rate_dps, temp_c):
        u = self.tempout_mv(temp_c)
        return self.zro_true_mv(u) + self.sf_true_mv(u) * rate_dps

    @staticmethod
    def _code(mv, offset_mv, per_mv):
        c = int(round((mv - offset_mv) * per_mv))
        return 0 if c < 0 else 2047 if c > 2047 else c

    def codes(self, rate_dps, temp_c):
        """(rate code, temperature code) the ADC converts for this state."""
        rc = self._code(self.output_mv(rate_dps, temp_c), 400.0, 12.0 / 25.0)
        tc = self._code(self.tempout_mv(temp_c), 300.0, 16.0 / 25.0)
        return rc, tc

    def set_state(self, rate_dps, temp_c):
        """True rate (deg/s) and die temperature (degC) from now on."""
        self.schedule([(rate_dps, temp_c)])

    def schedule(self, states):
        """Cycle through (rate_dps, temp_c) states, one per conversion of each channel."""
        rc = []
        tcs = []
        for r, t in states:
            a, b = self.codes(r, t)
            rc.append(a)
            tcs.append(b)
        self._rate_codes = rc
        self._temp_codes = tcs
        self._ri = 0
        self._ti = 0

    # --- fault injection ---
    def refuse(self, n=1, instr=None):
        """Refuse the next n instructions (n < 0: forever), or only those equal to instr."""
        self.refusals = n
        self.refuse_instr = instr

    def flip(self, addr, bit):
        """Toggle one EEPROM bit."""
        self.ee[addr] ^= 1 << bit

    # --- SPI model ---
    def select(self):
        self._pos = 0

    def deselect(self):
        self._pos = 0  # /SS high resets the exchange (datasheet p.9)

    def transfer(self, out):
        into = bytearray(len(out))
        self.transfer_into(out, into)
        return bytes(into)

    def transfer_into(self, out, into):
        """Clock len(out) bytes; allocation-free."""
        i = 0
        n = len(out)
        while i < n:
            p = self._pos
            if p == 0:
                into[i] = 0
                self._answer = self._execute(out[i])
                self._pos = 1
            elif p == 1:
                into[i] = self._answer >> 8
                self._pos = 2
            else:
                into[i] = self._answer & 0xFF
                self._pos = 0
            i += 1

    def _status(self):
        return EOC if self._eoc else 0

    def _execute(self, instr):
        self.instructions += 1
        if self._busy > 0:
            self._busy -= 1
            if self._busy == 0:
                self._eoc = True
        if self.refusals != 0 and (self.refuse_instr is None or self.refuse_instr == instr):
            if self.refusals > 0:
                self.refusals -= 1
            return REFUSAL
        if not instr & 0x80:  # EER: cell byte in the low byte of the answer
            return self.ee[instr]
        if instr == STATR:
            return self._status()
        if instr & 0xF3 == 0x90:  # ADCC 0b1001_CHAN_ADEN_00
            if instr & 0x04:
                if self._busy > 0:
                    return REFUSAL  # a conversion is still running
                self._aden = True
                self._eoc = False
                if instr & 0x08:
                    self._result = self._temp_codes[self._ti]
                    self._ti = (self._ti + 1) % len(self._temp_codes)
                else:
                    self._result = self._rate_codes[self._ri]
                    self._ri = (self._ri + 1) % len(self._rate_codes)
                self._busy = self.conversion_exchanges
                if self._busy == 0:
                    self._eoc = True
            else:
                self._aden = False
            return self._status()
        if instr == ADCR:
            if not self._eoc:
                return 0  # EOC clear: no result yet
            return EOC | (self._result << 1) | 1  # bit 0 is not part of the result
        return REFUSAL  # EEPROM write/erase, mode and other instructions are not modelled


def on_simspi(sim, cs_id=17):
    """A buses.SimSPI with sim wired to a new SimPin (returned as (spi, cs))."""
    try:
        from tools.sim.buses import SimPin, SimSPI
    except ImportError:
        from buses import SimPin, SimSPI
    spi = SimSPI()
    cs = SimPin(cs_id)
    spi.attach(cs, sim)
    return spi, cs


class _MachineStandIn:
    """A ``machine`` module whose SPI() is a SimSPI carrying sim and Pin(cs_id) its chip select."""

    def __init__(self, sim, cs_id):
        spi, cs = on_simspi(sim, cs_id)
        cs_pin = cs
        pin_cls = type(cs)

        def make_spi(*args, **kwargs):
            return spi

        def make_pin(id, mode=None, value=None):
            if id == cs_id:
                if value is not None:
                    cs_pin.value(value)
                return cs_pin
            return pin_cls(id, mode, value)

        self.SPI = make_spi
        self.Pin = _PinFactory(make_pin)


class _PinFactory:
    OUT = 1
    IN = 0

    def __init__(self, make):
        self._make = make

    def __call__(self, id, mode=None, value=None):
        return self._make(id, mode, value)


def machine_for(sim, cs_id=17):
    """Object to install as sys.modules["machine"] so REPL lines reach the simulated part."""
    return _MachineStandIn(sim, cs_id)
