"""Install paths: `make dist` builds a mip package of .mpy files per .mpy version, and `make deploy`
installs it by default with real `mpremote mip install` (here onto the virtual board), .py on
request; the board then imports tempcomp from the .mpy files and restores nothing it was not given."""
import json
import os
import subprocess
import sys

import pytest

from tools.board import build_mpy, deploy, dist
from tools.board.boardctl import Remote, VirtualBoard

REPO = build_mpy.REPO


@pytest.fixture(scope="module")
def package(tmp_path_factory):
    return dist.build(str(tmp_path_factory.mktemp("dist")))


def test_dist_is_one_package_per_mpy_version_listing_every_module(package):
    out = subprocess.run([build_mpy.mpy_cross(), "--version"], capture_output=True, text=True).stdout
    assert os.path.basename(package) == "mpy-v6.3" and "mpy v6.3" in out
    pkg = json.load(open(os.path.join(package, "package.json")))
    root = json.load(open(os.path.join(REPO, "package.json")))
    assert pkg["version"] == root["version"] and pkg["deps"] == []
    # the viper kernels twice: Thumb-2 (armv7m) and, picked where that is refused, the M0+'s
    want = sorted([rel[:-3] + ".mpy" for rel in build_mpy.lib_sources()]
                  + ["tempcomp/native_m0.mpy", "tempcomp/augment_native_m0.mpy", "tempcomp/augment_vrun_m0.mpy"])
    assert sorted(dst for dst, _ in pkg["urls"]) == want
    for dst, src in pkg["urls"]:
        assert dst == src  # relative to package.json: mip resolves it next to the manifest
        head = open(os.path.join(package, src), "rb").read(4)
        assert head[:2] == b"M\x06", (src, head)  # .mpy major version 6
        # arch bits (py/persistentcode.h: 4 armv6m, 5 armv7m): only the kernel modules carry
        # machine code; an armv6m .mpy loads on every ARM Cortex-M, an armv7m one not on an M0+
        arch = head[2] >> 2
        assert arch == {"native.mpy": 5, "native_m0.mpy": 4, "thumb.mpy": 4, "augment_native.mpy": 5,
                        "augment_native_m0.mpy": 4, "augment_thumb.mpy": 4, "augment_vrun.mpy": 5,
                        "augment_vrun_m0.mpy": 4}.get(os.path.basename(src), 0), src


def test_deploy_installs_mpy_by_default_and_py_on_request(tmp_path):
    cmds = deploy.deploy_commands("socket://127.0.0.1:1", "pico")
    assert cmds[0][-1].endswith(os.path.join("mpy-v6.3", "package.json"))
    assert os.path.exists(cmds[0][-1])
    py = deploy.deploy_commands("socket://127.0.0.1:1", "pico", py=True)
    assert py[0][-1] == os.path.join(REPO, "package.json")


def test_mip_install_of_the_mpy_package_on_the_virtual_board(tmp_path, package):
    vb = VirtualBoard(str(tmp_path / "vb"))
    try:
        vb.start()
        mp = [sys.executable, "-m", "mpremote", "connect", vb.url]
        proc = subprocess.run(mp + ["mip", "install", "--target", "/lib", os.path.join(package, "package.json")],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        out = Remote(vb.url).run(
            "import os\nprint('FILES', sorted(os.listdir('/lib/tempcomp')))\n"
            "import tempcomp.session, tempcomp.mpu6xxx\n"
            "print('FROM', tempcomp.session.__file__, tempcomp.mpu6xxx.__file__)\n")
    finally:
        vb.stop()
    files = eval(out.split("FILES", 1)[1].splitlines()[0])
    assert files == sorted([os.path.basename(rel)[:-3] + ".mpy" for rel in build_mpy.lib_sources()]
                           + ["native_m0.mpy", "augment_native_m0.mpy", "augment_vrun_m0.mpy"])
    assert "/lib/tempcomp/session.mpy /lib/tempcomp/mpu6xxx.mpy" in out, out
