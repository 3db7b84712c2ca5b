"""MPU-6xxx checks that run inside the MicroPython VM (host_tests/sensors/test_mpu6xxx_vm.py).

Prints machine-readable lines: ``CAL part face gx gy gz ax ay az f0 f1 f2 m0..m5`` (registers,
the factory trim words and the simulated part's mean output afterwards, in output LSB), ``ALLOC ...`` (allocprobe), and
``COMP t raw0..raw5 -> out0..out6`` for comparison with CPython.
"""

from array import array

from replay_i2c import ReplayI2C

from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_cal import MAX_PACKETS
from tempcomp.mpu6xxx_tc import BiasModel, compiled
from tools.sim.buses import SimI2C
from tools.sim.mpu6xxx_sim import MPU6xxxSim


def calibrations(seed):
    for part in ("MPU-6050", "MPU-6500"):
        for face in ("+z", "-y"):
            sim = MPU6xxxSim(part, seed=seed, gyro_noise_dps=0.01, accel_noise_g=0.001)
            seed += 1
            sim.place(face)
            imu = MPU6xxx(SimI2C({0x68: sim}))
            g, a = imu.calibrate(packets=300)
            vals = list(g) + list(a) + list(sim.factory) + ["%.3f" % v for v in sim.mean_output()]
            print("CAL %s %s %s" % (part, face, " ".join([str(v) for v in vals])))


def model_points(t0):
    # three bias points 2000 raw apart (~6 degC): register values drifting with temperature
    return [
        (t0 - 2000, (10.5, -20.25, 3.0), (1000.0, -501.5, 2300.0)),
        (t0, (12.0, -19.0, 2.5), (1004.0, -498.0, 2296.5)),
        (t0 + 2000, (14.5, -17.0, 1.0), (1010.0, -493.0, 2290.0)),
    ]


def allocations(seed):
    import allocprobe  # VM only (uses micropython.heap_lock)

    sim = MPU6xxxSim("MPU-6500", seed=seed)
    sim.place("+z")
    imu_sim = MPU6xxx(SimI2C({0x68: sim}))
    imu_sim.calibrate(packets=100)
    sim.regs[0x1B] = 0x08  # a user range: +-500 dps, +-4 g
    sim.regs[0x1C] = 0x08
    stream = bytearray()
    for _ in range(16):
        s = sim._sample()
        stream += s[0:6]
        stream += s[8:14]
    t0 = sim.temp_raw()
    img = bytearray(sim.regs)
    img[0x3B:0x49] = sim._sample()  # data registers hold a real sample
    bus = ReplayI2C(img, stream, 16 * 12, t_base=t0 - 256, t_step=8, t_span=64)
    imu = MPU6xxx(bus)
    imu._cal()._begin(MAX_PACKETS - 100, 0)
    allocprobe.report("mpu_fifo_poll_16_packets", imu._cal()._poll, (), 200)
    allocprobe.report("mpu_accumulate_16_packets", imu._cal()._accumulate, (0, 16), 200)
    model = BiasModel(model_points(t0))
    imu.compensate(model)
    out = array("i", [0] * 7)
    allocprobe.report("mpu_read_compensated", imu.read_compensated, (out,), 200)
    allocprobe.report("mpu_temp_c100", imu.temp_c100, (), 200)
    mi = model.to_ints()
    imu.compensate(compiled(imu, mi), mi)  # the boot form (tempcomp.mpu6xxx_rt)
    allocprobe.report("mpu_read_compensated_resumed", imu.read_compensated, (out,), 200)
    print("GOT %d" % imu._cal()._got)


def compensation_grid(seed):
    # integer results on 32-bit MicroPython, for exact comparison with CPython (which builds the
    # same part from the same seed)
    t0 = 4000
    model = BiasModel(model_points(t0))
    sim = MPU6xxxSim("MPU-6500", seed=seed)
    sim.regs[0x1B] = 0x18  # +-2000 dps
    sim.regs[0x1C] = 0x00  # +-2 g
    imu = MPU6xxx(SimI2C({0x68: sim}))
    imu.compensate(model)
    ca = imu._ca
    cg = imu._cg
    for t in (t0 - 2600, t0 - 2000, t0 - 777, t0, t0 + 1234, t0 + 2000, t0 + 3000):
        ca.update(t)
        cg.update(t)
        for raw in (-32768, -20000, -1, 0, 1, 12345, 32767):
            outs = [ca.apply(raw, k) for k in range(3)] + [cg.apply(raw, k) for k in range(3)]
            print("COMP %d %d %s" % (t, raw, " ".join([str(v) for v in outs])))
        g, a = model.targets(t)
        print("TGT %d %s" % (t, " ".join([str(v) for v in tuple(g) + tuple(a)])))
    mi = model.to_ints()
    ref = MPU6xxx(SimI2C({0x68: sim}))  # this port's own set-up path, what the boot form replaces
    ref.compensate(BiasModel.from_ints(mi))
    imu.compensate(compiled(imu, mi), mi)  # the boot form: its per-temperature numbers
    for t in (t0 - 2600, t0 - 2000, t0 - 777, t0, t0 + 1234, t0 + 2000, t0 + 3000):
        imu._ca.update(t)
        imu._cg.update(t)
        ref._ca.update(t)
        ref._cg.update(t)
        p = list(imu._ca.burst3) + list(imu._cg.burst3)
        print("RT %d %d %s" % (t, p == list(ref._ca.burst3) + list(ref._cg.burst3), " ".join([str(v) for v in p])))
    for raw in (-32768, -12345, -1, 0, 1, 9999, 32767):
        print("TEMP %d %d" % (raw, imu.temp_c100(raw)))


def main(seed=11):
    # the simulated parts: seed .. seed + 3 calibrated, seed + 4 for the hot path and the grid
    # (the test passes its run's seed: other parts every run)
    calibrations(seed)
    allocations(seed + 4)
    compensation_grid(seed + 4)
