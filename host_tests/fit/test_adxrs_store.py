"""The analog gyro's three-point calibration goes through the store and comes back whole, in the
MicroPython VM: a fresh driver loaded from flash reads exactly what the calibrated one read, and
both read the simulated part's true rate."""

from tools.board import build_mpy
from tools.firmware import mpvm as vm

VM_CODE = r"""
from tools.sim.analog_gyro_sim import AnalogGyroSim
from tempcomp.adxrs import AnalogGyro
import adxrs_cal
from tempcomp.store import Store
sim = AnalogGyroSim(vref_mv=3300, divider=2.0)
g = AnalogGyro(sim.rate, sim.temp, vref_mv=3300, divider=2.0)
pts = adxrs_cal.three_point(g, sim, (-20.0, 25.0, 70.0))
g.set_three_point(*pts)
Store("/flash/tempcomp.cal").save("gyro0", g.to_record())
print("MAGIC", open("/flash/tempcomp.cal", "rb").read(4))
# "power cycle": new objects, calibration only from flash
g2 = AnalogGyro(sim.rate, sim.temp, vref_mv=3300, divider=2.0)
g2.load_record(Store("/flash/tempcomp.cal").load("gyro0"))
for t in (-20.0, 0.0, 40.0, 70.0):
    for r in (-150.0, 0.0, 90.0):
        sim.temp_c = t
        sim.rate_dps = r
        print("ROW", t, r, g.rate(), g2.rate())
"""


def test_three_point_calibration_survives_the_store(tmp_path):
    out = vm.run(VM_CODE, mounts=(build_mpy.REPO + "/tools:/tools", str(tmp_path) + ":/flash"), paths=("/",))
    rows = [line.split()[1:] for line in out.splitlines() if line.startswith("ROW ")]
    assert len(rows) == 12
    assert "MAGIC b'TCAL'" in out
    for t, r, y1, y2 in rows:
        assert y1 == y2, (t, r, y1, y2)
        # the sim's null and scale are exactly quadratic in VT, so three points recover them; what
        # is left is the 16-bit ADC quantisation: 0.1 mV / 6 mV per dps ~ 17 mdps, plus rounding
        assert abs(int(y1) - float(r) * 1000) <= 60, (t, r, y1)
