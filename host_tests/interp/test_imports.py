"""Every on-device module imports on every interpreter (on the firmware as the .mpy a board gets from
``make deploy``; compiling the biggest .py sources on the board itself needs more than the Cortex-M3's
~140 KB heap)."""
import os

from paths import REPO

MODULES = sorted("tempcomp." + f[:-3] for f in os.listdir(os.path.join(REPO, "lib", "tempcomp"))
                 if f.endswith(".py") and f != "__init__.py")

SCRIPT = r"""
import gc, sys
for name in %r:
    try:
        __import__(name)
        print("IMPORT", name, "ok")
    except MemoryError as e:
        print("IMPORT", name, "MemoryError")
    for m in [m for m in sys.modules if m.startswith("tempcomp")]:
        del sys.modules[m]
    gc.collect()
"""


def results(out):
    return {ln.split()[1]: ln.split()[2] for ln in out.splitlines() if ln.startswith("IMPORT ")}


def test_every_module_imports(interp):
    got = results(interp.run(SCRIPT % (["tempcomp"] + MODULES,)))
    assert got == {m: "ok" for m in ["tempcomp"] + MODULES}

