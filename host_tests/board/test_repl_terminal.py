"""What a person does (issue 14): start the virtual board, run the REPL command its banner prints
in a real terminal (tmux), type a line and read the answer, run the guided session's first step,
and leave with Ctrl-]. This runs README.md's `mpremote connect build/vboard/tty repl` (the command the
banner prints) and the three lines of docs/demo.md's guided session, typed as written.

Stock mpremote, a real pty, a real terminal emulator: nothing here talks to the board except
through the keys typed into tmux.
"""

import os
import shlex
import shutil
import subprocess
import time

import pytest
from paths import in_ci
from vboard_line import REPO, VirtualBoard

from tools.board.boardctl import Remote

TMUX = shutil.which("tmux")
# in CI (CI=true) tmux is installed by .ci/run: there the tests run and fail without it
pytestmark = pytest.mark.skipif(TMUX is None and not in_ci(), reason="needs tmux (.ci/run installs it)")


class Terminal:
    """One tmux window running a command; keys in, screen text out."""

    def __init__(self, command, cwd, name):
        self.sock = name
        self.tmux("new-session", "-d", "-s", "t", "-x", "160", "-y", "50", "-c", str(cwd), command)
        self.tmux("set-option", "-t", "t", "remain-on-exit", "on")

    def tmux(self, *args):
        return subprocess.run([TMUX, "-L", self.sock, *args], capture_output=True, text=True, timeout=30)

    def keys(self, *keys):
        self.tmux("send-keys", "-t", "t", *keys)

    def type_line(self, text):
        self.keys("-l", text)
        self.keys("Enter")

    def screen(self):
        return self.tmux("capture-pane", "-p", "-J", "-S", "-2000", "-t", "t").stdout

    def wait_for(self, text, timeout=120, after=0):
        """The screen once `text` appears at or after character `after` (a hang guard, not a timing)."""
        deadline = time.monotonic() + timeout
        while True:
            s = self.screen()
            if text in s[after:]:
                return s
            if time.monotonic() > deadline:
                raise AssertionError("%r did not appear on the terminal:\n%s" % (text, s))
            time.sleep(0.2)

    def wait_prompt(self, timeout=120):
        """Until the last line on the screen is the REPL's prompt (tmux drops its trailing space)."""
        deadline = time.monotonic() + timeout
        while True:
            lines = [x for x in self.screen().splitlines() if x.strip()]
            if lines and lines[-1].rstrip() == ">>>":
                return
            if time.monotonic() > deadline:
                raise AssertionError("no prompt on the terminal:\n%s" % self.screen())
            time.sleep(0.2)

    def dead(self):
        return self.tmux("display-message", "-p", "-t", "t", "#{pane_dead}").stdout.strip() == "1"

    def close(self):
        self.tmux("kill-server")


def test_repl_in_a_terminal_runs_the_first_session_step(tmp_path):
    b = VirtualBoard(tmp_path / "flash").start()
    term = None
    try:
        # the banner's one REPL line, run as printed (a path relative to where the board started)
        cmd = b.repl_command
        assert cmd and cmd.startswith("mpremote connect ") and cmd.endswith(" repl"), b.log()
        Remote(b.url).deploy_mpy("virtual", str(tmp_path / "mpy"))
        venv_bin = os.path.dirname(os.path.abspath(os.path.join(REPO, ".venv", "bin", "python")))
        argv = shlex.split(cmd)
        assert argv[0] == "mpremote"
        run = " ".join([shlex.quote(os.path.join(venv_bin, "mpremote"))] + [shlex.quote(a) for a in argv[1:]])
        term = Terminal(run, os.getcwd(), "tempcomp-repl-%d" % os.getpid())
        term.wait_for("Use Ctrl-] or Ctrl-x to exit this shell")

        term.keys("Enter")
        term.wait_prompt()
        term.type_line("21 * 2")
        term.wait_for("\n42\n")

        term.type_line("import tempcomp_board")
        term.type_line("from tempcomp.session import Session")
        term.type_line("Session(tempcomp_board).run()")
        s = term.wait_for("Press Enter to start ([s] skip, [q] quit): ")
        assert "== Zero at rest ==" in s and "found: mlx90609, mpu6xxx" in s, s
        mark = len(s) - 60
        term.keys("Enter")  # the zero at rest, as a person lays the board down and presses Enter
        s = term.wait_for("== Check on another face ==", after=mark)
        assert "moved" not in s[mark:] and "!" not in s[mark:].replace("!=", ""), s[mark:]
        term.wait_for("Press Enter to start ([s] skip, [q] quit): ", after=s.index("== Check on another face =="))
        term.type_line("q")
        term.wait_for("nothing saved")
        term.wait_prompt()
        assert "Traceback" not in term.screen()  # quitting is an answer, not an error

        term.keys("C-]")
        deadline = time.monotonic() + 30
        while not term.dead():
            assert time.monotonic() < deadline, term.screen()
            time.sleep(0.2)
        # the board is still there for the next command
        assert "hello" in Remote(b.url).mpremote("exec", "print('hello')")
    finally:
        if term is not None:
            term.close()
        b.stop()
