"""MPU-6xxx fault handling inside the MicroPython VM (host_tests/sensors/test_mpu6xxx_faults.py).

The same driver code that runs on CPython, on 32-bit MicroPython: one corrupted read at a spread
of positions during calibrate(), a steady turn refused, the datasheet zero-rate limit, the
periodic trim check. main(seed) prints "GARBLE kind runs raised wrong" and "OK name" / "FAIL name" lines.
"""
from tempcomp.mpu6xxx import MPU6xxx, MPUError
from tempcomp.mpu6xxx_cal import MIN_PACKETS
from tools.sim.buses import GARBLES, SimI2C
from tools.sim.mpu6xxx_sim import MPU6xxxSim


def ok(name, cond):
    print(("OK " if cond else "FAIL ") + name)


SEED = [33]  # the simulated part's seed: main(seed) sets it (the test passes its run's seed)


def make(part="MPU-6500", face="-y", **kw):
    sim = MPU6xxxSim(part, seed=SEED[0], gyro_noise_dps=0.01, accel_noise_g=0.001, **kw)
    sim.place(face)
    bus = SimI2C({0x68: sim})
    return sim, bus, MPU6xxx(bus)


def garbled():
    sim, bus, imu = make()
    old = (sim.gyro_offsets(), sim.accel_offsets())
    clean = imu.calibrate(packets=MIN_PACKETS, settle_ms=2)
    total = bus.reads
    for kind in GARBLES:
        runs = raised = wrong = 0
        for k in range(0, total, 3):
            sim, bus, imu = make()
            before = sim.config()
            bus.garble = kind
            bus.garble_seed = k
            bus.garble_at = k
            runs += 1
            try:
                got = imu.calibrate(packets=MIN_PACKETS, settle_ms=2)
            except OSError:
                raised += 1
                if (sim.gyro_offsets(), sim.accel_offsets()) != old or sim.config() != before:
                    wrong += 1
                continue
            d = 0
            for i in range(2):
                for j in range(3):
                    d = max(d, abs(got[i][j] - clean[i][j]))
            if d > 2 or got != (sim.gyro_offsets(), sim.accel_offsets()) or sim.config() != before:
                wrong += 1
        print("GARBLE %s %d %d %d" % (kind, runs, raised, wrong))


def turns():
    sim, bus, imu = make(face="+z", gyro_bias_dps=(1.5, -2.0, 0.8))
    old = imu.offsets()
    sim.turn((2.0, 0.0, 0.0))
    try:
        imu.calibrate()
        ok("turn_about_x_refused", False)
    except MPUError as e:
        ok("turn_about_x_refused", "turned during capture" in str(e) and imu.offsets() == old)
    sim.place("+z")
    sim.turn((0.0, 0.0, 10.0))
    try:
        imu.calibrate()
        ok("turn_about_z_refused", False)
    except MPUError as e:
        ok("turn_about_z_refused", "was the board turning" in str(e) and imu.offsets() == old)
    sim.place("+z")
    g, a = imu.calibrate()
    ok("still_accepted", abs(g[2] - round(-0.8 * 32.8)) <= 1)
    ok("zro_limit", abs(imu.zro_limit_dps() - 5.0) < 0.01)


def trim():
    sim, bus, imu = make("ICM-20602", face="+z")
    cal = imu.calibrate(packets=300)
    sim.glitch_trim(1)
    n = imu.check(every_ms=0)
    ok("check_rewrites", n == 1 and (sim.gyro_offsets(), sim.accel_offsets()) == cal)
    t = bus.transactions
    ok("check_not_due", imu.check(every_ms=100000) == 0 and bus.transactions == t)


def main(seed=33):
    SEED[0] = seed
    garbled()
    turns()
    trim()
    print("DONE")
