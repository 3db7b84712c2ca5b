"""RAM on the Cortex-M3 firmware (MPS2-AN385, ~140 KB heap): every on-device module imports from
its .py source, compiled on the board itself (what a `mip install` of the .py package leaves a
board to do), under the RAM bench's own conditions; the calibration session imports from .mpy;
the boots load the layers they need and no more. The heap figures and their budgets are
`make bench` figures (tools/bench/ram.py, docs/ram.md), not assertions here."""
import os
import shutil

import pytest
import seeds
from paths import REPO


@pytest.mark.parametrize("interp", ["an385"], indirect=True)
def test_every_module_imports_from_py_as_the_bench_measures_it(interp, tmp_path):
    # The bench's route, through its own function (tools.bench.ram.measure_import): a freshly reset
    # board for each module, the .py tree served over the UART by mpremote's mount, whose reads
    # (a Python file object, one round trip per small read) allocate between the parser's chunks
    # and leave the compile a fragmented heap. This test used to import every module in one run
    # from a ROMFS image (read in place, as from flash): that passed while the bench hit a
    # MemoryError (tempcomp.mlx90609 compiling fixedpoint.py after the SPI adapter, docs/ram.md).
    from tools.bench import ram

    shutil.copytree(os.path.join(REPO, "lib", "tempcomp"), str(tmp_path / "tempcomp"))
    got = {mod: ram.measure_import(interp, str(tmp_path), mod) for mod in ram.modules()}
    failed = [m for m in got if got[m] is None]
    assert not failed, "MemoryError importing from .py, as `python -m tools bench ram` measures it: %s" % failed
    assert all(v > 0 for v in got.values()), got
    # served from the staged .py tree, not from the .mpy image every run also mounts at /lib
    out = interp.run("import tempcomp.store_crc as m\nprint('FROM', m.__file__)\n",
                     mounts=(str(tmp_path) + ":/ram",), paths=("/ram",))
    assert "FROM /ram/tempcomp/store_crc.py" in out, out


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
sim = MPU6xxxSim("MPU-6500", seed=PART_SEED)
imu = MPU6xxx(SimI2C({0x68: sim}))
t0 = imu.temp_raw()
model = BiasModel([(t0 - 2000, (10.5, -20.25, 3.0), (1000.0, -501.5, 2300.0)),
                   (t0, (12.0, -19.0, 2.5), (1004.0, -498.0, 2296.5)),
                   (t0 + 2000, (14.5, -17.0, 1.0), (1010.0, -493.0, 2290.0))])
print("FOLLOW", imu.follow(model), imu.follow(model), imu.offsets())
""".replace("PART_SEED", str(seeds.seed("ram/follow_part")))  # a part of this run


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
                     "imu = MPU6xxx(SimI2C({0x68: mpu6xxx_sim.MPU6xxxSim('MPU-6500', seed=%d)}))\n"
                     "imu.apply((1, 2, 3), imu.factory)\n"
                     "imu.check()\n"
                     "print('LOADED', ' '.join(sorted(m for m in sys.modules if m.startswith('tempcomp'))))\n"
                     % seeds.seed("ram/boot_part"),
                     mounts=(os.path.join(REPO, "tools", "sim") + ":/tools/sim",), paths=("/",))
    assert out.split("LOADED ", 1)[1].split() == [
        "tempcomp", "tempcomp.bus", "tempcomp.mpu6xxx", "tempcomp.mpu6xxx_parts"], out


@pytest.mark.parametrize("interp", ["an385"], indirect=True)
def test_the_sensors_restore_boot_loads_the_layers_it_needs_and_no_more(interp, tmp_path):
    # the boot of README's "Keep it across power cycles" through tempcomp.sensors.restore (the RAM
    # bench's row, docs/ram.md): the store's reader, the driver on the I2C adapter and the parts
    # table, offset(T) resumed from mpu_tcc. Not the fault words (mpu6xxx_faults), busio
    # (bus_busio), the store's checker, encoder or writer, nor the fixed-point set-up.
    from tools.bench import ram

    ram.make_store(str(tmp_path / "t.cal"))
    (tmp_path / "ram_board.py").write_text(ram._BOARD.format(seed=ram.SEED))
    out = interp.run("import sys\nimport ram_board\nfrom tempcomp.sensors import restore\n"
                     "s = restore(ram_board, '/st/t.cal')\nbuf = [0] * 7\ns.mpu.read_compensated(buf)\n"
                     "s.mpu.check(every_ms=1000)\nprint('READ', buf)\n"
                     "print('LOADED', ' '.join(sorted(m for m in sys.modules if m.startswith('tempcomp'))))\n",
                     mounts=(os.path.join(REPO, "tools", "sim") + ":/tools/sim", str(tmp_path) + ":/st"),
                     paths=("/st", "/"))
    assert "restored from /st/t.cal: mpu6xxx, mpu_tc\n" in out, out
    assert "READ [0, 0, 0, 0, 0, 0, 0]" not in out, out
    assert out.split("LOADED ", 1)[1].split() == [
        "tempcomp", "tempcomp.bus", "tempcomp.mpu6xxx", "tempcomp.mpu6xxx_parts", "tempcomp.mpu6xxx_rt",
        "tempcomp.sensors", "tempcomp.store", "tempcomp.store_format"], out
