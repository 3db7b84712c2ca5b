"""Packaging: every lib/ module compiles with mpy-cross, loads as .mpy in the VM, is listed in
the mip manifest (package.json) and in manifest.py's package; pyright really checks against
the MicroPython stubs."""

import json
import os
import subprocess

from tools.board import build_mpy
from tools.firmware import mpvm as vm

REPO = build_mpy.REPO


def test_every_lib_module_compiles_with_mpy_cross(tmp_path):
    rows = build_mpy.build(str(tmp_path))
    assert rows, "no modules found in lib/"
    names = {r[0] for r in rows}
    assert "tempcomp/fixedpoint.py" in names
    for rel, _py, mpy in rows:
        assert (tmp_path / (rel[:-3] + ".mpy")).read_bytes()[:1] == b"M", rel
        assert mpy > 0


def test_compiled_modules_load_in_the_vm(tmp_path):
    build_mpy.build(str(tmp_path))
    out = vm.run(
        "import tempcomp.fixedpoint as f\nprint(f.__file__)\n"
        "c = f.Compensator([[1.0]], [[2.0]], (0, 10))\nc.update(5)\nprint(c.apply(101))\n",
        mounts=(str(tmp_path) + ":/mpylib",),
        paths=("/mpylib",),
    )
    lines = out.split()
    assert lines[0].endswith(".mpy")
    assert lines[1] == "50"


def test_mip_manifest_lists_every_lib_module():
    with open(os.path.join(REPO, "package.json")) as f:
        pkg = json.load(f)
    listed = {dst: src for dst, src in pkg["urls"]}
    for rel in build_mpy.lib_sources():
        assert listed.get(rel) == "lib/" + rel, "package.json urls miss %s" % rel
    for dst, src in pkg["urls"]:
        assert os.path.exists(os.path.join(REPO, src)), src


def test_pyright_rejects_a_call_that_micropython_lacks(tmp_path):
    # the type check must use the MicroPython stubs, not CPython's: time.perf_counter is CPython-only
    probe = tmp_path / "probe.py"
    probe.write_text("import time\nprint(time.ticks_ms())\nprint(time.perf_counter())\n")
    cfg = json.load(open(os.path.join(REPO, "pyrightconfig.json")))
    cfg["include"] = [str(probe)]
    for k in ("typeshedPath",):
        cfg[k] = os.path.join(REPO, cfg[k])
    cfg["venvPath"] = REPO
    (tmp_path / "pyrightconfig.json").write_text(json.dumps(cfg))
    exe = os.path.join(REPO, "tools", "node_modules", ".bin", "pyright")
    proc = subprocess.run([exe, "-p", str(tmp_path / "pyrightconfig.json")], capture_output=True, text=True)
    assert proc.returncode != 0
    assert "perf_counter" in proc.stdout
    assert "ticks_ms" not in proc.stdout
