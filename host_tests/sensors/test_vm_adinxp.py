"""AN12760, analog gyro and cross-axis paths in the real MicroPython VM: results and zero allocation."""


import interps
import numpy as np
import seeds
from paths import REPO

from tempcomp.an12760 import AN12760
from tempcomp.crossaxis import CrossAxis
from tools.firmware.mpvm import alloc_lines
from tools.fit import an12760 as F

VM_CODE = r"""
from array import array
import allocprobe
from tempcomp.an12760 import AN12760
from tempcomp.adxrs import AnalogGyro
import adxrs_cal
from tempcomp.crossaxis import CrossAxis
from tools.sim.analog_gyro_sim import AnalogGyroSim, ReplayADC

# AN12760 Table 10 from simulated counts (passed in), 0.1 mg units, MPU-6500 temperature codes
acc = AN12760([(-20.0, (1.0,), 0.0264, (-0.001,))], 16384, (-40, 105), t_scale=1 / 333.87,
              t_offset=21.0, out_per_g=10000)
rows = ROWS
res = []
for temp, raw in rows:
    acc.update(acc.code_of(temp))
    res.append(acc.apply(raw))
print("T10", " ".join(str(v) for v in res))

# cubic three-axis instance: per sample = a new temperature code + three axes
acc3 = AN12760([(35.0, (1.2, -0.004, 3e-5), 0.03, (-6e-4, 2e-6, -1e-8)),
                (-50.0, (-0.7, 0.002), -0.02, (4e-4,)), (5.0, 0.3, 0.01, 1e-4)],
               4096, (-40, 105), t_scale=1 / 340, t_offset=36.53, out_per_g=10000)
codes = array("h", [acc3.code_of(-40 + 0.7 * i) for i in range(200)])
raws = array("h", [(i * 7919) % 65536 - 32768 for i in range(600)])
out = array("i", [0, 0, 0])
rr = array("h", [0, 0, 0])
st = array("i", [0])
def acc_step():
    i = st[0]
    i = i + 1 if i < 199 else 0
    st[0] = i
    rr[0] = raws[3 * i]
    rr[1] = raws[3 * i + 1]
    rr[2] = raws[3 * i + 2]
    acc3.update(codes[i])
    acc3.apply_all(rr, out)
allocprobe.report("an12760_sample", acc_step, (), 300)

buf = bytearray(6)
def acc_be16():
    i = st[0]
    i = i + 1 if i < 199 else 0
    st[0] = i
    buf[0] = i
    acc3.update(codes[i])
    acc3.apply_be16(buf, out)
allocprobe.report("an12760_be16", acc_be16, (), 300)

# analog gyro: simulated sensor in the VM for set-up, replayed codes for the hot path
sim = AnalogGyroSim(vref_mv=3300, divider=2.0, noise_mv=0.3, t_noise_mv=0.2, bits=12, seed=GYRO_SEED)
g = AnalogGyro(sim.rate, sim.temp, 3300, divider=2.0)
pts = adxrs_cal.three_point(g, sim, (-40, 25, 85))
g.set_three_point(pts[0], pts[1], pts[2])
sim.temp_c = 60
sim.rate_dps = -150.0
s = 0
for _ in range(64):
    s += g.rate()
print("GYRO", s // 64)
tc = []
rc = []
for i in range(97):
    sim.temp_c = -40 + i * 1.3
    sim.rate_dps = -250 + 5 * i
    tc.append(sim.temp.read_u16())
    rc.append(sim.rate.read_u16())
hot = AnalogGyro(ReplayADC(rc), ReplayADC(tc), 3300, divider=2.0)
hot.set_three_point(pts[0], pts[1], pts[2])
allocprobe.report("adxrs_rate", hot.rate, (), 300)
hot2 = AnalogGyro(ReplayADC(rc), ReplayADC(tc), 3300, divider=2.0, t_smooth=3, temp_every=4)
hot2.set_three_point(pts[0], pts[1], pts[2])
allocprobe.report("adxrs_rate_smooth", hot2.rate, (), 300)

ca = CrossAxis([[0.001, -0.004, 0.002], [0.004, -0.002, 0.001], [-0.002, -0.001, 0.0005]])
v = array("i", [150000, -200000, 262143])
def cross():
    v[0] = -v[0]
    ca.apply(v, out)
allocprobe.report("crossaxis", cross, (), 300)
ca.apply(array("i", [150000, -200000, 262143]), out)
print("CROSS", out[0], out[1], out[2])

# cross-axis with a quadratic temperature law, MPU-6500 codes; per sample a new code + apply
cl = CrossAxis(LAW0, law=LAW1, t_span_c=(-40, 85), t_scale=1 / 333.87, t_offset=21.0)
tcodes = array("i", [cl.code_of(-55 + 0.9 * i) for i in range(170)])  # across and beyond the span
def cross_law():
    i = st[0]
    i = i + 1 if i < 169 else 0
    st[0] = i
    v[0] = -v[0]
    cl.update(tcodes[i])
    cl.apply(v, out)
allocprobe.report("crossaxis_law", cross_law, (), 300)
for c in CODES:
    cl.update(c)
    cl.apply(array("i", [150000, -200000, 262143]), out)
    print("CLAW", c, out[0], out[1], out[2])
"""

LAW0 = [0.01, -0.004, 0.02, 0.004, -0.002, 0.001, -0.002, -0.031, 0.0005]
LAW1 = [[1e-4, -1e-4, 2e-5, 1e-4, 0.0, -3e-5, 1e-4, 1.5e-4, -1e-4], [1e-6, -5e-7, 0.0, 2e-7, 8e-7, 0.0, -1e-6, 0.0, 3e-7]]
T_SCALE = 1 / 333.87
CODES = [int(round((t - 21.0) / T_SCALE)) for t in (-60.0, -40.0, -7.5, 25.0, 61.0, 85.0, 110.0)]


def test_vm_results_and_zero_allocation(interp):
    T = [-40, -40, -40, 25, 25, 25, 105, 105, 105]
    G = [-1.0, 0.0, 1.0] * 3
    raw = [int(round(v * 16.384)) for v in F.simulate_mg(np.array(T, float), np.array(G), -20.0, 1.0, 0.0264, -0.001)]
    code = VM_CODE.replace("ROWS", repr(list(zip(T, raw)))).replace("LAW0", repr(LAW0)).replace(
        "LAW1", repr(LAW1)).replace("CODES", repr(CODES)).replace("GYRO_SEED", str(seeds.seed("vm_adinxp/gyro")))
    out = interps.run(interp, code, mounts=(REPO + "/tools/sim:/tools/sim",), paths=("/",))
    lines = {ln.split()[0]: ln.split()[1:] for ln in out.splitlines() if ln and not ln.startswith("ALLOC")}
    # AN12760 Table 10 AccTCOTCS in the VM: exactly -1000.0 / 0.0 / +1000.0 mg (0.1 mg units)
    assert [int(v) for v in lines["T10"]] == [-10000, 0, 10000] * 3
    # the VM computes the same integers as CPython for the same set-up
    acc = AN12760([(-20.0, (1.0,), 0.0264, (-0.001,))], 16384, (-40, 105), t_scale=1 / 333.87, t_offset=21.0,
                  out_per_g=10000)
    host = []
    for t, r in zip(T, raw):
        acc.update(acc.code_of(t))
        host.append(acc.apply(r))
    assert host == [int(v) for v in lines["T10"]]
    # three-point calibrated gyro in the VM on the simulated sensor, -150 dps at 60 degC
    assert abs(int(lines["GYRO"][0]) + 150000) < 600
    # cross-axis against float
    v = np.array([150000, -200000, 262143])
    E = np.array([[0.001, -0.004, 0.002], [0.004, -0.002, 0.001], [-0.002, -0.001, 0.0005]])
    assert np.max(np.abs(np.array([int(x) for x in lines["CROSS"]]) - (v + E @ v))) < 0.9
    # cross-axis temperature law: the VM's integers are CPython's, and within 0.8 LSB of float64
    # (I + E(T)) v with T from the code, held at the span's edges
    cl = CrossAxis(LAW0, law=LAW1, t_span_c=(-40, 85), t_scale=T_SCALE, t_offset=21.0)
    got = [[int(x) for x in ln.split()[1:]] for ln in out.splitlines() if ln.startswith("CLAW ")]
    assert [g[0] for g in got] == CODES
    for c, *o in got:
        host = [0, 0, 0]
        cl.update(c)
        cl.apply([150000, -200000, 262143], host)
        assert o == host
        d = min(max(c * T_SCALE + 21.0, -40.0), 85.0) - 25.0
        E = (np.array(LAW0) + np.array(LAW1[0]) * d + np.array(LAW1[1]) * d * d).reshape(3, 3)
        assert np.max(np.abs(np.array(o) - (v + E @ v))) < 0.8, (c, o)
    probes = alloc_lines(out)
    assert set(probes) == {"an12760_sample", "an12760_be16", "adxrs_rate", "adxrs_rate_smooth", "crossaxis",
                           "crossaxis_law"}
    for name, (b, ok) in probes.items():
        assert b == 0 and ok, (name, b, ok, out)
