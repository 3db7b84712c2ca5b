"""The runner behind the ``interp`` fixture: each interpreter is the one it claims to be, a Python error
surfaces as InterpError with its traceback, the soft reset between scripts leaves nothing behind, and
mounts and paths are seen as in the WebAssembly VM."""
import pytest

from tools.firmware.interp import InterpError

IDENTITY = {  # name -> (sys.implementation.name, version, a fact only that build has)
    "wasm": ("micropython", (1,), "webassembly"),
    "an385": ("micropython", (1, 27, 0), "mps2-an385 with Cortex-M3"),
    "an500": ("micropython", (1, 27, 0), "mps2-an500 with Cortex-M7"),
    "circuitpython": ("circuitpython", (10, 2, 1), "coverage"),
}


def test_identity(interp):
    out = interp.run("import sys\nprint(sys.implementation.name)\nprint(tuple(sys.implementation.version[:3]))\n"
                     "print(getattr(sys.implementation, '_machine', ''), getattr(sys.implementation, '_build', ''),"
                     " sys.platform)\n").split("\n")
    impl, version, fact = IDENTITY[interp.name]
    assert out[0] == impl
    assert eval(out[1])[:len(version)] == version
    assert fact in out[2]


def test_error_and_reset(interp, tmp_path):
    with pytest.raises(InterpError, match="ValueError: boom"):
        interp.run("LEFT_OVER = 1\nprint('before')\nraise ValueError('boom')\n")
    # a fresh interpreter state each run: nothing of the previous script is left
    assert interp.run("print('LEFT_OVER' in globals())").strip() == "False"
    (tmp_path / "probe_mod.py").write_text("X = 41\n")
    out = interp.run("import probe_mod, tempcomp\nprint(probe_mod.X + 1)\n"
                     "with open('/hostdir/w.txt', 'w') as f:\n    f.write('hi')\n",
                     mounts=(str(tmp_path) + ":/hostdir",), paths=("/hostdir",))
    assert out.strip() == "42"
    if interp.name != "wasm":  # the wasm VM copies mounts in; the others write through to the host
        assert (tmp_path / "w.txt").read_text() == "hi"
