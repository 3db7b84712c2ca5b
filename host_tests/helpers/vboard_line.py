"""The virtual board as a test drives it: its server as a child process (own port, flash and
pid file) and the serial line as a plain socket (what a terminal sees).

Every wait here is for an event (the banner's last line, a token on the line, the process's
exit, the port accepting again), with a ceiling far above what it takes on a loaded machine
(CEILING): a slow host makes a test slower, never a failure; only an event that never comes
fails it."""

import itertools
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SERVER = REPO / "tools" / "vboard" / "server.mjs"
NODE = os.environ.get("NODE") or shutil.which("node") or "node"
CEILING = 120  # seconds: the most any one event may take before the test fails
START_TIMEOUT = CEILING
BANNER_END = b'Type "help()" for more information.\r\n>>> '


class VirtualBoard:
    def __init__(self, flash, port=0, devices=None, extra=()):
        self.flash = Path(flash)
        self.port_arg = port
        self.devices = devices
        self.extra = list(extra)
        self.proc = None
        self.lines = []
        self.port = None
        self.pty = None
        self.repl_command = None  # the banner's "REPL: mpremote connect <tty> repl"

    def start(self):
        # the server thread's heap bounded as `python -m tools board` bounds it (no
        # --disallow-code-generation-from-strings: the sealed bridge must hold without it)
        cmd = [NODE, "--max-old-space-size=256", str(SERVER), "--port", str(self.port_arg), "--flash", str(self.flash),
               "--pidfile", str(self.flash.parent / f"board-{id(self)}.pid")]
        if self.devices:
            cmd += ["--devices", str(self.devices)]
        cmd += self.extra
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, start_new_session=True)
        ready = threading.Event()

        def reader():
            for line in self.proc.stdout:
                self.lines.append(line)
                if "listening on socket://" in line:
                    self.port = int(line.rsplit(":", 1)[1])
                if line.startswith("virtual board: pty "):
                    self.pty = line.split()[3]
                if line.startswith("  REPL: "):
                    self.repl_command = line[len("  REPL: "):].strip()
                if line.startswith("  stop: "):  # the banner's last line
                    ready.set()
            ready.set()

        threading.Thread(target=reader, daemon=True).start()
        if not ready.wait(START_TIMEOUT) or self.port is None:
            self.stop()
            raise RuntimeError("virtual board did not start:\n" + "".join(self.lines))
        return self

    @property
    def url(self):
        return f"socket://127.0.0.1:{self.port}"

    def log(self):
        return "".join(self.lines)

    def mpremote(self, *args, timeout=CEILING, check=True):
        deadline = time.monotonic() + CEILING
        while True:
            r = subprocess.run([sys.executable, "-m", "mpremote", "connect", self.url, *args],
                               capture_output=True, text=True, timeout=timeout)
            # not listening (yet): nothing was sent when mpremote could not connect, so running
            # it again is safe (up to CEILING)
            if "failed to access" not in r.stderr or time.monotonic() > deadline:
                break
            time.sleep(0.2)
        if check and r.returncode != 0:
            raise AssertionError(f"mpremote {args} failed ({r.returncode}):\n{r.stdout}\n{r.stderr}"
                                 f"\n--- board log ---\n{self.log()}")
        return r

    def kill(self):
        # A power cut: no chance to flush anything.
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(CEILING)

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(CEILING)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(CEILING)


_SYNC = itertools.count(random.randrange(10**6, 10**7) * 10)


class Line:
    """The serial line seen from a terminal: a plain socket."""

    def __init__(self, port):
        # the board listens for its whole life; a previous client on its way out is waited for.
        # recv waits up to CEILING too: a reply (or the board closing the line) is an event
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=CEILING)
        self.buf = b""

    def send(self, data):
        self.sock.sendall(data)

    def read_until(self, token, timeout=CEILING):
        deadline = time.monotonic() + timeout
        while token not in self.buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"timed out waiting for {token!r}; got {self.buf!r}")
            self.sock.settimeout(left)
            try:
                chunk = self.sock.recv(4096)
            except socket.timeout:
                continue
            if not chunk:
                raise AssertionError(f"connection closed waiting for {token!r}; got {self.buf!r}")
            self.buf += chunk
        out, _, self.buf = self.buf.partition(token)
        return out + token

    def quiet_for(self, seconds):
        """True if nothing arrives for `seconds`."""
        self.sock.settimeout(seconds)
        try:
            chunk = self.sock.recv(4096)
        except socket.timeout:
            return True
        self.buf += chunk
        return False

    def friendly_prompt(self):
        """Get to a fresh friendly-REPL prompt, whatever state the board was in
        (a board that has just booted has already printed its banner).

        After the banner, an expression no one else types and its answer: whatever the board still
        had to print (a late prompt, the echo of the Enter and Ctrl-C) comes before that answer and
        goes with it, however slowly it arrives."""
        self.send(b"\r\x03\x02")
        self.read_until(BANNER_END)
        n = next(_SYNC)
        self.send(b"%d+1\r" % n)
        self.read_until(b"\r\n%d\r\n>>> " % (n + 1))
        assert not self.buf, self.buf
        self.buf = b""

    def close(self):
        self.sock.close()


def proc_start(pid):
    """A process's start time (clock ticks since boot), as the board's pid file records it."""
    stat = open("/proc/%d/stat" % pid).read()
    return stat[stat.rindex(")") + 2:].split()[19]


def rss_kb(pid):
    """A process's resident memory from /proc, in KiB."""
    for line in open("/proc/%d/status" % pid):
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError("no VmRSS")
