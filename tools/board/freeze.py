"""Build MicroPython firmware with tempcomp frozen in: the install path for the smallest boards.

    .venv/bin/python -m tools.board.freeze OUTDIR [--board MPS2_AN385] [--micropython-src DIR]

Frozen modules run their bytecode from flash, so an import costs the heap only the module's
globals and objects (docs/install.md, docs/ram.md). Your board's manifest needs one line,
``include("PATH/TO/tempcomp/manifest.py")``; this tool proves that line works by building the
qemu port's MPS2-AN385 (Cortex-M3) firmware with exactly such a manifest, from the MicroPython
1.27.0 sources (``--micropython-src`` / MICROPY_SRC, else ../shared/vendor unpacked under OUTDIR),
into ``OUTDIR/<board>/firmware.elf``. Takes a few minutes (mpy-cross, then the port).
"""

import argparse
import os
import shutil
import subprocess
import sys

from tools import REPO
from tools.firmware import build as fwbuild

MANIFEST = os.path.join(REPO, "manifest.py")
BOARDS = {"MPS2_AN385": "an385", "MPS2_AN500": "an500"}


def board_manifest(out):
    """A board manifest as a user writes it: it only includes tempcomp's (and nothing else)."""
    path = os.path.join(out, "board_manifest.py")
    with open(path, "w") as f:
        f.write("# tempcomp frozen into the firmware (tools/board/freeze.py)\n")
        f.write("include(%r)\n" % MANIFEST)
    return path


def build(out, board="MPS2_AN385", src=None, quiet=True):
    """Build the firmware with tempcomp frozen; return the path of its firmware.elf."""
    out = os.path.abspath(out)
    os.makedirs(out, exist_ok=True)
    src = src or os.environ.get("MICROPY_SRC") or fwbuild.unpack(
        "micropython-%s-qemu.tar.xz" % fwbuild.MICROPY_TAG, os.path.join(out, "src"))
    mpylib = os.path.join(out, "no-micropython-lib")
    os.makedirs(mpylib, exist_ok=True)
    open(os.path.join(mpylib, "README.md"), "a").close()
    manifest = board_manifest(out)
    obj = os.path.join(out, "obj-" + board)
    kw = {"stdout": subprocess.DEVNULL} if quiet else {}
    for cmd in (["make", "-j", fwbuild.jobs(), "-C", os.path.join(src, "mpy-cross")],
                ["make", "-j", fwbuild.jobs(), "-C", os.path.join(src, "ports", "qemu"), "BOARD=" + board,
                 "BUILD=" + obj, "FROZEN_MANIFEST=" + manifest, "MPY_LIB_DIR=" + mpylib]):
        proc = subprocess.run(cmd, stderr=subprocess.PIPE, text=True, **kw)
        if proc.returncode != 0:
            raise SystemExit("freeze: %s failed:\n%s" % (" ".join(cmd[:4]), proc.stderr[-3000:]))
    dst = os.path.join(out, BOARDS.get(board, board.lower()), "firmware.elf")
    os.makedirs(os.path.dirname(dst), exist_ok=True)
    shutil.copy2(os.path.join(obj, "firmware.elf"), dst)
    return dst


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m tools freeze", description=__doc__.splitlines()[0])
    ap.add_argument("outdir", help="where the sources are unpacked and the firmware is written")
    ap.add_argument("--board", default="MPS2_AN385", choices=sorted(BOARDS), help="qemu port board")
    ap.add_argument("--micropython-src", default=None, help="a MicroPython 1.27.0 source tree")
    a = ap.parse_args(argv)
    print(build(a.outdir, a.board, a.micropython_src, quiet=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
