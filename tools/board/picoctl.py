"""The virtual Pico from the host: boot it with tempcomp deployed, run scripts on it, cut its power.

    from tools.board.picoctl import PicoInterp
    with PicoInterp() as pico:              # the RP2040 firmware on rp2040js, tempcomp in /lib
        print(pico.run("import tempcomp; print(tempcomp.__name__)"))   # soft reset, then the script

The board is tools/vboard/server.mjs --board pico (tools/pico), reached over its loopback port by
mpremote's transport. tempcomp goes on its flash as ``make deploy`` puts it there (the mip .mpy
package of ``make dist``: native kernels for the M0+ included), with host_tests/device/ in
/vmtest; the deployed flash image is kept in build/pico/ under a hash of what went on it, so the
next session boots it at once. Scripts see ``sys.path = ['', '/vmtest', '/lib']`` as on the other
interpreters (tools/firmware/interp.py); their files stay on the Pico's littlefs.

``cut_sweep`` runs a script with the power cut at chosen cycles of its flash writes (tools/pico/cut.mjs).
"""
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile

from tools import REPO
from tools.board import boardctl, dist
from tools.firmware.interp import InterpError, Unavailable

FW = os.path.join(REPO, "build", "fw", "rp2")
HOME = os.path.join(REPO, "build", "pico")
DEVICE = os.path.join(REPO, "host_tests", "device")
CUT = os.path.join(REPO, "tools", "pico", "cut.mjs")


def missing():
    """Why the virtual Pico cannot run here (one line), or None."""
    for f in ("firmware.bin", "firmware.elf", "bootrom.mjs"):
        if not os.path.exists(os.path.join(FW, f)):
            return "build/fw/rp2/%s is missing: run make setup (it builds the RPI_PICO firmware)" % f
    if not os.path.exists(os.path.join(REPO, "tools", "node_modules", "rp2040js")):
        return "rp2040js is not installed: run make setup (npm ci in tools/)"
    if not shutil.which(boardctl.NODE):
        return "node is not installed"
    return None


def _digest(paths):
    h = hashlib.sha256()
    for top in paths:
        if os.path.isfile(top):
            h.update(top.encode())
            h.update(open(top, "rb").read())
            continue
        for root, dirs, files in os.walk(top):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            for f in sorted(files):
                p = os.path.join(root, f)
                h.update(os.path.relpath(p, REPO).encode())
                h.update(open(p, "rb").read())
    return h.hexdigest()[:16]


def deployed_image():
    """A flash image with tempcomp (.mpy, as make deploy installs it) and boards/pico.py (as
    tempcomp_board) in /lib, host_tests/device in /vmtest: built once per content, then copied
    from build/pico/."""
    board_py = os.path.join(REPO, "boards", "pico.py")
    key = _digest([os.path.join(REPO, "lib"), DEVICE, os.path.join(FW, "firmware.bin"), board_py,
                   os.path.join(REPO, "tools", "board", "build_mpy.py")])
    img = os.path.join(HOME, "deployed-%s.img" % key)
    if os.path.exists(img):
        return img
    os.makedirs(HOME, exist_ok=True)
    for old in os.listdir(HOME):
        if old.startswith("deployed-") and old.endswith(".img"):
            os.remove(os.path.join(HOME, old))
    work = tempfile.mkdtemp(prefix="tempcomp-pico-")
    try:
        pkg = os.path.join(dist.build(os.path.join(work, "dist")), "package.json")
        vb = boardctl.VirtualBoard(os.path.join(work, "board"), board="pico", env={"PICO_REALTIME": "0"})
        vb.start(timeout=60)
        try:
            r = boardctl.Remote(vb.url)
            r.mpremote("mip", "install", "--target", "/lib", pkg, timeout=600)
            r.mpremote("mkdir", ":/vmtest")
            files = sorted(f for f in os.listdir(DEVICE) if f.endswith(".py"))
            args = ["cp", board_py, ":/lib/tempcomp_board.py", "+"]
            for f in files:
                args += ["cp", os.path.join(DEVICE, f), ":/vmtest/" + f, "+"]
            r.mpremote(*args[:-1], timeout=600)
        finally:
            vb.stop()
        shutil.copy(vb.flash, img + ".tmp")
        os.replace(img + ".tmp", img)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return img


class PicoInterp:
    """The virtual Pico as a test interpreter: booted once, soft-reset before every run."""

    name = "pico"

    def __init__(self, image=None, env=None):
        why = missing()
        if why:
            raise Unavailable(why)
        from mpremote.transport_serial import SerialTransport

        self.home = tempfile.mkdtemp(prefix="tempcomp-pico-run-")
        self.board = boardctl.VirtualBoard(self.home, board="pico", env=dict({"PICO_REALTIME": "0"}, **(env or {})))
        shutil.copy(image or deployed_image(), self.board.flash)
        self.board.start(timeout=60)
        try:
            self.transport = SerialTransport(self.board.url, baudrate=115200, exclusive=False)
            self.transport.enter_raw_repl(soft_reset=False)
        except BaseException:
            self.close()
            raise

    @property
    def flash(self):
        return self.board.flash

    def world(self):
        """A WorldControl on this board's world (close it when done)."""
        return WorldControl(os.path.join(self.home, "world.sock"))

    def run(self, code, timeout=300):
        from mpremote.transport import TransportError

        t = self.transport
        try:
            t.enter_raw_repl(soft_reset=True)
            t.exec_raw_no_follow("import sys\nsys.path[:] = ['', '/vmtest', '/lib']\ndel sys\n" + code)
            out, err = t.follow(timeout)
        except (TransportError, OSError) as e:
            # the board's log says why (a firmware that stopped names where)
            raise InterpError("[pico] %s\n%s" % (e, "".join(self.board.lines[-20:]))) from None
        out = out.replace(b"\r\n", b"\n").decode(errors="replace")
        if err:
            raise InterpError("[pico] script raised:\n%s\n%s" % (out, err.replace(b"\r\n", b"\n").decode(errors="replace")))
        return out

    def close(self):
        t = getattr(self, "transport", None)
        if t is not None:
            try:
                t.close()
            except Exception:
                pass
            self.transport = None
        self.board.stop()
        shutil.rmtree(self.home, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class WorldControl:
    """The virtual Pico's world from the host (tools/pico/control.mjs): a test rig's hands.

        w = WorldControl(os.path.join(home, "world.sock"))   # beside the board's pid file
        w.place("+x"); w.spin((0, 0, 20)); w.bump(for_ms=400); w.heat([(0, 20), (30, 50)])
        w.state()   # {"rp2040_ms", "world_ms", "temperature_c", "face", "rate"}

    Each call is done at the RP2040's simulated time when it arrives; a refused request raises
    ValueError with the board's reason.
    """

    def __init__(self, path, timeout=30):
        import socket

        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.settimeout(timeout)
        self.sock.connect(path)
        self.rfile = self.sock.makefile("r", encoding="utf-8")

    def call(self, cmd, **args):
        self.sock.sendall((json.dumps(dict(args, cmd=cmd)) + "\n").encode())
        line = self.rfile.readline()
        if not line:
            raise InterpError("[pico] the world control closed the connection")
        answer = json.loads(line)
        if not answer.get("ok"):
            raise ValueError(answer.get("error"))
        return answer

    def state(self):
        return self.call("state")["state"]

    def place(self, face):
        return self.call("place", face=face)["state"]

    def spin(self, rate_dps):
        return self.call("spin", rate=list(rate_dps))["state"]

    def bump(self, after_ms=0, for_ms=1000, rate_dps=None):
        args = dict(after_ms=after_ms, for_ms=for_ms)
        if rate_dps is not None:
            args["rate"] = list(rate_dps)
        return self.call("bump", **args)["state"]

    def heat(self, points):
        return self.call("heat", points=[list(p) for p in points])["state"]

    def temperature_at(self, rp2040_ms):
        """The temperature (degC) at those RP2040 times (ms since its power-on, as ticks_ms()),
        under the temperature programme in force now."""
        return self.call("temperature", at_ms=list(rp2040_ms))["temperature_c"]

    def close(self):
        self.rfile.close()
        self.sock.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def cut_sweep(image, setup, action, check, cuts, timeout=1800):
    """Power cuts through ``action``'s flash writes, each followed by a reboot and ``check``.

    image: a flash image (copied, never changed); setup, action, check: MicroPython source run in
    that order at the REPL of a fresh boot (setup and action in one power-on, check after the
    cut). cuts: [{"op": k, "frac": f}] (the k-th flash operation of ``action``, f of its time) or
    [{"cycle": n}] (n cycles into ``action``). Returns cut.mjs's JSON: per cut where it fell and
    what ``check`` printed.
    """
    spec = {"image": os.path.abspath(image), "setup": setup, "action": action, "check": check, "cuts": cuts}
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(spec, f)
    try:
        proc = subprocess.run([boardctl.NODE, CUT, f.name], capture_output=True, text=True, timeout=timeout)
    finally:
        os.remove(f.name)
    if proc.returncode != 0:
        raise InterpError("[pico] cut sweep failed (exit %d):\n%s\n%s" % (proc.returncode, proc.stdout[-3000:],
                                                                         proc.stderr[-3000:]))
    return json.loads(proc.stdout)


if __name__ == "__main__":
    with PicoInterp() as p:
        sys.stdout.write(p.run(sys.argv[1] if len(sys.argv) > 1 else "import sys; print(sys.implementation)"))
