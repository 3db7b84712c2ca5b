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
    except Exception as e:
        print("IMPORT", name, type(e).__name__)
    for m in [m for m in sys.modules if m.startswith("tempcomp")]:
        del sys.modules[m]
    gc.collect()
"""


def results(out):
    return {ln.split()[1]: ln.split()[2] for ln in out.splitlines() if ln.startswith("IMPORT ")}


# machine-code kernels: fixedpoint and augment import them where the emitter exists and fall back
# to pure Python on these errors (a port without viper / asm_thumb refuses them at compile time)
KERNELS = ("tempcomp.native", "tempcomp.thumb", "tempcomp.augment_native", "tempcomp.augment_thumb",
           "tempcomp.augment_vrun")
REFUSALS = ("SyntaxError", "ImportError", "NotImplementedError", "ValueError")


def test_every_module_imports(interp):
    got = results(interp.run(SCRIPT % (["tempcomp"] + MODULES,)))
    assert set(got) == set(["tempcomp"] + MODULES)
    assert {m: r for m, r in got.items() if m not in KERNELS} == {m: "ok" for m in got if m not in KERNELS}
    for m in KERNELS:
        if m in got:
            # the Cortex-M firmware has both emitters (Thumb-2): there they must load
            assert got[m] == "ok" if interp.name in ("an385", "an500") else got[m] in ("ok",) + REFUSALS, (m, got[m])

