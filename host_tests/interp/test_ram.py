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
