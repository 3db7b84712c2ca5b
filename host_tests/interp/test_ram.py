"""RAM on the Cortex-M3 firmware (MPS2-AN385, ~140 KB heap): every on-device module imports from
its .py source, compiled on the board itself (what a `mip install` of the .py package leaves a
board to do), and the calibration session imports from .mpy. The heap figures and their budgets
are `make bench` figures (tools/bench/ram.py, docs/ram.md), not assertions here."""
import os

import pytest
from paths import REPO

MODULES = ["tempcomp"] + sorted("tempcomp." + f[:-3] for f in os.listdir(os.path.join(REPO, "lib", "tempcomp"))
                                if f.endswith(".py") and f != "__init__.py")

# each import on a heap emptied of tempcomp: the module and what it imports, compiled here
SCRIPT = r"""
import gc, sys
for name in %r:
    for m in [m for m in sys.modules if m.startswith("tempcomp")]:
        del sys.modules[m]
    gc.collect()
    a0 = gc.mem_alloc()
    try:
        __import__(name)
        gc.collect()
        print("IMPORT", name, sys.modules[name].__file__, gc.mem_alloc() - a0)
    except MemoryError:
        print("IMPORT", name, "MemoryError", 0)
"""


def imports(out):
    return {ln.split()[1]: (ln.split()[2], int(ln.split()[3])) for ln in out.splitlines() if ln.startswith("IMPORT ")}


@pytest.mark.parametrize("interp", ["an385"], indirect=True)
def test_every_module_imports_from_py_on_the_cortex_m3_heap(interp):
    got = imports(interp.run(SCRIPT % (MODULES,), mpy=False))
    assert sorted(got) == sorted(MODULES)
    failed = [m for m in MODULES if got[m][0] == "MemoryError"]
    assert not failed, "MemoryError importing from .py: %s" % failed
    for m in MODULES:
        assert got[m][0].endswith(".py"), got[m]  # compiled on the board, not a .mpy
        assert got[m][1] > 0


@pytest.mark.parametrize("interp", ["an385"], indirect=True)
def test_session_imports_from_mpy_without_the_drivers(interp):
    out = interp.run(SCRIPT % (["tempcomp.session"],)
                     + "print('LOADED', ' '.join(sorted(m for m in sys.modules if m.startswith('tempcomp'))))\n")
    path, _ = imports(out)["tempcomp.session"]
    assert path.endswith("session.mpy"), path
    loaded = out.split("LOADED ", 1)[1].split()
    # the drivers, the store and the fixed-point core are loaded when a part is found or saved
    assert loaded == ["tempcomp", "tempcomp.sensors", "tempcomp.session"], loaded


FOLLOW = r"""
from tools.sim import mpu6xxx_sim
from tools.sim.buses import SimI2C
from tools.sim.mpu6xxx_sim import MPU6xxxSim
from tempcomp.mpu6xxx import MPU6xxx
mpu6xxx_sim._NOISE_N = 256  # its default 4096 boxed floats would take half this heap
from tempcomp.mpu6xxx_tc import BiasModel
sim = MPU6xxxSim("MPU-6500", seed=3)
imu = MPU6xxx(SimI2C({0x68: sim}))
t0 = imu.temp_raw()
model = BiasModel([(t0 - 2000, (10.5, -20.25, 3.0), (1000.0, -501.5, 2300.0)),
                   (t0, (12.0, -19.0, 2.5), (1004.0, -498.0, 2296.5)),
                   (t0 + 2000, (14.5, -17.0, 1.0), (1010.0, -493.0, 2290.0))])
print("FOLLOW", imu.follow(model), imu.follow(model), imu.offsets())
"""


@pytest.mark.parametrize("interp", ["an385"], indirect=True)
def test_what_a_boot_loads_late_works_on_the_firmware(interp, tmp_path):
    # follow() lives beside BiasModel and the salvage of a corrupt newest copy in its own module,
    # both loaded on first use: run them from .mpy on the firmware, against CPython's answer
    import subprocess
    import sys

    from tempcomp.store import Store

    path = tmp_path / "t.cal"
    st = Store(str(path))
    st.save("a", (1, 2))
    st.save("b", (3, 4))  # only in the newest copy
    img = bytearray(path.read_bytes())
    img[-6] ^= 0x10  # one flipped bit in the newest copy's last value: its CRC fails
    path.write_bytes(bytes(img))
    out = interp.run(FOLLOW + "from tempcomp.store import Store, StoreError\n"
                     "try:\n    Store('/st/t.cal').load('b')\nexcept StoreError as e:\n    print('LOST', e)\n",
                     mounts=(os.path.join(REPO, "tools", "sim") + ":/tools/sim", str(tmp_path) + ":/st"),
                     paths=("/",))
    ref = subprocess.run([sys.executable, "-c", FOLLOW], capture_output=True, text=True, cwd=REPO,
                         env=dict(os.environ, PYTHONPATH=os.path.join(REPO, "lib") + os.pathsep + REPO))
    assert ref.returncode == 0, ref.stderr
    follow = [ln for ln in out.splitlines() if ln.startswith("FOLLOW ")]
    assert follow == [ref.stdout.strip()], (out, ref.stdout)
    assert follow[0].startswith("FOLLOW True False ")  # wrote once, then nothing until T moves
    assert "records only it held (lost): 'b'" in out, out


@pytest.mark.parametrize("interp", ["an385"], indirect=True)
def test_an_intact_store_is_read_by_the_reader_alone(interp, tmp_path):
    # the boot's heap figure (docs/ram.md) holds only while an intact store loads nothing more than
    # the facade and the format it stands on: the diagnosis (store_check), the salvage, the encoder
    # and the writer come with a damaged copy or a save
    from tempcomp.store import Store

    st = Store(str(tmp_path / "t.cal"))
    st.save("a", (1, 2))
    st.save("b", (3, 4))  # two generations: path and path.old both read
    out = interp.run("import sys\nfrom tempcomp.store import Store\nprint('VAL', Store('/st/t.cal').load('b'))\n"
                     "print('LOADED', ' '.join(sorted(m for m in sys.modules if m.startswith('tempcomp'))))\n",
                     mounts=(str(tmp_path) + ":/st",))
    assert "VAL (3, 4)" in out, out
    assert out.split("LOADED ", 1)[1].split() == ["tempcomp", "tempcomp.store", "tempcomp.store_format"], out


@pytest.mark.parametrize("interp", ["an385"], indirect=True)
def test_the_driver_boot_loads_the_bottom_layers_it_needs_and_no_more(interp):
    # the registers boot (docs/ram.md): the driver with the I2C adapter and the parts table; the
    # capture, the offset registers' units, the SPI adapter and the temperature model load on use
    out = interp.run("import sys\n"
                     "from tools.sim import mpu6xxx_sim\n"
                     "from tools.sim.buses import SimI2C\n"
                     "mpu6xxx_sim._NOISE_N = 256\n"
                     "from tempcomp.mpu6xxx import MPU6xxx\n"
                     "imu = MPU6xxx(SimI2C({0x68: mpu6xxx_sim.MPU6xxxSim('MPU-6500', seed=3)}))\n"
                     "imu.apply((1, 2, 3), imu.factory)\n"
                     "imu.check()\n"
                     "print('LOADED', ' '.join(sorted(m for m in sys.modules if m.startswith('tempcomp'))))\n",
                     mounts=(os.path.join(REPO, "tools", "sim") + ":/tools/sim",), paths=("/",))
    assert out.split("LOADED ", 1)[1].split() == [
        "tempcomp", "tempcomp.bus", "tempcomp.mpu6xxx", "tempcomp.mpu6xxx_parts"], out
