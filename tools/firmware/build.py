"""Build the real interpreters the tests and benchmarks run (``make setup`` calls this).

    python -m tools.firmware.build [--out build/fw] [--micropython-src DIR] [--circuitpython-src DIR]

Builds what is missing from the output directory, and nothing else:

    an385/firmware.elf   MicroPython 1.27.0, ports/qemu BOARD=MPS2_AN385 (Cortex-M3)
    an500/firmware.elf   MicroPython 1.27.0, ports/qemu BOARD=MPS2_AN500 (Cortex-M7)
    mpy-cross            MicroPython 1.27.0 mpy-cross
    circuitpython        CircuitPython 10.2.1, ports/unix VARIANT=coverage
    rp2/firmware.bin     MicroPython 1.27.0, ports/rp2 BOARD=RPI_PICO (RP2040, Cortex-M0+), the image the
                         emulated Pico (tools/pico) boots; firmware.elf beside it (symbols)

Sources: ``--micropython-src`` / ``--circuitpython-src`` (or MICROPY_SRC / CIRCUITPY_SRC), checkouts of
those tags (for rp2 with its submodules: lib/pico-sdk, lib/tinyusb, lib/mbedtls, lib/micropython-lib);
otherwise the archives in ../shared/vendor are unpacked under <out>/src (the rp2 one under
<out>/src/rp2, its own tree). The steps are the ones ../shared/vendor/README.md checked: nothing from
micropython-lib is frozen into the QEMU boards (an empty manifest, and MPY_LIB_DIR pointed at an empty
directory instead of touching the source tree); the Pico keeps its board's own manifest (its
``_boot.py`` mounts littlefs), built with ``CMAKE_ARGS=-DPICO_NO_PICOTOOL=1`` in the environment so
pico-sdk does not try to download picotool; CircuitPython's version header wants a git tag, so an
unpacked archive becomes a one-commit repository tagged 10.2.1.
The Debian packages the firmware needs are installed with apt-get when running as root; otherwise the
one command to run is printed and the rest is built.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tarfile

from tools import REPO

MICROPY_TAG = "1.27.0"
CIRCUITPY_TAG = "10.2.1"
VENDOR = os.path.join(os.path.dirname(REPO), "shared", "vendor")
BOARDS = {"an385": "MPS2_AN385", "an500": "MPS2_AN500"}
# Debian package -> how to tell it is there
DEBIAN = {
    "gcc-arm-none-eabi": lambda: shutil.which("arm-none-eabi-gcc") is not None,
    "libnewlib-arm-none-eabi": lambda: os.path.isdir("/usr/lib/arm-none-eabi/newlib"),
    "qemu-system-arm": lambda: shutil.which("qemu-system-arm") is not None,
    "cmake": lambda: shutil.which("cmake") is not None,
    # the rp2 port links pico-sdk's C++ runtime bits: without it the link fails on <cstdlib>
    "libstdc++-arm-none-eabi-newlib": lambda: os.path.exists("/usr/lib/arm-none-eabi/newlib/libstdc++.a")
    and os.path.isdir("/usr/include/newlib/c++"),
}
RP2_DEBIAN = ["cmake", "gcc-arm-none-eabi", "libnewlib-arm-none-eabi", "libstdc++-arm-none-eabi-newlib"]


def log(msg):
    sys.stdout.write("fw-build: %s\n" % msg)
    sys.stdout.flush()


def sh(cmd, cwd=None, env=None):
    log("$ " + " ".join(cmd))
    subprocess.run(cmd, cwd=cwd, env=env, check=True)


def debian_packages(need):
    """Install the missing Debian packages among ``need`` when root; return those still missing."""
    missing = [p for p in need if not DEBIAN[p]()]
    if not missing:
        return []
    cmd = ["apt-get", "install", "-y", "--no-install-recommends"] + missing
    if hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("apt-get"):
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        sh(["apt-get", "update", "-q"], env=env)
        sh(cmd, env=env)
        missing = [p for p in missing if not DEBIAN[p]()]
    if missing:
        log("missing Debian packages; run:  sudo apt-get install -y %s" % " ".join(missing))
    return missing


def unpack(archive, dest_parent):
    """Unpack a vendor archive once; return its top directory."""
    path = os.path.join(VENDOR, archive)
    top = os.path.join(dest_parent, re.sub(r"-(qemu|unix|rp2)\.tar\.xz$", "", archive))
    if os.path.isdir(top) and os.path.exists(os.path.join(top, ".unpacked")):
        return top
    if not os.path.exists(path):
        raise SystemExit("fw-build: %s not found; give the source path (MICROPY_SRC= / CIRCUITPY_SRC=)" % path)
    log("unpacking %s" % path)
    os.makedirs(dest_parent, exist_ok=True)
    with tarfile.open(path) as tf:
        names = {n.split("/")[0] for n in tf.getnames()}
        if names != {os.path.basename(top)}:
            raise SystemExit("fw-build: %s does not hold one %s/ directory" % (path, os.path.basename(top)))
        if hasattr(tarfile, "data_filter"):
            tf.extractall(dest_parent, filter="tar")
        else:
            tf.extractall(dest_parent)
    open(os.path.join(top, ".unpacked"), "w").close()
    return top


def empty_inputs(out):
    """The empty frozen manifest and the stand-in micropython-lib directory both ports' builds check for."""
    d = os.path.join(out, "src")
    os.makedirs(os.path.join(d, "no-micropython-lib"), exist_ok=True)
    open(os.path.join(d, "no-micropython-lib", "README.md"), "a").close()
    manifest = os.path.join(d, "empty_manifest.py")
    with open(manifest, "w") as f:
        f.write("# nothing frozen: the library is served from the host\n")
    return manifest, os.path.join(d, "no-micropython-lib")


def jobs():
    return str(max(1, min(4, os.cpu_count() or 1)))


def build_micropython(out, src, want):
    manifest, mpylib = empty_inputs(out)
    if src is None:
        src = unpack("micropython-%s-qemu.tar.xz" % MICROPY_TAG, os.path.join(out, "src"))
    if "mpy-cross" in want or any(b in want for b in BOARDS):
        sh(["make", "-j", jobs(), "-C", os.path.join(src, "mpy-cross")])
    if "mpy-cross" in want:
        shutil.copy2(os.path.join(src, "mpy-cross", "build", "mpy-cross"), os.path.join(out, "mpy-cross"))
    for name, board in BOARDS.items():
        if name not in want:
            continue
        obj = os.path.join(out, "obj", name)
        sh(["make", "-j", jobs(), "-C", os.path.join(src, "ports", "qemu"), "BOARD=" + board, "BUILD=" + obj,
            "FROZEN_MANIFEST=" + manifest, "MPY_LIB_DIR=" + mpylib])
        os.makedirs(os.path.join(out, name), exist_ok=True)
        shutil.copy2(os.path.join(obj, "firmware.elf"), os.path.join(out, name, "firmware.elf"))


def build_circuitpython(out, src):
    manifest, mpylib = empty_inputs(out)
    if src is None:
        src = unpack("circuitpython-%s-unix.tar.xz" % CIRCUITPY_TAG, os.path.join(out, "src"))
        if not os.path.isdir(os.path.join(src, ".git")):
            git = ["git", "-c", "user.name=tempcomp", "-c", "user.email=build@tempcomp.invalid"]
            sh(git + ["init", "-q"], cwd=src)
            sh(git + ["add", "-A"], cwd=src)
            sh(git + ["commit", "-qm", "CircuitPython %s source (vendor archive)" % CIRCUITPY_TAG], cwd=src)
            sh(git + ["tag", CIRCUITPY_TAG], cwd=src)
    venv = os.path.join(out, "src", "cp-venv")
    vpy = os.path.join(venv, "bin", "python")
    if not os.path.exists(os.path.join(venv, ".stamp")):
        sh([sys.executable, "-m", "venv", venv])
        sh([vpy, "-m", "pip", "install", "-q", "--disable-pip-version-check", "huffman", "polib"])
        open(os.path.join(venv, ".stamp"), "w").close()
    env = dict(os.environ, PATH=os.path.join(venv, "bin") + os.pathsep + os.environ.get("PATH", ""))
    sh(["make", "-j", jobs(), "-C", os.path.join(src, "mpy-cross")], env=env)
    sh(["make", "-j", jobs(), "-C", os.path.join(src, "ports", "unix"), "VARIANT=coverage", "MICROPY_PY_FFI=0",
        "MICROPY_PY_BTREE=0", "MICROPY_PY_SSL=0", "FROZEN_MANIFEST=" + manifest, "MPY_LIB_DIR=" + mpylib], env=env)
    exe = os.path.join(out, "circuitpython")
    shutil.copy2(os.path.join(src, "ports", "unix", "build-coverage", "micropython"), exe)
    ver = subprocess.run([exe, "-c", "import sys; print(sys.implementation.name, sys.implementation.version[:3])"],
                         capture_output=True, text=True).stdout.split(None, 1)
    if ver[:1] != ["circuitpython"]:
        raise SystemExit("fw-build: %s is not CircuitPython: %r" % (exe, ver))


def build_rp2(out, src):
    """RPI_PICO firmware (ports/rp2) into <out>/rp2/firmware.{bin,elf}."""
    if src is None:
        src = unpack("micropython-%s-rp2.tar.xz" % MICROPY_TAG, os.path.join(out, "src", "rp2"))
    elif not os.path.exists(os.path.join(src, "lib", "pico-sdk", "README.md")):
        raise SystemExit("fw-build: %s has no lib/pico-sdk: run `make -C ports/rp2 submodules` there first" % src)
    obj = os.path.join(out, "obj", "rp2")
    # CMAKE_ARGS in the environment: on make's command line it would replace the Makefile's own
    env = dict(os.environ, CMAKE_ARGS="-DPICO_NO_PICOTOOL=1")
    sh(["make", "-j", jobs(), "-C", os.path.join(src, "mpy-cross")])
    sh(["make", "-j", jobs(), "-C", os.path.join(src, "ports", "rp2"), "BOARD=RPI_PICO", "BUILD=" + obj], env=env)
    os.makedirs(os.path.join(out, "rp2"), exist_ok=True)
    shutil.copy2(os.path.join(obj, "firmware.elf"), os.path.join(out, "rp2", "firmware.elf"))
    # the .bin last: it is what says the build is there
    shutil.copy2(os.path.join(obj, "firmware.bin"), os.path.join(out, "rp2", "firmware.bin"))


def rp2_bootrom(out):
    """The RP2040's B1 mask ROM for rp2040js (rp2040-bootrom-b1.mjs in ../shared/vendor) beside the
    Pico firmware: the virtual Pico boots through it (tools/pico/boot.mjs)."""
    dst = os.path.join(out, "rp2", "bootrom.mjs")
    src = os.path.join(VENDOR, "rp2040-bootrom-b1.mjs")
    if os.path.exists(os.path.join(out, "rp2", "firmware.bin")) and not os.path.exists(dst):
        if os.path.exists(src):
            shutil.copy2(src, dst)
        else:
            log("%s not found: the virtual Pico cannot boot without the RP2040 bootrom" % src)


def artefacts(out):
    return {"mpy-cross": os.path.join(out, "mpy-cross"),
            "an385": os.path.join(out, "an385", "firmware.elf"),
            "an500": os.path.join(out, "an500", "firmware.elf"),
            "circuitpython": os.path.join(out, "circuitpython"),
            "rp2": os.path.join(out, "rp2", "firmware.bin")}


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m tools.firmware.build", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="example: python -m tools.firmware.build --micropython-src ~/micropython")
    ap.add_argument("--out", default=os.path.join(REPO, "build", "fw"))
    ap.add_argument("--micropython-src", default=os.environ.get("MICROPY_SRC") or None)
    ap.add_argument("--circuitpython-src", default=os.environ.get("CIRCUITPY_SRC") or None)
    a = ap.parse_args(argv)
    out = os.path.abspath(a.out)
    for src in (a.micropython_src, a.circuitpython_src):
        if src and not os.path.isdir(os.path.join(src, "py")):
            ap.error("%s is not a MicroPython/CircuitPython source tree (no py/ inside)" % src)
    want = [k for k, p in artefacts(out).items() if not os.path.exists(p)]
    need = ["qemu-system-arm"]
    if any(b in want for b in BOARDS):
        need += ["gcc-arm-none-eabi", "libnewlib-arm-none-eabi"]
    if "rp2" in want:
        need += [p for p in RP2_DEBIAN if p not in need]
    still = debian_packages(need)
    if not want:
        rp2_bootrom(out)
        log("%s: all present (%s)" % (a.out, ", ".join(artefacts(out))))
        return 0
    os.makedirs(out, exist_ok=True)
    if any(p in still for p in ("gcc-arm-none-eabi", "libnewlib-arm-none-eabi")):
        skip = [b for b in BOARDS if b in want]
        log("not building %s without the ARM toolchain; their tests will skip" % ", ".join(skip))
        want = [w for w in want if w not in skip]
    if "rp2" in want and any(p in still for p in RP2_DEBIAN):
        log("not building rp2 (the Pico firmware) without %s; its tests will skip"
            % ", ".join(p for p in RP2_DEBIAN if p in still))
        want.remove("rp2")
    mp = os.path.abspath(a.micropython_src) if a.micropython_src else None
    cp = os.path.abspath(a.circuitpython_src) if a.circuitpython_src else None
    if [w for w in want if w not in ("circuitpython", "rp2")]:
        build_micropython(out, mp, want)
    if "rp2" in want:
        build_rp2(out, mp)
    if "circuitpython" in want:
        build_circuitpython(out, cp)
    rp2_bootrom(out)
    left = [k for k, p in artefacts(out).items() if not os.path.exists(p)]
    log("built %s%s" % (", ".join(w for w in want if w not in left) or "nothing",
                        "; still missing: " + ", ".join(left) if left else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
