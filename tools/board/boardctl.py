"""Drive a board from the host with mpremote: the virtual board's process, deploy, run code.

Used by `make demo` (tools/demo/__main__.py) and the end-to-end tests::

    from tools.board.boardctl import VirtualBoard, Remote
    vb = VirtualBoard("build/demo", env={"VBOARD_TIME_SCALE": "4"}).start()
    try:
        r = Remote(vb.url)
        r.deploy_mpy("virtual")
        print(r.run("import tempcomp_board; print(tempcomp_board.NAME)"))
        vb.power_cycle()
    finally:
        vb.stop()                     # always: the board is a background process

A VirtualBoard owns its node process (its own flash directory and pid file, a free port unless
one is given) and stops it by pid, never by name.
"""

import codecs
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

from tools import REPO

SERVER = os.path.join(REPO, "tools", "vboard", "server.mjs")
NODE = os.environ.get("NODE") or shutil.which("node") or "node"


class BoardError(RuntimeError):
    """The board did not start, or a command on it failed (the message has its output)."""


class VirtualBoard:
    """tools/vboard/server.mjs as a child process with its own flash directory under ``home``."""

    def __init__(self, home, port=0, env=None, fresh=True, board="virtual"):
        # board="pico": the virtual Pico (tools/pico), whose flash is one littlefs image file
        self.home = os.path.abspath(home)
        self.board = board
        self.flash = os.path.join(self.home, "flash.img" if board == "pico" else "flash")
        self.port_arg = int(port)
        self.env = dict(env or {})
        self.proc = None
        self.port = None
        self.lines = []
        os.makedirs(self.home, exist_ok=True)
        if board == "pico":
            if fresh and os.path.exists(self.flash):
                os.remove(self.flash)
            return
        if fresh and os.path.isdir(self.flash):
            shutil.rmtree(self.flash)
        os.makedirs(self.flash, exist_ok=True)

    @property
    def url(self):
        return "socket://127.0.0.1:%d" % self.port

    def start(self, env=None, timeout=20):
        """Power on; env adds VBOARD_* settings for this power-on (e.g. a new profile)."""
        e = dict(os.environ)
        e.update(self.env)
        e.update(env or {})
        port = self.port if self.port is not None else self.port_arg
        cmd = [NODE, "--disallow-code-generation-from-strings", "--max-old-space-size=256", SERVER,
               "--port", str(port), "--flash", self.flash,
               "--pidfile", os.path.join(self.home, "board.pid"), "--board", self.board]
        self.lines = []
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     env=e, start_new_session=True)
        ready = threading.Event()

        def reader(proc=self.proc):
            for line in proc.stdout:
                self.lines.append(line)
                if "listening on socket://" in line:
                    self.port = int(line.rsplit(":", 1)[1])
                    ready.set()
            ready.set()

        threading.Thread(target=reader, daemon=True).start()
        if not ready.wait(timeout) or self.proc.poll() is not None:
            log = "".join(self.lines)
            self.stop()
            raise BoardError("the virtual board did not start:\n" + log)
        return self

    def stop(self):
        """Power off (SIGTERM to our own process group, then SIGKILL); safe to call twice."""
        p = self.proc
        self.proc = None
        if p is None or p.poll() is not None:
            return
        try:
            os.killpg(p.pid, signal.SIGTERM)
            p.wait(5)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.wait(5)

    def power_cycle(self, env=None):
        """Stop and start again on the same port and flash: RAM and the parts' registers are lost."""
        self.stop()
        return self.start(env)

    def log(self):
        return "".join(self.lines)


class Remote:
    """mpremote against one port (a pyserial URL or a serial device)."""

    def __init__(self, port, echo=None):
        self.port = port
        self.echo = echo  # a callable given the output as it arrives, or None

    def mpremote(self, *args, timeout=120):
        cmd = [sys.executable, "-m", "mpremote", "connect", self.port] + list(args)
        for attempt in range(5):
            out, err, code = self._mpremote(cmd, timeout)
            # the board was not listening yet (or no longer): nothing was sent, running it again is
            # safe (a second client while one is attached is accepted, told why and closed)
            if not (code == 1 and "failed to access" in err and self.port.startswith("socket://")):
                break
            time.sleep(0.2 * (attempt + 1))
        if code != 0:
            raise BoardError("mpremote %s failed (exit %d):\n%s\n%s" % (" ".join(args[:2]), code, out[-3000:], err[-3000:]))
        return out

    def _mpremote(self, cmd, timeout):
        if self.echo is None:
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=REPO)
            out = r.stdout
            err = r.stderr
            code = r.returncode
        else:
            # bytes, not text mode: universal newlines would turn a progress bar's \r into \n
            p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=REPO)
            timer = threading.Timer(timeout, p.kill)
            timer.start()
            chunks = []
            dec = codecs.getincrementaldecoder("utf-8")("replace")
            try:
                assert p.stdout is not None
                while True:
                    b = p.stdout.read(1)
                    if not b:
                        break
                    for c in dec.decode(b):
                        chunks.append(c)
                        self.echo(c)
                code = p.wait()
                err = p.stderr.read().decode("utf-8", "replace") if p.stderr else ""
            finally:
                timer.cancel()
            out = "".join(chunks)
        return out, err, code

    def run(self, code, timeout=120):
        """Run Python source on the board (mpremote run of a temporary file); returns its output."""
        fd, path = tempfile.mkstemp(suffix=".py", prefix="tempcomp-")
        try:
            with os.fdopen(fd, "w") as f:
                f.write(code)
            return self.mpremote("run", path, timeout=timeout)
        finally:
            os.remove(path)

    def soft_reset(self):
        return self.mpremote("soft-reset")

    def deploy_mpy(self, board, mpy_dir=None):
        """Compile lib/ with mpy-cross and copy it to /lib, the board module as /lib/tempcomp_board.py.

        (.mpy is half the bytes of the sources: mpremote copies in 256-byte round trips.)
        """
        mpy_dir = mpy_dir or os.path.join(REPO, "build", "mpy")
        subprocess.run([sys.executable, "-m", "tools.board.build_mpy", mpy_dir], cwd=REPO, check=True,
                       stdout=subprocess.DEVNULL)
        board_py = os.path.join(REPO, "boards", board + ".py")
        if not os.path.exists(board_py):
            raise BoardError("no board module boards/%s.py" % board)
        self.mpremote("exec", "import os\ntry:\n os.mkdir('/lib')\nexcept OSError:\n pass")
        return self.mpremote("cp", "-r", os.path.join(mpy_dir, "tempcomp"), ":/lib/", "+",
                             "cp", board_py, ":/lib/tempcomp_board.py")
