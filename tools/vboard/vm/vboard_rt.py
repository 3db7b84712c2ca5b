# Start-up of the virtual board's VM, run by the host before boot.py.
# Lives outside the board's flash: the host mounts it only while this runs.
import sys


def _input(prompt=""):
    # The WebAssembly port's built-in input() reads from a stub that returns
    # 0 forever, so it never returns; this one reads the serial line via
    # sys.stdin and echoes as a board's readline does.
    global _after_cr
    if prompt:
        sys.stdout.write(prompt)
    line = []
    while True:
        c = sys.stdin.read(1)
        if not c:
            # Woken by Ctrl-C: the pending KeyboardInterrupt is raised on
            # this loop's back edge.
            continue
        if c == "\n" and _after_cr:
            _after_cr = False
            continue
        _after_cr = c == "\r"
        if c in "\r\n":
            sys.stdout.write("\r\n")
            return "".join(line)
        if c in "\x08\x7f":
            if line:
                line.pop()
                sys.stdout.write("\x08 \x08")
        elif c == "\x04" and not line:
            raise EOFError
        elif c >= " ":
            line.append(c)
            sys.stdout.write(c)


_after_cr = False


def run_file(name):
    # pyexec_file_if_exists() for boot.py / main.py: run in __main__.
    import __main__

    with open(name) as f:
        src = f.read()
    exec(compile(src, name, "exec"), __main__.__dict__)


class FlashVfs:
    # The board's flash as MicroPython sees it: the host's mirrored directory
    # (a VfsPosix) with what a LittleFS/FAT board adds: sizes in ilistdir
    # (mpremote ls shows them) and statvfs of a flash chip, not of the host.
    BLOCK = 4096

    def __init__(self, root, size):
        import vfs

        self._fs = vfs.VfsPosix(root)
        self.blocks = size // self.BLOCK  # --flash-size; 2 MiB (a Pico-sized filesystem) by default

    def __repr__(self):
        return "<VfsFlash>"

    def mount(self, readonly, mkfs):
        pass

    def umount(self):
        pass

    def ilistdir(self, path):
        fs = self._fs
        base = path.rstrip("/") + "/" if path not in ("", ".") else ""
        for ent in fs.ilistdir(path):
            name, kind = ent[0], ent[1]
            size = fs.stat(base + name)[6] if kind == 0x8000 else 0
            yield (name, kind, 0, size)

    def _used(self, path):
        n = 0
        for name, kind, _, size in self.ilistdir(path):
            if kind == 0x4000:
                n += self.BLOCK + self._used(path.rstrip("/") + "/" + name)
            else:
                # a file takes at least one block (the host counts the same: vm_files.mjs)
                n += max(1, (size + self.BLOCK - 1) // self.BLOCK) * self.BLOCK
        return n

    def statvfs(self, path):
        free = max(0, self.blocks - self._used("/") // self.BLOCK)
        return (self.BLOCK, self.BLOCK, self.blocks, free, free, 0, 0, 0, 0, 255)

    def open(self, path, mode):
        return self._fs.open(path, mode)

    def stat(self, path):
        return self._fs.stat(path)

    def mkdir(self, path):
        return self._fs.mkdir(path)

    def rmdir(self, path):
        return self._fs.rmdir(path)

    def remove(self, path):
        return self._fs.remove(path)

    def rename(self, a, b):
        # VfsPosix (MicroPython 1.27) builds both root-prefixed paths in one
        # shared buffer, so with two absolute paths the second overwrites the
        # first and rename("/x", "/y") fails with ENOENT: give it the target
        # relative to the root instead.
        if a.startswith("/") and b.startswith("/"):
            cwd = self._fs.getcwd()
            self._fs.chdir("/")
            try:
                return self._fs.rename(a, b[1:])
            finally:
                self._fs.chdir(cwd or "/")  # VfsPosix.getcwd() gives "" at its root
        return self._fs.rename(a, b)

    def chdir(self, path):
        return self._fs.chdir(path)

    def getcwd(self):
        return self._fs.getcwd()


class _BoardTime:
    # `time` as code on the board sees it: the VM's own, whose sleeps also let the same
    # time pass on the board's simulated clock (vboard.py, "Time").
    pass


def _board_time(board):
    import time

    t = _BoardTime()
    for name in dir(time):
        if not name.startswith("__"):
            setattr(t, name, getattr(time, name))
    t.__name__ = "time"

    # the board's clock moves once the sleep is over (a Ctrl-C that ends it moves nothing)
    def sleep(s):
        time.sleep(s)
        board.advance_us(int(s * 1000000))

    def sleep_ms(ms):
        time.sleep_ms(ms)
        board.advance_us(int(ms) * 1000)

    def sleep_us(us):
        time.sleep_us(us)
        board.advance_us(int(us))

    t.sleep = sleep
    t.sleep_ms = sleep_ms
    t.sleep_us = sleep_us
    return t


def start():
    import builtins
    import os

    import vboard_config
    import vfs

    vfs.umount("/")
    vfs.mount(FlashVfs("/flash", vboard_config.FLASH_BYTES), "/")
    os.chdir("/")
    builtins.input = _input
    # Board modules are built in on a real board: load them now, while their
    # directory is mounted, so that `import machine` finds them in sys.modules.
    import machine  # noqa: F401
    import vboard

    # found before the built-in by every later `import time` (sys.modules is searched first)
    sys.modules["time"] = _board_time(vboard.board)
