"""One way to run a script on each real interpreter the on-device code supports.

    from tools.firmware.interp import open_interp
    with open_interp("an385") as it:          # boots the firmware once
        out = it.run("import tempcomp; print(tempcomp.__name__)")   # soft reset, then the script

Interpreters (``INTERPRETERS``):

- ``wasm``: the MicroPython WebAssembly VM (``mpvm.mjs`` under node), a fresh VM per script.
- ``an385``: MicroPython 1.27.0 firmware for the MPS2-AN385 board (Cortex-M3, soft float,
  single-precision floats, ~140 KB heap) under ``qemu-system-arm``.
- ``an500``: the same for MPS2-AN500 (Cortex-M7, double-precision FPU).
- ``circuitpython``: CircuitPython 10.2.1's unix port (coverage variant), a fresh process per script.

Every script sees the same filesystem: ``lib/`` at ``/lib`` and ``host_tests/device/`` at
``/vmtest``, both on ``sys.path``, plus ``mounts`` (``"HOSTDIR:/VMDIR"``) and ``paths`` as
``mpvm.run`` takes them. The boards have no filesystem of their own: lib/, host_tests/device/ and
tools/sim/ are ROMFS images (``vfs.VfsRom``, as ``mpremote romfs`` deploys) loaded into the board's
spare RAM at boot and mounted where the script expects them; anything else (``tmp_path`` mounts, the
root) is served over the UART by mpremote's mount protocol, so writes land in the host directory.
The firmware runs under ``-icount shift=0``:
``time.ticks_us()`` then advances one microsecond per 1000 executed instructions (1 ns each).

On the firmware the repository's directories (lib/, host_tests/device/, mounted tools/ folders) are
served as .mpy compiled by build/fw/mpy-cross (``-march=armv7m``), as ``make deploy`` installs the
library on a board; ``run(..., mpy=False)`` serves the .py sources instead (a ~140 KB heap cannot
compile the biggest modules).

``run`` raises ``InterpError`` (an ``AssertionError``) when the script raises, with its output and
traceback. Binaries come from ``build/fw`` (``make setup`` builds them: tools/firmware/build.py).
"""
import os
import re
import select
import shutil
import signal
import subprocess
import tempfile
import time

from tools import REPO

FW_DIR = os.environ.get("TEMPCOMP_FW_DIR") or os.path.join(REPO, "build", "fw")
INTERPRETERS = ("wasm", "an385", "an500", "circuitpython")
VM_TEST_DIR = os.path.join(REPO, "host_tests", "device")
QEMU_MACHINE = {"an385": "mps2-an385", "an500": "mps2-an500"}


class InterpError(AssertionError):
    pass


class Unavailable(RuntimeError):
    """The interpreter's binary (or qemu) is missing: ``make setup`` builds it."""


def binary(name):
    """Path of the file an interpreter needs (firmware.elf, the circuitpython binary)."""
    if name in QEMU_MACHINE:
        return os.path.join(FW_DIR, name, "firmware.elf")
    if name == "circuitpython":
        return os.path.join(FW_DIR, "circuitpython")
    if name == "mpy-cross":
        return os.path.join(FW_DIR, "mpy-cross")
    return None


def missing(name):
    """Why ``name`` cannot run here (one line), or None when it can."""
    if name not in INTERPRETERS:
        return "unknown interpreter %r (one of %s)" % (name, ", ".join(INTERPRETERS))
    if name == "wasm":
        return None if shutil.which("node") else "node is not installed"
    path = binary(name)
    if not os.path.exists(path):
        return "%s is missing: run make setup" % os.path.relpath(path, REPO)
    if name in QEMU_MACHINE and not shutil.which("qemu-system-arm"):
        return "qemu-system-arm is not installed: apt-get install qemu-system-arm"
    return None


def open_interp(name, **kw):
    """Start interpreter ``name`` (one of INTERPRETERS); the result has run(code, ...) and close()."""
    why = missing(name)
    if why:
        raise Unavailable(why)
    if name == "wasm":
        return WasmInterp(**kw)
    if name == "circuitpython":
        return UnixInterp(binary(name), name, **kw)
    return QemuInterp(name, **kw)


def _prologue(paths):
    # the same search path on every interpreter: script dir, mounted paths, /vmtest, /lib
    return "import sys\nsys.path[:] = %r\ndel sys\n" % (["", ] + list(paths)[::-1] + ["/vmtest", "/lib"])


MPY_CACHE = os.path.join(REPO, "build", "fw-mpy")
MPY_ARCH = "armv7m"  # Thumb-2 native code (viper) for the M3; the M7 (armv7emdp) loads it too


def mpy_tree(src):
    """A mirror of host directory ``src`` with every .py compiled by build/fw/mpy-cross (other files
    symlinked), kept up to date by mtime; what a board gets from ``make deploy``, as .mpy."""
    dst_root = os.path.join(MPY_CACHE, src.strip(os.sep).replace(os.sep, "+"))
    want = set()
    for root, dirs, files in os.walk(src, followlinks=True):
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        rel = os.path.relpath(root, src)
        os.makedirs(os.path.join(dst_root, rel), exist_ok=True)
        for f in files:
            s = os.path.join(root, f)
            if f.endswith(".py"):
                d = os.path.join(dst_root, rel, f[:-3] + ".mpy")
                if not os.path.exists(d) or os.path.getmtime(d) < os.path.getmtime(s):
                    proc = subprocess.run([binary("mpy-cross"), "-march=" + MPY_ARCH, "-s",
                                           os.path.normpath(os.path.join(rel, f)), "-o", d + ".tmp", s],
                                          capture_output=True, text=True)
                    if proc.returncode != 0:
                        raise InterpError("mpy-cross failed on %s:\n%s" % (s, proc.stderr or proc.stdout))
                    os.replace(d + ".tmp", d)
            else:
                d = os.path.join(dst_root, rel, f)
                if not os.path.lexists(d):
                    os.symlink(s, d)
            want.add(os.path.normpath(d))
    for root, _dirs, files in os.walk(dst_root, topdown=False):  # removed or renamed since the last run
        for f in files:
            p = os.path.normpath(os.path.join(root, f))
            if p not in want:
                os.unlink(p)
        if root != dst_root and not os.listdir(root):
            # a folder left empty (a package moved back to a module) would read as a namespace
            # package on the board and hide the module of the same name
            os.rmdir(root)
    return dst_root


# Spare RAM of both MPS2 boards' 4 MB SSRAM1: the firmware's image, heap and bss sit at the bottom
# (checked against the ELF) and its stack hangs from the 4 MB top (ports/qemu mps2.ld), so ROMFS
# images go between.
ROM_BASE = 0x00100000
ROM_END = 0x00380000


def _elf_end(path):
    """The highest address an ELF32 image's loadable segments (bss included) occupy."""
    import struct
    with open(path, "rb") as f:
        hdr = f.read(52)
        if hdr[:4] != b"\x7fELF" or hdr[4] != 1:
            raise InterpError("%s is not a 32-bit ELF file" % path)
        phoff, = struct.unpack_from("<I", hdr, 28)
        phentsize, phnum = struct.unpack_from("<HH", hdr, 42)
        end = 0
        for i in range(phnum):
            f.seek(phoff + i * phentsize)
            ptype, _off, vaddr, _paddr, _filesz, memsz = struct.unpack("<6I", f.read(24))
            if ptype == 1 and vaddr < 0x01000000:  # PT_LOAD in SSRAM1
                end = max(end, vaddr + memsz)
    return end


def _tree_stamp(dirs):
    out = []
    for d in dirs:
        for root, ds, files in os.walk(d, followlinks=True):
            ds[:] = sorted(x for x in ds if x != "__pycache__")
            for f in sorted(files):
                st = os.stat(os.path.join(root, f))
                out.append((root, f, st.st_mtime_ns, st.st_size))
    return out


def _romfs_image(tree):
    """A ROMFS image (mpremote's writer, as ``mpremote romfs build``) of a directory."""
    from mpremote.romfs import VfsRomWriter
    w = VfsRomWriter()

    def walk(d):
        for name in sorted(os.listdir(d)):
            p = os.path.join(d, name)
            if os.path.isdir(p):
                if name != "__pycache__":
                    w.opendir(name)
                    walk(p)
                    w.closedir()
            elif not name.endswith(".pyc"):
                with open(p, "rb") as f:
                    w.mkfile(name, f.read())
    walk(tree)
    return bytes(w.finalise())


# repository directories the firmware gets as ROMFS images rather than over the UART
ROM_SOURCES = (os.path.join(REPO, "lib"), VM_TEST_DIR, os.path.join(REPO, "tools", "sim"))


class _Staged:
    """A host directory laid out as the script's filesystem root, made of symlinks."""

    def __init__(self):
        self.root = tempfile.mkdtemp(prefix="tempcomp-fs-")
        self.layout = None
        self.sources = []

    def lay_out(self, mounts, mpy=False):
        layout = [(os.path.join(REPO, "lib"), "/lib"), (VM_TEST_DIR, "/vmtest")]
        for m in mounts:
            host, _, vm = m.rpartition(":")
            if not host or not vm.startswith("/") or vm == "/":
                raise ValueError("bad mount %r: want HOSTDIR:/VMDIR" % m)
            layout.append((os.path.abspath(host), vm.rstrip("/")))
        self.sources = layout  # before compiling: which repository directory is where
        if mpy:
            layout = [(mpy_tree(h) if os.path.isdir(h) and h.startswith(REPO + os.sep) else h, v)
                      for h, v in layout]
        if layout == self.layout:
            return
        for ent in os.listdir(self.root):
            p = os.path.join(self.root, ent)
            if os.path.islink(p) or not os.path.isdir(p):
                os.unlink(p)
            else:
                shutil.rmtree(p)
        for host, vm in layout:
            dst = os.path.join(self.root, vm.lstrip("/"))
            os.makedirs(os.path.dirname(dst), exist_ok=True)
            if os.path.lexists(dst):
                os.unlink(dst)
            os.symlink(host, dst)
        self.layout = layout

    def close(self):
        shutil.rmtree(self.root, ignore_errors=True)


class _Base:
    name = "?"

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        pass

    def __repr__(self):
        return "<interp %s>" % self.name


class WasmInterp(_Base):
    """The MicroPython WebAssembly VM: each run is a fresh VM (``mpvm.run``)."""
    name = "wasm"

    def __init__(self, heap="1m"):
        self.heap = heap

    def run(self, code, mounts=(), paths=(), timeout=300, mpy=None):  # noqa: ARG002 (firmware only)
        from tools.firmware import mpvm
        try:
            return mpvm.run(code, mounts=mounts, paths=paths, heap=self.heap, timeout=timeout)
        except mpvm.VMError as e:
            raise InterpError("[wasm] %s" % e) from None


# The unix port's "/" becomes the staged directory. Not VfsPosix(root): CircuitPython 10.2.1's
# VfsPosix with a root builds both rename() paths in one buffer (the first is lost). A Python VFS
# that prefixes every path itself and hands the plain VfsPosix whole host paths.
_HOST_ROOT = """import os
class _HostRoot:
    def __init__(self, root):
        self.root = root
        self.cwd = "/"
        self.fs = os.VfsPosix()
    def _p(self, path):
        if not path.startswith("/"):
            path = self.cwd + path
        return self.root + path
    def mount(self, readonly, mkfs):
        pass
    def umount(self):
        pass
    def chdir(self, path):
        if not path.startswith("/"):
            path = self.cwd + path
        if not path.endswith("/"):
            path += "/"
        self.fs.stat(self.root + path)
        self.cwd = path
    def getcwd(self):
        return self.cwd if self.cwd == "/" else self.cwd[:-1]
    def open(self, path, mode):
        return self.fs.open(self._p(path), mode)
    def stat(self, path):
        return self.fs.stat(self._p(path))
    def statvfs(self, path):
        return self.fs.statvfs(self._p(path))
    def ilistdir(self, path):
        return self.fs.ilistdir(self._p(path))
    def remove(self, path):
        self.fs.remove(self._p(path))
    def rename(self, old, new):
        self.fs.rename(self._p(old), self._p(new))
    def mkdir(self, path):
        self.fs.mkdir(self._p(path))
    def rmdir(self, path):
        self.fs.rmdir(self._p(path))
os.umount("/")
os.mount(_HostRoot(%r), "/")
os.chdir("/")
del os, _HostRoot
"""


class UnixInterp(_Base):
    """A unix-port interpreter (CircuitPython's coverage build): a fresh process per run, its
    filesystem root replaced by the staged directory (VfsPosix mounted at /)."""

    def __init__(self, exe, name, heap="16m"):
        self.exe, self.name, self.heap = exe, name, heap
        self.fs = _Staged()

    def run(self, code, mounts=(), paths=(), timeout=300, mpy=None):  # noqa: ARG002 (firmware only)
        self.fs.lay_out(mounts)
        pre = _HOST_ROOT % self.fs.root
        env = dict(os.environ, MICROPYPATH="")
        try:
            proc = subprocess.run([self.exe, "-X", "heapsize=" + self.heap, "-c", pre + _prologue(paths) + code],
                                  capture_output=True, text=True, timeout=timeout, env=env, cwd=self.fs.root)
        except subprocess.TimeoutExpired as e:
            raise InterpError("[%s] timed out after %ss; output so far:\n%s" % (self.name, timeout, e.stdout)) from None
        if proc.returncode != 0:
            raise InterpError("[%s] failed (exit %d):\n%s\n%s" % (self.name, proc.returncode, proc.stdout, proc.stderr))
        return proc.stdout

    def close(self):
        self.fs.close()


# mpremote's device-side filesystem hook, mounted at / instead of mpremote's /remote so the
# script sees the same absolute paths as in the other interpreters.
_MOUNT = "os.mount(RemoteFS(RemoteCommand()), '/')\nos.chdir('/')\n"


class QemuInterp(_Base):
    """MicroPython firmware on an emulated MPS2 board: booted once, soft-reset before every run."""

    def __init__(self, name, boot_timeout=30, mpy=True):
        self.name = name
        self.elf = binary(name)  # fixed now: a caller may point FW_DIR elsewhere for this instance
        self.mpy = mpy
        self.boot_timeout = boot_timeout
        self.fs = _Staged()
        self.rom_dir = tempfile.mkdtemp(prefix="tempcomp-rom-")
        self.proc = None
        self.transport = None
        self._boot()

    def _boot(self):
        """Start qemu with lib/, host_tests/device/ and tools/sim/ as ROMFS images (.mpy and .py
        flavours) in the board's spare RAM, read in place by vfs.VfsRom: no UART round trips and
        no heap for the files' bytes. Rebooted when one of them changes."""
        from mpremote.transport_serial import SerialTransport
        self.roms, self.rom_stamp = {}, _tree_stamp(ROM_SOURCES)
        cmd = ["qemu-system-arm", "-machine", QEMU_MACHINE[self.name], "-nographic", "-monitor", "null",
               "-semihosting", "-serial", "pty", "-icount", "shift=0", "-kernel", self.elf]
        addr = max(ROM_BASE, (_elf_end(self.elf) + 0xFFFF) & ~0xFFFF)
        for i, src in enumerate(ROM_SOURCES):
            for mpy in (True, False):
                img = _romfs_image(mpy_tree(src) if mpy else src)
                if addr + len(img) > ROM_END:
                    raise InterpError("ROMFS images exceed the board's spare RAM (%d bytes)" % (ROM_END - ROM_BASE))
                path = os.path.join(self.rom_dir, "%d%s.romfs" % (i, "mpy" if mpy else "py"))
                with open(path, "wb") as f:
                    f.write(img)
                cmd += ["-device", "loader,file=%s,addr=0x%x,force-raw=on" % (path, addr)]
                self.roms[src, mpy] = (addr, len(img))
                addr = (addr + len(img) + 0xFFF) & ~0xFFF
        self.proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT)
        try:
            self.pty = self._read_pty(self.boot_timeout)
            self.transport = SerialTransport(self.pty, baudrate=115200, exclusive=False)
            self.transport.enter_raw_repl(soft_reset=False)
        except BaseException:
            self.close()
            raise

    def _stop(self):
        self._pause(False)  # a stopped process would hold its SIGTERM
        if self.transport is not None:
            try:
                self._unmount()
                self.transport.close()
            except Exception:
                pass
            self.transport = None
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.proc is not None and self.proc.stdout:
            self.proc.stdout.close()

    def _read_pty(self, timeout):
        deadline, seen = time.monotonic() + timeout, b""
        assert self.proc.stdout is not None
        while time.monotonic() < deadline:
            r, _, _ = select.select([self.proc.stdout], [], [], 0.2)
            if r:
                chunk = os.read(self.proc.stdout.fileno(), 4096)
                if not chunk:
                    break
                seen += chunk
                m = re.search(rb"(/dev/pts/\d+)", seen)
                if m:
                    return m.group(1).decode()
        raise Unavailable("qemu did not start %s: %s" % (self.name, seen.decode(errors="replace").strip()))

    def _unmount(self):
        t = self.transport
        if t.mounted:
            t.serial = t.serial.orig_serial
            t.mounted = False

    def _soft_reset_and_mount(self, mpy):
        from mpremote.transport_serial import PyboardCommand, SerialIntercept, fs_hook_code
        t = self.transport
        self._unmount()
        t.enter_raw_repl(soft_reset=True)
        roms = [self.roms[host, mpy] + (vm,) for host, vm in self.fs.sources if (host, mpy) in self.roms]
        if roms:  # mounted before / (the UART), so they take precedence for their paths
            t.exec("import vfs, uctypes\n" + "".join(
                "vfs.mount(vfs.VfsRom(uctypes.bytearray_at(0x%x, %d)), %r)\n" % r for r in roms)
                + "del vfs, uctypes\n")
        t.exec(fs_hook_code)
        t.exec(_MOUNT)
        t.cmd = PyboardCommand(t.serial, t.serial, self.fs.root, unsafe_links=True)
        t.serial = SerialIntercept(t.serial, t.cmd)
        t.mounted = True

    def _pause(self, on):
        # the port polls its UART while it waits for the next script: about a quarter of a host
        # core per idle board, so between runs qemu is stopped (its instruction clock stops too)
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGSTOP if on else signal.SIGCONT)

    def run(self, code, mounts=(), paths=(), timeout=300, mpy=None):
        self._pause(False)
        try:
            return self._run(code, mounts, paths, timeout, mpy)
        finally:
            self._pause(True)

    def _run(self, code, mounts, paths, timeout, mpy):
        from mpremote.transport import TransportError
        if self.proc.poll() is not None:
            raise InterpError("[%s] qemu exited (status %s)" % (self.name, self.proc.returncode))
        mpy = self.mpy if mpy is None else mpy
        if _tree_stamp(ROM_SOURCES) != self.rom_stamp:
            self._stop()  # a served directory changed since boot: new ROMFS images
            self._boot()
        self.fs.lay_out(mounts, mpy)
        self._soft_reset_and_mount(mpy)
        t = self.transport
        try:
            t.exec_raw_no_follow(_prologue(paths) + code)
            out, err = t.follow(timeout)
        except TransportError as e:
            # a hung script: interrupt it so the next run starts from a clean prompt
            self._interrupt()
            raise InterpError("[%s] %s" % (self.name, e)) from None
        out = out.replace(b"\r\n", b"\n").decode(errors="replace")
        if err:
            raise InterpError("[%s] script raised:\n%s\n%s" % (
                self.name, out, err.replace(b"\r\n", b"\n").decode(errors="replace")))
        return out

    def _interrupt(self):
        try:
            self._unmount()
            self.transport.serial.write(b"\x03\x03")
            time.sleep(0.2)
            self.transport.serial.reset_input_buffer()
        except Exception:  # the next run's soft reset reports anything left
            pass

    def close(self):
        self._stop()
        self.fs.close()
        shutil.rmtree(self.rom_dir, ignore_errors=True)
