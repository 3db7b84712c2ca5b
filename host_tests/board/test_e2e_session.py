"""End to end on the virtual board, driven with unmodified mpremote as a user drives a board.

Deploy lib/tempcomp, run the guided session (scripted answers; the virtual board's world plays
the user's hands: a knock during the first capture, a heater for the temperature points),
soft-reset, power-cycle, re-apply with one call, and read compensated rates.

Every expected value comes from the simulated parts' true properties (tools/vboard/vm/
vboard_sensors.py, built here on CPython as well), never from the code under test:

* MPU-6500 offset registers after the session: gyro = -bias(20 degC) * 32.8 LSB/(deg/s),
  accel = factory word - bias * 2048 LSB/g, each within 1 register LSB (the knock, 60-80 deg/s,
  would move them by thousands: a capture that saw it must have been refused and redone).
* Compensated rate at 38 degC (between the temperature points) on a turntable at 15 deg/s
  about z, mean of 32 reads:
  MPU-6500 gyro x/y/z within 0.1 deg/s of 0/0/15 (noise 0.05 deg/s per sample; the bias is an
  exact quadratic of T, fitted through three points);
  MLX90609 within 0.35 deg/s (its true ZRO departs from the EEPROM quadratic by up to
  zro_bump_mv = 1.5 mV at 20 and at 38 degC: 3 mV / 13.3 mV per deg/s = 0.23; SF bump
  0.2 % of 15 = 0.03; half an ADC code 0.08);
  analog gyro within 0.2 deg/s (null fitted exactly through 3 points; the nominal 6 mV per
  deg/s scale is 0.3 % off at 38 degC: 0.05; ADC and noise below 0.02).
  The uncompensated readings must be off by more than those bounds, or the check proves
  nothing: a board whose parts did not drift would pass it uncalibrated.
"""

import ast
import os
import sys

import pytest
from paths import REPO

for _p in (os.path.join(REPO, "tools", "sim"), os.path.join(REPO, "tools", "vboard", "vm")):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import vboard_sensors as truth  # noqa: E402  (the simulated parts' true properties)

from tools.board.boardctl import Remote, VirtualBoard  # noqa: E402

ROOM_C = 20.0
HOLD_C = 38.0
SPIN_DPS = 15.0
# heater with plateaus at 32 and 44 degC: the points are taken where the temperature is steady.
# Times are the board's simulated seconds (x2, VBOARD_TIME_SCALE), which advance with what the
# board does, not with the host: a point's captures take about 1.4 s of them here, on an idle
# host or a loaded one, so the room plateau outlasts the first point's captures.
HEAT = [(0, ROOM_C), (4, ROOM_C), (4.5, 32.0), (10, 32.0), (10.5, 44.0), (20, 44.0)]

SESSION = r"""
import tempcomp_board, vboard_sensors
from tempcomp.session import Session
w = vboard_sensors.world
hot = []

def hands(step, attempt):
    if step == "still":
        w.place("+z")
        if attempt == 1:
            w.bump(after_ms=0, for_ms=300)
    elif step.startswith("face:"):
        w.place(step[5:])
    else:
        w.place("+z")
        if not hot:
            hot.append(1)
            w.heat(%r)

Session(tempcomp_board, answers=[], hook=hands, points=3, step_c=11, packets=500, samples=128).run()
import tempcomp.sensors
s = tempcomp.sensors.open_sensors(tempcomp_board)
print("OFFSETS", repr(s.mpu.offsets()))
"""

READ = r"""
import tempcomp_board, vboard_sensors
from tempcomp.session import restore
s = restore(tempcomp_board)
w = vboard_sensors.world
w.place("+z")
w.heat([(0, %r)])
w.spin((0, 0, %r))
print("OFFSETS", repr(s.mpu.offsets()))
print("READ", repr(s.read(32)))
"""

TURNING = r"""
import os, tempcomp_board, vboard_sensors
from tempcomp.session import Session, Aborted
from tempcomp.sensors import open_sensors
w = vboard_sensors.world
before = open_sensors(tempcomp_board, ("mpu6xxx",)).mpu.offsets()
w.place("+z")
w.spin((0, 0, 40.0))
try:
    Session(tempcomp_board, store_path="/turning.cal", which=("mpu6xxx",), answers=["", "q"], points=1,
            packets=200).run()
except Aborted:
    print("ABORTED")
print("KEPT", open_sensors(tempcomp_board, ("mpu6xxx",)).mpu.offsets() == before)
print("SAVED", "turning.cal" in os.listdir("/"))
"""


def tagged(out, tag):
    vals = [ast.literal_eval(line[len(tag) + 1:].strip()) for line in out.splitlines() if line.startswith(tag + " ")]
    assert vals, "no %s line in:\n%s" % (tag, out)
    return vals[-1]


def true_bias_dps(axis, temp_c):
    b0 = truth.MPU_GYRO_BIAS_DPS[axis]
    b1, b2 = truth.MPU_GYRO_TC[axis]
    d = temp_c - 25.0
    return b0 + b1 * d + b2 * d * d


def expected_offsets():
    mpu, _, _ = truth.make_parts()
    gyro = tuple(round(-true_bias_dps(k, ROOM_C) * 32.8) for k in range(3))
    fac = [w - 0x10000 if w & 0x8000 else w for w in mpu.factory]
    accel = tuple(fac[k] - truth.MPU_ACCEL_BIAS_G[k] * 2048 for k in range(3))
    return gyro, accel


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    home = tmp_path_factory.mktemp("e2e")
    vb = VirtualBoard(str(home), env={"VBOARD_TIME_SCALE": "2", "VBOARD_PROFILE": "0:%g" % ROOM_C})
    try:
        vb.start()
        r = Remote(vb.url)
        r.deploy_mpy("virtual", str(home / "mpy"))
        yield vb, r
    finally:
        vb.stop()


def check_offsets(offsets):
    gyro, accel = offsets
    want_g, want_a = expected_offsets()
    for k in range(3):
        assert abs(gyro[k] - want_g[k]) <= 1, (gyro, want_g)
        assert abs(accel[k] - want_a[k]) <= 2, (accel, want_a)  # bit 0 is the part's


def test_session_knock_redo_reset_power_cycle_and_compensated_reads(board):
    vb, r = board
    out = r.run(SESSION % (HEAT,), timeout=180)
    # the knock: a clear message naming the motion, then the step again, then a good capture
    assert "the part moved during capture" in out, out
    assert "keep it still" in out
    assert "redo:" in out
    assert "saved to /tempcomp.cal: mlx90609, mpu6xxx, mpu_tc, mpu_tcc, adxrs" in out, out
    assert out.count("point at") == 3
    check_offsets(tagged(out, "OFFSETS"))

    # soft reset: RAM gone (and, on this board, the parts' registers); one call brings it back
    r.soft_reset()
    out = r.run("import tempcomp_board\nfrom tempcomp.session import restore\n"
                "print('OFFSETS', repr(restore(tempcomp_board).mpu.offsets()))")
    assert "restored from /tempcomp.cal: mlx90609, mpu6xxx, mpu_tc, adxrs" in out, out
    check_offsets(tagged(out, "OFFSETS"))

    # power cycle: a new process, only the flash directory survives
    vb.power_cycle()
    out = r.run(READ % (HOLD_C, SPIN_DPS))
    assert "restored from /tempcomp.cal: mlx90609, mpu6xxx, mpu_tc, adxrs" in out, out
    check_offsets(tagged(out, "OFFSETS"))
    rd = tagged(out, "READ")
    assert abs(rd["temp_c"] - HOLD_C) < 0.05

    want = {"mpu_gx": 0.0, "mpu_gy": 0.0, "mpu_gz": SPIN_DPS, "mlx": SPIN_DPS, "adxrs": SPIN_DPS}
    bound = {"mpu_gx": 0.1, "mpu_gy": 0.1, "mpu_gz": 0.1, "mlx": 0.35, "adxrs": 0.2}
    for key in want:
        comp, raw = rd[key]
        assert abs(comp - want[key]) <= bound[key], (key, comp, want[key])
        assert abs(raw - want[key]) > 2 * bound[key], (key, raw, "uncompensated already within the bound")
    # the MPU's uncompensated error is its true bias at 38 degC (the registers taken out again)
    for k, key in enumerate(("mpu_gx", "mpu_gy", "mpu_gz")):
        assert abs(rd[key][1] - want[key] - true_bias_dps(k, HOLD_C)) < 0.05


def test_steady_turn_is_refused_and_nothing_changes(board):
    # a turn with no spread passes the motion check; calibrate() refuses a bias beyond the
    # MPU-6500's datasheet zero-rate range before writing anything
    _, r = board
    out = r.run(TURNING)
    assert "gyro z reads" in out and "was the board turning? Nothing written" in out, out
    assert "ABORTED" in out
    assert "KEPT True" in out
    assert "SAVED False" in out
