"""The MPU-6xxx family's layers at run time: the driver hands the capture, the temperature model and
the resumed state what they need, and none of them calls back into it (issue 27: the boot used to
re-enter mpu6xxx.py from mpu6xxx_rt/mpu6xxx_tc for _comp_set, ranges and _read_offsets).
Every call into a function of lib/tempcomp/mpu6xxx.py is traced while the driver calibrates,
captures bias points, compensates from a BiasModel and from its compiled record, follows the
temperature in hardware and restores from a store; the caller of each must be outside the
family's lower layers."""

import os
import sys

import seeds

from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_tc import BiasModel, compiled
from tempcomp.store import Store
from tools.sim.buses import SimI2C
from tools.sim.mpu6xxx_sim import MPU6xxxSim

LOWER = ("mpu6xxx_parts.py", "mpu6xxx_units.py", "mpu6xxx_cal.py", "mpu6xxx_tc.py", "mpu6xxx_rt.py")


def _calls_into_the_driver(run):
    seen = []

    def prof(frame, event, arg):
        if event == "call" and frame.f_back is not None and frame.f_code.co_filename.endswith(
                os.sep + os.path.join("tempcomp", "mpu6xxx.py")):
            caller = os.path.basename(frame.f_back.f_code.co_filename)
            if caller in LOWER:
                seen.append("%s -> mpu6xxx.%s" % (caller, frame.f_code.co_name))

    sys.setprofile(prof)
    try:
        run()
    finally:
        sys.setprofile(None)
    return seen


def test_no_lower_layer_calls_back_into_the_driver(tmp_path):
    sim = MPU6xxxSim("MPU-6500", seed=seeds.seed("mpu6xxx_layers/part"), temp_c=25.0)  # a part of this run
    sim.set_tc(gyro=[(0.02, 0.0)] * 3, accel=[(0.0002, 0.0)] * 3)
    bus = SimI2C({0x68: sim})
    imu = MPU6xxx(bus)
    st = Store(str(tmp_path / "t.cal"))
    state = {}

    def driver_work():
        imu.calibrate(packets=200)
        pts = []
        for t in (25.0, 31.0, 37.0):
            sim.temp_c = t
            pts.append(imu.bias_point(packets=200))
        model = BiasModel(pts)
        imu.compensate(model)
        imu.follow(model)
        state["model"] = model

    assert _calls_into_the_driver(driver_work) == []
    # compiled() is called by the session (not by the driver): it reads the part's ranges and
    # offsets through the driver's public methods
    mi = state["model"].to_ints()
    tcc = compiled(imu, mi)
    imu.save(st)
    st.save("mpu_tc", mi)
    st.save("mpu_tcc", tcc)

    def boot():
        imu2 = MPU6xxx(bus)
        imu2.restore(st)
        imu2.compensate(st.load("mpu_tcc"), st.load("mpu_tc"))
        imu2.read_compensated([0] * 7)

    assert _calls_into_the_driver(boot) == []
