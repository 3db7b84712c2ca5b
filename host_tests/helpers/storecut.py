"""Power-cut simulation for store tests: builtins.open / os.rename / os.remove intercepted under
pytest's monkeypatch, a torn write at any byte, and a simulated nvm byte array.

A cut is the exception PowerCut (a BaseException, so no `except Exception/OSError` in the code
under test can swallow it); whatever the files hold at that moment is what the next boot sees.
"""

import builtins
import errno
import os
import pathlib
import shutil
import tempfile


class PowerCut(BaseException):
    pass


def _writing(mode):
    return "w" in mode or "x" in mode  # the store creates its scratch file with "xb"


class _TornFile:
    """A file opened for writing whose first write stops after k bytes, then the power goes."""

    def __init__(self, f, path, old, k, tail):
        self._f = f
        self._path = path
        self._old = old
        self._k = k
        self._tail = tail

    def write(self, data):
        data = bytes(data)
        k = min(self._k, len(data))
        self._f.close()
        if self._tail == "truncate":
            body = data[:k]
        elif self._tail == "old":  # an in-place rewrite: the old bytes remain past the tear
            body = data[:k] + self._old[k:]
        else:  # "ff": erased-but-not-yet-programmed flash past the tear
            body = data[:k] + b"\xff" * (len(data) - k)
        with Medium.real_open(self._path, "wb") as f:
            f.write(body)
        raise PowerCut("torn write of %s at byte %d (%s)" % (self._path, k, self._tail))

    def __getattr__(self, name):
        return getattr(self._f, name)


class Medium:
    """Counts open/rename/remove calls under `root`; cuts the power at one of them or tears a
    write. fat=True gives FAT/Windows rename semantics (no rename over an existing file)."""

    real_open = builtins.open
    real_rename = os.rename
    real_remove = os.remove

    def __init__(self, monkeypatch, root, fat=False):
        self.root = str(root)
        self.fat = fat
        self.count = 0
        self.cut = None  # (n, "before" | "after"): cut at the n-th operation
        self.tear = None  # (k, tail): tear the first write of a file opened for writing
        self.log = []
        monkeypatch.setattr(builtins, "open", self._open)
        monkeypatch.setattr(os, "rename", self._rename)
        monkeypatch.setattr(os, "remove", self._remove)
        # fsync costs real disk waits thousands of times over; its ordering is tested apart
        monkeypatch.setattr(os, "fsync", lambda fd: None)

    def _mine(self, path):
        return str(path).startswith(self.root)

    def _op(self, name, when):
        if self.cut == (self.count, when):
            self.cut = None  # the board reboots: later operations run normally
            raise PowerCut("power cut %s %s (operation %d)" % (when, name, self.count))

    def _open(self, path, mode="r", *a, **kw):
        if not self._mine(path):
            return Medium.real_open(path, mode, *a, **kw)
        self.log.append(("open", os.path.basename(str(path)), mode))
        self._op("open", "before")
        old = b""
        if _writing(mode) and self.tear is not None:
            try:
                with Medium.real_open(path, "rb") as f:
                    old = f.read()
            except FileNotFoundError:
                pass
        f = Medium.real_open(path, mode, *a, **kw)
        self._op("open", "after")
        self.count += 1
        if _writing(mode) and self.tear is not None:
            k, tail = self.tear
            self.tear = None
            return _TornFile(f, path, old, k, tail)
        return f

    def _rename(self, src, dst):
        if not self._mine(src):
            return Medium.real_rename(src, dst)
        self.log.append(("rename", os.path.basename(src), os.path.basename(dst)))
        self._op("rename", "before")
        if self.fat and os.path.exists(dst):
            self._op("rename", "after")
            self.count += 1
            raise FileExistsError(errno.EEXIST, "File exists", dst)
        Medium.real_rename(src, dst)
        self._op("rename", "after")
        self.count += 1

    def _remove(self, path):
        if not self._mine(path):
            return Medium.real_remove(path)
        self.log.append(("remove", os.path.basename(path)))
        self._op("remove", "before")
        Medium.real_remove(path)
        self._op("remove", "after")
        self.count += 1


class FakeNvm:
    """microcontroller.nvm stand-in: a byte array whose slice assignment can be torn."""

    def __init__(self, size=1024, fill=0xFF):
        self.b = bytearray([fill]) * size
        self.tear = None  # (k, "old" | "ff")
        self.writes = 0

    def __len__(self):
        return len(self.b)

    def __getitem__(self, k):
        return self.b[k]

    def __setitem__(self, k, v):
        self.writes += 1
        if self.tear is None:
            self.b[k] = v
            return
        n, tail = self.tear
        self.tear = None
        data = bytes(v)
        a = k.start
        if tail == "ff":
            self.b[a : a + len(data)] = b"\xff" * len(data)
        self.b[a : a + min(n, len(data))] = data[:n]
        raise PowerCut("torn nvm write at byte %d (%s)" % (n, tail))


def ram_dir(tmp_path):
    """Body of a tmp_path fixture on a RAM disk when the host has one: these tests rewrite
    thousands of small files, and ext4 flushes a truncated-and-rewritten file on close."""
    if not os.path.isdir("/dev/shm") or not os.access("/dev/shm", os.W_OK):
        yield tmp_path
        return
    d = tempfile.mkdtemp(prefix="tempcomp-store-", dir="/dev/shm")
    try:
        yield pathlib.Path(d)
    finally:
        shutil.rmtree(d, ignore_errors=True)
