"""MLX90609: EEPROM decoding, driver, compensation, against the independent simulated part.

References: the AN2 encoder and forward formulas in tools/sim/mlx90609_sim.py (written from the
note's figure 3 and section 3.4), the part's transfer function there, and AN2 equations 3-13
evaluated literally in float64 below.
"""

import os
import random
import re
import sys

import interps
import numpy as np
import pytest
import seeds
from paths import REPO

from tempcomp import mlx90609 as mlx
from tempcomp.mlx90609 import MLX90609, MLX90609Error, compensator, decode_eeprom
from tools.firmware import mpvm as _mpvm
from tools.sim import blinka
from tools.sim import mlx90609_sim as ms

VERSIONS = (1, 2, 3, 255)
OPTION_CODES = {"N2": 75, "E2": 150, "R2": 300}  # AN2 section 3.1 ordering table


def random_fields(rnd):
    """A random table a real MLX90609 could hold: full scale 50..400 deg/s, TEMPOUT 2.0..3.0 V at
    25 degC rising 5..20 mV/K (what decode_eeprom accepts; see test_plausibility_limits)."""
    v = rnd.choice(VERSIONS)
    rng = rnd.randint(10, 80)
    while True:
        t1 = rnd.randint(2000, 3000)
        tc = [t1 - rnd.randint(65 * 5, 65 * 20), t1, t1 + rnd.randint(60 * 5, 60 * 20)]
        if 300 <= tc[0] and tc[2] <= 3498:
            break
    ee_z = [rnd.randint(0, 255) for _ in range(3)]
    ee_s = [rnd.randint(0, 255) for _ in range(3)]
    return v, rng, tc, ee_z, ee_s


# ---------------------------------------------------------------- decoding


def test_decode_matches_independent_encoder_random_tables():
    rnd = random.Random(seeds.seed("mlx_tables"))
    seen = set()
    for n in range(400):
        v, rng, tc, ee_z, ee_s = random_fields(rnd)
        seen.add(v)
        img = ms.encode_eeprom(v, rng, tc, ee_z, ee_s, seed=n)
        t = decode_eeprom(img)
        assert (t.version, t.full_scale_dps) == (v, 5 * rng)
        assert list(t.tc) == tc and list(t.ee_zro) == ee_z and list(t.ee_sf) == ee_s
        assert t.vote_disagreements == 0
        for output in ("analog", "digital"):
            assert t.zro(output) == pytest.approx([ms.note_zro(v, e, output) for e in ee_z], abs=1e-9)
        s0 = rnd.uniform(1.0, 30.0)
        assert t.sf(s0) == pytest.approx([ms.note_sf(e, s0) for e in ee_s], rel=1e-12)
    assert seen == set(VERSIONS)


@pytest.mark.parametrize("version", VERSIONS)
def test_physical_values_survive_encoding(version):
    # the factory encodes a measured ZRO/SF; decoding must give it back within half a step,
    # in mV (analog) and, through the part's 12/25 LSB per mV, in LSB (digital)
    zro = (2481.3, 2500.2, 2533.9) if version == 1 else (2402.7, 2500.0, 2611.1)
    sf = (0.9612, 1.0, 1.0317)
    sim = ms.MLX90609Sim(version=version, full_scale_dps=150, zro_mv=zro, sf_rel=sf)
    t = decode_eeprom(sim.ee)
    step_mv = 1.0 if version == 1 else 400 / 255
    for got, want in zip(t.zro("analog"), zro):
        assert abs(got - want) <= step_mv / 2 + 1e-9
    for got, want in zip(t.zro("digital"), zro):
        assert abs(got - (want - 400) * 12 / 25) <= step_mv * 12 / 25 / 2 + 1e-9
    s0 = 2000 / 150 * 12 / 25  # LSB per deg/s
    assert t.s0("digital") == pytest.approx(6.4)
    for got, want in zip(t.sf(s0), sf):
        assert abs(got - want * s0) <= s0 / 2560 / 2 + 1e-12


@pytest.mark.parametrize("code", sorted(OPTION_CODES))
def test_range_of_option_codes(code):
    fs = OPTION_CODES[code]
    t = decode_eeprom(ms.MLX90609Sim(full_scale_dps=fs).ee)
    assert t.full_scale_dps == fs
    # sensor-facts: +-2 V swing at full scale; 12.8 LSB/(deg/s) for the 75 deg/s part
    assert t.s0("analog") == pytest.approx(2000 / fs)
    assert t.s0("digital") == pytest.approx({75: 12.8, 150: 6.4, 300: 3.2}[fs])


def _fields(t):
    return (t.version, t.full_scale_dps, t.tc, t.ee_zro, t.ee_sf)


def test_every_single_flip_of_every_voted_copy_is_corrected():
    rnd = random.Random(seeds.seed("mlx_tables_2"))
    for n in range(4):
        v, rng, tc, ee_z, ee_s = random_fields(rnd)
        img = ms.encode_eeprom(v, rng, tc, ee_z, ee_s, seed=n)
        want = _fields(decode_eeprom(img))
        flips = 0
        for name in ms.VOTED:
            first, cells, copies = ms.LAYOUT[name]
            for k in range(cells):
                for p in copies:
                    bad = bytearray(img)
                    bad[first + k] ^= 1 << p
                    t = decode_eeprom(bad)
                    assert _fields(t) == want, (name, k, p)
                    assert t.vote_disagreements == 1
                    flips += 1
        assert flips == 64 * 3
        # bits AN2 does not assign to the table never matter
        owned = ms.owned_bits()
        for a in range(128):
            for b in range(8):
                if not owned[a] >> b & 1:
                    bad = bytearray(img)
                    bad[a] ^= 1 << b
                    t = decode_eeprom(bad)
                    assert _fields(t) == want and t.vote_disagreements == 0


def test_two_flips_in_one_vote_show_in_the_health_figure():
    img = ms.MLX90609Sim(version=2, full_scale_dps=150, tc_mv=(1843, 2497, 3109)).ee
    ref = decode_eeprom(img)
    for name in ms.VOTED:
        first, cells, copies = ms.LAYOUT[name]
        for k in range(cells):
            for drop in range(3):
                bad = bytearray(img)
                for i, p in enumerate(copies):
                    if i != drop:
                        bad[first + k] ^= 1 << p
                try:
                    t = decode_eeprom(bad)
                except ValueError as e:
                    # the flipped bit made the table unusable: the error says the EEPROM is damaged
                    assert "1 voted EEPROM bits disagree" in str(e), (name, k)
                    continue
                assert t.vote_disagreements == 1, (name, k)
                assert _fields(t) != _fields(ref)  # the majority is wrong now: only health shows it


def test_unvoted_zro_sf_flips_change_the_result_as_the_encoder_predicts():
    v, fs = 2, 75
    sim = ms.MLX90609Sim(version=v, full_scale_dps=fs)
    for field in ("EE_ZRO0", "EE_ZRO1", "EE_ZRO2", "EE_SF0", "EE_SF1", "EE_SF2"):
        first, cells, (bit,) = ms.LAYOUT[field]
        i = int(field[-1])
        for k in range(cells):
            bad = bytearray(sim.ee)
            bad[first + k] ^= 1 << bit
            t = decode_eeprom(bad)
            assert t.vote_disagreements == 0  # single copies: a flip is invisible
            ee_z = list(sim.ee_zro)
            ee_s = list(sim.ee_sf)
            if field.startswith("EE_ZRO"):
                ee_z[i] ^= 1 << k
            else:
                ee_s[i] ^= 1 << k
            want = decode_eeprom(ms.encode_eeprom(v, fs // 5, sim.tc_mv, ee_z, ee_s))
            assert _fields(t) == _fields(want)
            assert t.zro("digital")[i] == pytest.approx(ms.note_zro(v, ee_z[i], "digital"))
            assert t.sf(12.8)[i] == pytest.approx(ms.note_sf(ee_s[i], 12.8))


# ---------------------------------------------------------------- bad input


def test_version_0_says_there_is_no_table_and_what_to_do():
    img = ms.encode_eeprom(0, 15, (1850, 2500, 3100), (0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError, match="VERSION 0.*no look-up table.*three-point"):
        decode_eeprom(img)


@pytest.mark.parametrize("version", [4, 7, 128, 254])
def test_unknown_version_is_quoted(version):
    img = ms.encode_eeprom(version, 15, (1850, 2500, 3100), (1, 2, 3), (4, 5, 6))
    with pytest.raises(ValueError, match="VERSION %d is unknown" % version):
        decode_eeprom(img)


@pytest.mark.parametrize(
    "tc,msg",
    [((2500, 2500, 3100), "TC0 = TC1 = 2500 mV"), ((1850, 3100, 3100), "TC1 = TC2 = 3100 mV"),
     ((1850, 2500, 1850), "TC0 = TC2 = 1850 mV")],
)
def test_degenerate_table(tc, msg):
    img = ms.encode_eeprom(2, 15, tc, (1, 2, 3), (4, 5, 6))
    with pytest.raises(ValueError, match="degenerate MLX90609 table: " + msg):
        decode_eeprom(img)


def test_wrong_cell_count():
    with pytest.raises(ValueError, match="128"):
        decode_eeprom(bytes(127))


# ---------------------------------------------------------------- plausibility (issue 17, item 7)


def test_random_images_are_never_taken_for_a_table():
    """Before the limits about 1.5 % of random 128-byte images decoded as tables (38..57 voted
    bits disagreeing, TC like 64,623 mV). A random image has 48 +- 3.5 of its 64 voted bits
    disagreeing; the health limit is 4, so the chance one passes that check alone is below
    1e-30: 0 of 50,000 is the expectation, not luck."""
    rnd = random.Random(seeds.seed("mlx_tables_3"))
    reasons = {}
    for _ in range(50000):
        img = bytes(rnd.getrandbits(8) for _ in range(128))
        with pytest.raises(ValueError) as e:
            decode_eeprom(img)
        key = "voted bits" if "voted bits (RANGE" in str(e.value) else str(e.value).split(":")[0]
        reasons[key] = reasons.get(key, 0) + 1
    print("random images refused by:", reasons)
    assert sum(reasons.values()) == 50000
    # and the value limits alone, with the vote check switched off, refuse them too
    for _ in range(20000):
        img = bytes(rnd.getrandbits(8) for _ in range(128))
        with pytest.raises(ValueError, match="MLX90609"):
            decode_eeprom(img, max_disagree=64)


def _within_limits(fs, tc):
    # the value limits docs/mlx90609.md states: TC in 300..3498 mV, rising 5..20 mV/K from -40 to 25
    # and 25 to 85 degC, TC1 2500 +- 500 mV, full scale 50..400 deg/s
    return (all(300 <= t <= 3498 for t in tc) and len(set(tc)) == 3 and 5 <= (tc[1] - tc[0]) / 65 <= 20
            and 5 <= (tc[2] - tc[1]) / 60 <= 20 and abs(tc[1] - 2500) <= 500 and 50 <= fs <= 400)


def test_random_fields_with_healthy_votes_are_refused_by_the_value_limits():
    # a table whose every voted bit is unanimous and VERSION known, but RANGE and TC random:
    # only the value limits stand in the way. A random table passes them with probability about
    # 0.28 * (1001 * 976 * 900 / 65536**3) ~ 9e-7 (RANGE 10..80, then TC1, TC0 and TC2 each in
    # their window): such a table is a plausible part, and must be accepted - every table is
    # accepted exactly when it is within the limits
    rnd = random.Random(seeds.seed("mlx_tables_4"))
    accepted = 0
    for n in range(20000):
        tc = [rnd.randint(0, 0xFFFF) for _ in range(3)]
        rng_code = rnd.randint(0, 255)
        img = ms.encode_eeprom(rnd.choice(VERSIONS), rng_code, tc, [1, 2, 3], [4, 5, 6], seed=n)
        try:
            t = decode_eeprom(img)
        except ValueError as e:
            assert "VERSION" not in str(e) and "disagree" not in str(e)
            assert not _within_limits(5 * rng_code, tc), (rng_code, tc, str(e))
            continue
        accepted += 1
        assert _within_limits(t.full_scale_dps, t.tc), (t.full_scale_dps, t.tc)
    assert accepted <= 3  # 0.02 expected in 20,000


def test_real_tables_are_still_accepted():
    # AN2 prints no numeric table, so: the nominal part of sensor-facts (2.5 V at 25 degC, 10 mV/K:
    # 1850 / 2500 / 3100 mV), the simulated parts of the tests and the virtual board, every AN2
    # option code and VERSION, and the extremes the limits allow
    for version in VERSIONS:
        for fs in (75, 150, 300):
            for tc in ((1850, 2500, 3100), (1843, 2497, 3109), (2000 - 65 * 20 + 1, 2000, 2000 + 300),
                       (3000 - 325, 3000, 3498)):
                t = decode_eeprom(ms.encode_eeprom(version, fs // 5, tc, (7, 128, 250), (0, 100, 255)))
                assert t.tc == tc and t.full_scale_dps == fs and t.vote_disagreements == 0
    t = decode_eeprom(ms.MLX90609Sim(version=2, full_scale_dps=150, zro_mv=(2440.0, 2500.0, 2570.0)).ee)
    assert t.tc == (1850, 2500, 3100)


@pytest.mark.parametrize("tc,rng,msg", [
    ((1850, 2500, 64623), 30, r"TC2 = 64623 mV \(TEMPOUT at 85 degC\) is outside what the part's TEMPOUT spans \(300..3498 mV\)"),
    ((200, 1500, 2100), 30, r"TC0 = 200 mV"),
    ((3100, 2500, 1850), 30, r"TEMPOUT goes from 3100 mV \(TC0, -40 degC\) to 2500 mV \(TC1, 25 degC\), -9.2 mV/K"),
    ((2400, 2500, 3100), 30, r"from 2400 mV \(TC0.*1.5 mV/K; the sensor rises about 10 mV/K \(accepted 5..20\)"),
    ((1350, 2000, 3260), 30, r"from 2000 mV \(TC1, 25 degC\) to 3260 mV \(TC2, 85 degC\), 21.0 mV/K"),
    ((500, 1900, 2500), 30, r"21.5 mV/K"),
    ((1350, 1950, 2550), 30, r"TC1 = 1950 mV at 25 degC; TEMPOUT is about 2500 mV there \(accepted \+-500\)"),
    ((1850, 2500, 3100), 0, r"full scale of 0 deg/s"),
    ((1850, 2500, 3100), 255, r"full scale of 1275 deg/s; parts are made for 75, 150 or 300 \(accepted 50..400\)"),
])
def test_each_limit_names_the_problem(tc, rng, msg):
    img = ms.encode_eeprom(2, rng, tc, (1, 2, 3), (4, 5, 6))
    with pytest.raises(ValueError, match="implausible MLX90609 table: .*" + msg):
        decode_eeprom(img)
    # the same limits guard a table re-applied from the store
    with pytest.raises(ValueError, match="implausible MLX90609 table"):
        mlx.LookupTable.from_ints((2, rng * 5) + tc + (1, 2, 3, 4, 5, 6))


def test_vote_health_threshold():
    img = ms.MLX90609Sim(version=2, full_scale_dps=150).ee
    bad = bytearray(img)
    # one flipped copy in k different TC1 bits (cells 0x48..): the majority still reads right
    for k in range(5):
        bad[0x48 + k] ^= 1
        if k < 4:
            assert decode_eeprom(bad).vote_disagreements == k + 1
    with pytest.raises(ValueError, match="5 of the 64 voted bits .* disagree .*accepted 4.*EEPROM is failing"):
        decode_eeprom(bad)
    assert decode_eeprom(bad, max_disagree=5).tc == decode_eeprom(img).tc


# ---------------------------------------------------------------- compensation precision


def _sweep(table, output, out_scale, t_step):
    comp = compensator(table, output, out_scale)
    z = table.zro(output)
    s = table.sf(table.s0(output))
    lo, hi = comp.t_in
    raws = np.arange(0, 2048) if output == "digital" else np.arange(0, 5001)
    worst = ymax = 0.0
    ts = list(range(lo - 40, hi + 41, t_step)) + [lo, hi, min(table.tc), max(table.tc)]
    for t in ts:
        comp.update(t)
        got = np.array([comp.apply(int(r)) for r in raws], dtype=float)
        te = min(max(t, lo), hi)  # documented: held at the edge of t_in beyond it
        ref = out_scale * (raws - ms.an2_quadratic(table.tc, z, te)) / ms.an2_quadratic(table.tc, s, te)
        worst = max(worst, float(np.abs(got - ref).max()))
        ymax = max(ymax, float(np.abs(ref).max()))
    return worst, ymax


def test_an2_reference_is_the_interpolating_quadratic_and_overflows_32_bits():
    tc = (1843, 2497, 3109)
    y = (2478.4, 2500.1, 2531.7)
    for t, want in zip(tc, y):
        assert ms.an2_quadratic(tc, y, t) == pytest.approx(want, abs=1e-9)
    # why the module does not evaluate the note's closed forms in integers: one product of
    # equation (10) alone is ~2**43, far beyond MicroPython's 2**30 small ints, and the
    # denominator T0*T1*T2 is within a factor 2 of that limit
    T0, T1, T2 = tc[1] - tc[0], tc[2] - tc[1], tc[0] - tc[2]
    assert abs(y[0] * T1 * tc[1] * tc[2]) > 2**43
    assert abs(T0 * T1 * T2) > 2**28


def core_excess(ymax):
    # fixedpoint's documented bound beyond the final rounding's 0.5 LSB: truncations < 1/16
    # output LSB, and the scale's 27-bit evaluation about |y| * 2**-24
    return 1 / 16 + ymax * 2**-24


@pytest.mark.parametrize(
    "version,fs,output,out_scale",
    [(1, 75, "digital", 1000), (2, 150, "digital", 1000), (255, 300, "digital", 1000),
     (3, 300, "digital", 100), (2, 75, "analog", 1000), (1, 300, "analog", 1000),
     (2, 75, "digital", 10000), (3, 150, "digital", 100), (255, 150, "analog", 1000)],
)
def test_compensation_matches_an2_equations_3_to_13(version, fs, output, out_scale):
    rnd = random.Random(seeds.seed("mlx_version", version * 1000 + fs))
    tc = (1850 + rnd.randint(-80, 80), 2500 + rnd.randint(-50, 50), 3100 + rnd.randint(-80, 80))
    img = ms.encode_eeprom(version, fs // 5, tc, [rnd.randint(0, 255) for _ in range(3)],
                           [rnd.randint(0, 255) for _ in range(3)])
    table = decode_eeprom(img)
    worst, ymax = _sweep(table, output, out_scale, 7)
    print("MLX90609 v%d %d dps %s: worst %.4f output LSB = %.3f milli-deg/s"
          % (version, fs, output, worst, worst * 1000 / out_scale))
    assert worst <= 0.5 + core_excess(ymax)
    assert worst > 0.45  # the sweep does reach rounding-limited points (a real comparison)


def test_out_of_range_tempout_is_held_and_counted():
    table = decode_eeprom(ms.MLX90609Sim().ee)
    comp = compensator(table)
    lo, hi = comp.t_in
    assert (lo, hi) == (1850 - 150, 3100 + 150)
    comp.update(hi)
    edge = comp.apply(1500)
    n = comp.clamped
    comp.update(4000)
    assert comp.apply(1500) == edge and comp.clamped == n + 1
    comp.update(300)
    comp.update(lo)
    assert comp.clamped == n + 2


# ---------------------------------------------------------------- driver over real Blinka busio


def blinka_gyro(sim, **kw):
    spi, cs = ms.on_simspi(sim)
    bus = blinka.spi(spi)
    gyro = MLX90609(bus, blinka.cs_pin(cs), **kw)
    return gyro, bus, spi


def test_driver_over_blinka_reads_table_and_tracks_true_rate():
    sim = ms.MLX90609Sim(version=2, full_scale_dps=150, conversion_exchanges=5)
    gyro, bus, spi = blinka_gyro(sim)
    assert (bus._spi.polarity, bus._spi.phase) == (1, 1)  # SPI mode 3
    assert bytes(gyro.cells) == bytes(sim.ee)
    assert _fields(gyro.table) == _fields(decode_eeprom(sim.ee))
    # truth: one rate code is 1/6.4 deg/s; the table quantisation and the part's curvature
    # between the table temperatures add a few tenths at most
    worst = 0.0
    for temp in (-40, -20, 0, 25, 50, 70, 85):
        for rate in (-140.0, -10.0, 0.0, 3.0, 75.0, 140.0):
            sim.set_state(rate, temp)
            worst = max(worst, abs(gyro.rate_dps() - rate))
    assert worst < 0.6
    # and it is the table's compensation, not a coincidence: the uncompensated nominal reading
    # is far off at the cold end
    sim.set_state(0.0, -40)
    nominal = (gyro.rate_code() - 1008) / 6.4
    assert abs(nominal) > 1.0 and abs(gyro.rate_dps()) < 0.3


def test_rate_is_exactly_the_compensator_on_the_read_codes():
    sim = ms.MLX90609Sim(version=1, full_scale_dps=75, conversion_exchanges=3)
    gyro, _, _ = blinka_gyro(sim, out_scale=1000)
    comp = compensator(decode_eeprom(sim.ee), "digital", 1000)
    for temp, rate in ((-30, 12.0), (10, -60.0), (80, 5.5)):
        sim.set_state(rate, temp)
        rc, tcode = sim.codes(rate, temp)
        tmv = ((tcode * 25 + 8) >> 4) + 300  # 25/16 mV per code + 300 mV, nearest mV
        comp.update(tmv)
        assert gyro.rate() == comp.apply(rc)


def test_refusals_are_retried_then_named():
    sim = ms.MLX90609Sim()
    sim.refuse(5)
    gyro, _, _ = blinka_gyro(sim)
    assert gyro.refusals == 5 and gyro.health()["refusals"] == 5
    assert bytes(gyro.cells) == bytes(sim.ee)
    sim.refuse(-1, instr=0x42)
    with pytest.raises(OSError, match="refused EER of EEPROM cell 0x42 9 times"):
        MLX90609(*ms.on_simspi(sim))
    sim.refuse(-1)
    with pytest.raises(MLX90609Error, match="refused ADCC 0x9C"):
        gyro.rate()
    sim.refuse(0)
    sim.refuse(-1, instr=0x80)  # ADCR refused while converting: polled, then reported
    with pytest.raises(MLX90609Error, match="not finished after 200 ADCR polls"):
        gyro.rate()


def test_nobody_answering():
    from tools.sim.buses import SimPin, SimSPI

    with pytest.raises(MLX90609Error, match="cell 0x00.*no part answers"):
        MLX90609(SimSPI(), SimPin(5))


def test_conversion_that_never_ends():
    sim = ms.MLX90609Sim(conversion_exchanges=10**6)
    gyro, _, _ = blinka_gyro(sim)
    with pytest.raises(MLX90609Error, match="not finished"):
        gyro.tempout_mv()


def test_version_0_part_still_reads_raw_for_three_point_calibration():
    sim = ms.MLX90609Sim(version=0)
    gyro, _, _ = blinka_gyro(sim)
    assert gyro.table is None
    sim.set_state(0.0, 25.0)
    assert gyro.tempout_mv() == 2500 and 900 < gyro.rate_code() < 1100
    with pytest.raises(ValueError, match="no look-up table.*three-point"):
        gyro.rate()
    with pytest.raises(ValueError, match="no look-up table"):
        gyro.rezero()


def test_rezero_removes_the_supply_shift_at_every_temperature():
    # version 1 stores whole mV: with no between-point curvature the table is the part exactly,
    # so what remains at rest is the supply shift alone (plus the ADC's half-code rounding)
    sim = ms.MLX90609Sim(version=1, full_scale_dps=75, zro_mv=(2478.0, 2500.0, 2531.0),
                         zro_bump_mv=0.0, supply_shift_mv=24.0)
    gyro, _, _ = blinka_gyro(sim)
    sim.set_state(0.0, 30.0)
    before = gyro.rate_dps()
    assert before == pytest.approx(24.0 / 26.67, abs=0.1)  # 24 mV at 26.67 mV/(deg/s)
    shift = gyro.rezero()
    assert shift == pytest.approx(24.0 * 12 / 25, abs=0.55)
    for temp in (-35, 0, 60, 85):
        for rate in (0.0, 40.0):
            sim.set_state(rate, temp)
            assert gyro.rate_dps() == pytest.approx(rate, abs=0.25)


def test_rezero_interrupted_by_a_bus_fault_keeps_the_old_zero():
    sim = ms.MLX90609Sim(supply_shift_mv=10.0)
    gyro, _, spi = blinka_gyro(sim)
    sim.set_state(0.0, 40.0)
    r0 = gyro.rate()
    spi.fail_at = 30
    with pytest.raises(OSError):
        gyro.rezero()
    assert gyro.zro_shift == 0.0 and gyro.rate() == r0


def test_calibration_ints_round_trip_and_bad_records():
    sim = ms.MLX90609Sim(version=3, full_scale_dps=300, supply_shift_mv=-12.0)
    gyro, _, _ = blinka_gyro(sim)
    sim.set_state(0.0, 10.0)
    gyro.rezero()
    ints = gyro.calibration_ints()
    assert len(ints) == 13 and all(isinstance(i, int) and -2**31 <= i < 2**31 for i in ints)
    sim.set_state(33.0, 70.0)
    exact = gyro.rate()
    gyro.apply_calibration_ints(ints)  # the re-zero is kept to 1/256 LSB
    want = gyro.rate()
    assert abs(want - exact) <= 1
    # a fresh driver on a part whose EEPROM has since lost a copy: re-applied from the record
    sim.flip(0x50, 0)
    other, _, _ = blinka_gyro(sim)
    assert other.health()["vote_disagreements"] == 1
    other.apply_calibration_ints(ints)
    assert other.rate() == want
    assert other.zro_shift == pytest.approx(gyro.zro_shift, abs=1 / 256)
    for bad in (ints[:12], (2,) + ints[1:], ints[:1] + (0,) + ints[2:], ints[:3] + (ints[4],) + ints[4:]):
        with pytest.raises(ValueError):
            other.apply_calibration_ints(bad)
        assert other.rate() == want  # old calibration kept


def test_save_and_reapply_through_the_store(tmp_path):
    from tempcomp import store as store_mod  # an import error fails here: never a silent skip
    sim = ms.MLX90609Sim(version=2, full_scale_dps=150, supply_shift_mv=15.0)
    gyro, _, _ = blinka_gyro(sim)
    sim.set_state(0.0, 35.0)
    gyro.rezero()
    path = str(tmp_path / "tempcomp.cal")
    gyro.save(store_mod.Store(path))
    sim.set_state(-25.0, 75.0)
    other, _, _ = blinka_gyro(sim)
    assert abs(other.rate() - gyro.rate()) > 100  # without the re-zero: 15 mV = 1.1 deg/s off
    other.load(store_mod.Store(path))
    assert abs(other.rate() - gyro.rate()) <= 1
    with pytest.raises(KeyError):
        other.load(store_mod.Store(path), "nothing")


# ---------------------------------------------------------------- MicroPython VM

VM_SCRIPT = r"""
import sys
import mlx90609_sim as ms
import allocprobe
from tempcomp.mlx90609 import MLX90609, decode_eeprom

# 1. the REPL lines of docs/mlx90609.md, as written, with machine.SPI reaching a simulated part
sim = ms.MLX90609Sim(version=2, full_scale_dps=150, supply_shift_mv=0.0)
sim.set_state(42.0, 55.0)
sys.modules["machine"] = ms.machine_for(sim, 17)
ns = {}
exec(DOC, ns)
print("DOC", ns["gyro"].rate_dps())

# 2. decoding in the VM equals CPython's
for v, fs in ((1, 75), (255, 300)):
    t = decode_eeprom(ms.MLX90609Sim(version=v, full_scale_dps=fs, seed=v).ee)
    print("DEC", t.version, t.full_scale_dps, t.tc, t.ee_zro, t.ee_sf, t.zro("digital"))

# 3. read + compensate allocates nothing; temperature and rate change on every sample
sim2 = ms.MLX90609Sim(version=2, full_scale_dps=150)
spi, cs = ms.on_simspi(sim2)
g = MLX90609(spi, cs)
states = []
for i in range(37):
    states.append((-140.0 + 7.7 * i, -60.0 + 4.6 * i))
sim2.schedule(states)
outs = []
for i in range(37):
    outs.append(g.rate())
print("RATES", outs)
allocprobe.report("mlx_rate", g.rate, (), 200)
g.temp_every = 8
allocprobe.report("mlx_rate_every8", g.rate, (), 200)
print("CLAMPED", g.health()["tempout_clamped"])

# 4. the plausibility limits in the VM: random images and an implausible table refused
x = 12345
refused = 0
for n in range(300):
    img = bytearray(128)
    for i in range(128):
        x = (x * 1103515245 + 12345) & 0x7FFFFFFF
        img[i] = x >> 16 & 0xFF
    try:
        decode_eeprom(img)
    except ValueError:
        refused += 1
print("REFUSED", refused)
try:
    decode_eeprom(ms.encode_eeprom(2, 30, (1850, 2500, 64623), (1, 2, 3), (4, 5, 6)))
except ValueError as e:
    print("IMPLAUSIBLE", str(e))
"""


def doc_block(tag):
    text = open(os.path.join(REPO, "docs", "mlx90609.md")).read()
    m = re.search(r"<!-- repl:%s -->\s*```python\n(.*?)```" % tag, text, re.S)
    assert m, tag
    return m.group(1)


def test_in_the_micropython_vm(interp):
    doc = doc_block("micropython")
    assert len(doc.strip().splitlines()) == 5
    out = interps.run(interp, "DOC = %r\n" % doc + VM_SCRIPT,
               mounts=(os.path.join(REPO, "tools", "sim") + ":/simdir",), paths=("/simdir",))
    lines = {ln.split(" ", 1)[0]: ln.split(" ", 1)[1] for ln in out.splitlines() if " " in ln}
    assert float(lines["DOC"]) == pytest.approx(42.0, abs=0.4)
    # same decode as CPython
    decs = [ln for ln in out.splitlines() if ln.startswith("DEC ")]
    for (v, fs), ln in zip(((1, 75), (255, 300)), decs):
        t = decode_eeprom(ms.MLX90609Sim(version=v, full_scale_dps=fs, seed=v).ee)
        parts = ln.split(" ", 3)
        assert (int(parts[1]), int(parts[2])) == (t.version, t.full_scale_dps)
        assert str(t.tc) in ln and str(t.ee_zro) in ln and str(t.ee_sf) in ln
    # same integers as CPython's driver on the same schedule
    sim2 = ms.MLX90609Sim(version=2, full_scale_dps=150)
    g, _, _ = blinka_gyro(sim2)
    sim2.schedule([(-140.0 + 7.7 * i, -60.0 + 4.6 * i) for i in range(37)])
    assert lines["RATES"] == str([g.rate() for _ in range(37)])
    assert int(lines["CLAMPED"]) > 0  # the schedule reaches below TC0 - 150 mV on purpose
    assert lines["REFUSED"] == "300"
    assert lines["IMPLAUSIBLE"].startswith("implausible MLX90609 table: TC2 = 64623 mV")
    alloc = _mpvm.alloc_lines(out)
    assert alloc["mlx_rate"] == (0.0, True)
    assert alloc["mlx_rate_every8"] == (0.0, True)


# ---------------------------------------------------------------- docs on CPython with Blinka


def test_doc_lines_work_as_written(monkeypatch):
    # MicroPython lines: machine.SPI reaches the simulated part
    sim = ms.MLX90609Sim(version=1, full_scale_dps=75)
    sim.set_state(-20.0, 0.0)
    monkeypatch.setitem(sys.modules, "machine", ms.machine_for(sim, 17))
    ns = {}
    exec(doc_block("micropython"), ns)
    assert ns["gyro"].rate_dps() == pytest.approx(-20.0, abs=0.3)
    # CircuitPython lines: the real Blinka busio.SPI and digitalio, wired to another part
    import board
    import busio
    import digitalio

    sim2 = ms.MLX90609Sim(version=255, full_scale_dps=300)
    sim2.set_state(120.0, 70.0)
    spi, cs = ms.on_simspi(sim2)
    bus = blinka.spi(spi)  # a real busio.SPI whose back-end is the simulated bus
    monkeypatch.setattr(board, "D5", board.Dx_OUTPUT, raising=False)
    monkeypatch.setattr(busio, "SPI", lambda *pins: bus if pins == (board.SCK, board.MOSI, board.MISO) else None)
    monkeypatch.setattr(digitalio, "DigitalInOut", lambda pin: blinka.cs_pin(cs, pin))
    block = doc_block("circuitpython")
    assert len(block.strip().splitlines()) == 5
    ns = {}
    exec(block, ns)
    assert ns["gyro"].rate_dps() == pytest.approx(120.0, abs=1.0)


def test_package_lists_the_module():
    import json

    urls = json.load(open(os.path.join(REPO, "package.json")))["urls"]
    assert ["tempcomp/mlx90609.py", "lib/tempcomp/mlx90609.py"] in urls
    assert mlx.CELLS == 128
