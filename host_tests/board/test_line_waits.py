"""The board helpers (host_tests/helpers/vboard_line.py) wait for events, not for deadlines: a
board that stalls (a loaded host that does not schedule it for seconds) makes a test slower,
never a failure, and a prompt that comes late is never mistaken for the next command's."""
import os
import signal
import socket
import threading
import time

from vboard_line import BANNER_END, Line, VirtualBoard


def _stall(proc, seconds):
    # the whole server (and the VM's worker thread in it) stops being scheduled, as on a busy host
    os.kill(proc.pid, signal.SIGSTOP)
    t = threading.Timer(seconds, os.kill, (proc.pid, signal.SIGCONT))
    t.start()
    return t


def test_ctrl_c_and_the_prompt_outlast_a_stalled_board(tmp_path):
    board = VirtualBoard(tmp_path / "flash").start()
    try:
        board.mpremote("exec", "--no-follow", "n = 5\nwhile True:\n  pass")
        line = Line(board.port)
        try:
            t0 = time.monotonic()
            timer = _stall(board.proc, 8.0)  # longer than the 5 s the Ctrl-C wait allowed
            line.send(b"\x03")
            assert b"KeyboardInterrupt" in line.read_until(b"\x04>")
            assert time.monotonic() - t0 >= 7.5
            timer.join()
            timer = _stall(board.proc, 6.0)
            line.friendly_prompt()  # the banner and the answer come after the stall
            timer.join()
            line.send(b"n * 3\r")
            assert b"\r\n15\r\n" in line.read_until(b">>> ")
        finally:
            line.close()
    finally:
        board.stop()


class _LateBoard:
    """A peer that answers as a board whose last prompt after Ctrl-B comes 0.6 s late (output
    still queued on a loaded host): the banner, then, later, one more prompt."""

    def __init__(self):
        self.srv = socket.socket()
        self.srv.bind(("127.0.0.1", 0))
        self.srv.listen(1)
        self.port = self.srv.getsockname()[1]
        threading.Thread(target=self.serve, daemon=True).start()

    def serve(self):
        conn, _ = self.srv.accept()
        buf = b""
        while True:
            data = conn.recv(4096)
            if not data:
                return
            buf += data
            if b"\x02" in buf:
                buf = buf.split(b"\x02", 1)[1]
                conn.sendall(b"\r\nMicroPython v1.27.0 on 2026-01-01; virtual\r\n" + BANNER_END)
                time.sleep(0.6)
                conn.sendall(b"\r\n>>> ")
            while b"\r" in buf:
                cmd, buf = buf.split(b"\r", 1)
                reply = str(eval(cmd.decode(), {})).encode()  # noqa: S307 - the test's own expressions
                conn.sendall(cmd + b"\r\n" + reply + b"\r\n>>> ")


def test_friendly_prompt_takes_a_late_prompt_with_it():
    peer = _LateBoard()
    line = Line(peer.port)
    try:
        line.friendly_prompt()
        line.send(b"6*7\r")
        # the answer, not the late prompt of before
        assert b"42" in line.read_until(b">>> ")
    finally:
        line.close()
