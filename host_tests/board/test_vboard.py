"""The virtual board driven the way a user drives a real one: unmodified
mpremote over pyserial's socket:// transport, against the real MicroPython
WebAssembly VM served by tools/vboard/server.mjs.

Each test starts its own board (on a free port, with its own flash directory)
and stops it afterwards.
"""

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from vboard_line import BANNER_END, NODE, REPO, SERVER, START_TIMEOUT, Line, VirtualBoard  # noqa: F401

EXAMPLE_DEVICES = '''
class Thermometer:
    """Trivial I2C device: register 0 = id 0x5A, registers 1-2 = centi-degC."""

    def __init__(self, board):
        self.board = board
        self.regs = bytearray(8)
        self.regs[0] = 0x5A
        self.ptr = 0

    def write(self, buf):
        self.ptr = buf[0]
        for b in buf[1:]:
            self.regs[self.ptr] = b
            self.ptr += 1

    def read_into(self, buf):
        t = int(self.board.temperature_c() * 100)
        self.regs[1] = (t >> 8) & 0xFF
        self.regs[2] = t & 0xFF
        for i in range(len(buf)):
            buf[i] = self.regs[self.ptr + i]


class Inverter:
    """Trivial SPI device: answers each byte inverted, counts selections."""

    def __init__(self):
        self.selections = 0

    def select(self):
        self.selections += 1

    def transfer(self, wbuf, rbuf):
        if rbuf is not None:
            for i in range(len(rbuf)):
                rbuf[i] = wbuf[i] ^ 0xFF


inverter = Inverter()


def setup(board):
    board.set_profile([(0, 30.0), (1000, 30.0)])
    board.add_i2c(0, 0x68, Thermometer(board))
    board.add_spi(0, 17, inverter)
    board.add_adc(26, lambda: 40000)
'''


@pytest.fixture
def board(tmp_path):
    b = VirtualBoard(tmp_path / "flash").start()
    yield b
    b.stop()


@pytest.fixture
def device_board(tmp_path):
    devices = tmp_path / "devices.py"
    devices.write_text(EXAMPLE_DEVICES)
    b = VirtualBoard(tmp_path / "flash", devices=devices).start()
    yield b
    b.stop()


def test_exec_and_eval(board):
    r = board.mpremote("exec", "import sys; print('impl', sys.implementation.name)",
                       "eval", "2**40 + 1")
    assert "impl micropython" in r.stdout
    # 2**40 does not fit a 32-bit small int: the VM is MicroPython, not CPython.
    assert "1099511627777" in r.stdout


def test_exec_error_is_reported_like_a_board(board):
    r = board.mpremote("exec", "def f():\n  return 1/0\nf()", check=False)
    assert r.returncode != 0
    assert "ZeroDivisionError" in r.stdout + r.stderr
    # ... and the board is still usable afterwards.
    assert board.mpremote("eval", "6*7").stdout.strip() == "42"


def test_cp_ls_cat_mkdir_rm(board, tmp_path):
    blob = os.urandom(5000)
    src = tmp_path / "blob.bin"
    src.write_bytes(blob)
    text = tmp_path / "note.txt"
    text.write_text("first line\nsecond line\n")
    board.mpremote("mkdir", ":lib", "+", "cp", str(src), ":lib/blob.bin",
                   "+", "cp", str(text), ":note.txt")
    ls = board.mpremote("ls", ":lib").stdout
    assert "5000 blob.bin" in ls
    back = tmp_path / "back.bin"
    board.mpremote("cp", ":lib/blob.bin", str(back))
    assert back.read_bytes() == blob
    assert "second line" in board.mpremote("cat", ":note.txt").stdout
    # Written through to the host-side flash as soon as the file was closed.
    assert (board.flash / "lib" / "blob.bin").read_bytes() == blob

    board.mpremote("rm", ":lib/blob.bin", "+", "rmdir", ":lib", "+", "rm", ":note.txt")
    assert board.mpremote("eval", "__import__('os').listdir('/')").stdout.strip() == "[]"
    assert not (board.flash / "lib").exists()
    r = board.mpremote("rm", ":missing.txt", check=False)
    assert r.returncode != 0 and "No such file" in r.stdout + r.stderr


def test_run_host_file(board, tmp_path):
    script = tmp_path / "script.py"
    script.write_text("import sys\nprint('ran as', __name__, 'on', sys.platform)\n")
    assert "ran as __main__ on webassembly" in board.mpremote("run", str(script)).stdout


def test_soft_reset_clears_ram_keeps_flash_runs_boot(board, tmp_path):
    boot = tmp_path / "boot.py"
    boot.write_text("booted = 'yes'\n")
    board.mpremote("cp", str(boot), ":boot.py", "+", "exec", "ram = 1")
    assert board.mpremote("resume", "eval", "ram").stdout.strip() == "1"
    board.mpremote("soft-reset")
    r = board.mpremote("resume", "eval", "('ram' in globals(), booted)")
    assert r.stdout.strip() == "(False, 'yes')"
    assert "boot.py" in board.mpremote("ls").stdout


def test_soft_reset_banner_on_the_line(board):
    line = Line(board.port)
    try:
        line.friendly_prompt()
        line.send(b"\x04")
        out = line.read_until(b">>> ")
        assert b"MPY: soft reboot\r\n" in out
        assert b"MicroPython v1.27" in out
    finally:
        line.close()


def test_power_cycle_keeps_files(tmp_path):
    flash = tmp_path / "flash"
    payload = tmp_path / "data.txt"
    payload.write_text("survives power loss\n")
    first = VirtualBoard(flash).start()
    try:
        first.mpremote("cp", str(payload), ":data.txt",
                       "+", "exec", "f = open('log.txt', 'w'); f.write('closed'); f.close()")
        first.kill()
    finally:
        first.stop()
    second = VirtualBoard(flash).start()
    try:
        r = second.mpremote("cat", ":data.txt", "+", "cat", ":log.txt")
        assert "survives power loss" in r.stdout and "closed" in r.stdout
    finally:
        second.stop()


def test_ctrl_c_interrupts_tight_loop_and_keeps_ram(board):
    # mpremote returns once the board acknowledged the code (OK): the loop runs, or is about
    # to (a Ctrl-C queued just before it starts interrupts it too, as a UART interrupt would)
    board.mpremote("exec", "--no-follow", "n = 42\nwhile True:\n  pass")
    line = Line(board.port)
    try:
        line.send(b"\x03")
        out = line.read_until(b"\x04>")  # the helper's ceiling: under load the interrupt may take a while
        assert b"KeyboardInterrupt" in out
    finally:
        line.close()
    # Globals survive: it was an interrupt, not a reset.
    assert board.mpremote("resume", "eval", "n").stdout.strip() == "42"


def test_mpremote_interrupts_sleeping_main_loop(board):
    # an hour's sleep: mpremote gets its answer only if Ctrl-C ends a sleep, as on a board
    board.mpremote("exec", "--no-follow", "import time\nm = 7\nwhile True:\n  time.sleep(3600)")
    assert board.mpremote("resume", "eval", "m * 6", timeout=120).stdout.strip() == "42"
    r = board.mpremote("exec", "import time, vboard\nt = time.ticks_ms()\nc = vboard.board.clock_us()\n"
                       "time.sleep_ms(200)\n"
                       "print('slept', time.ticks_diff(time.ticks_ms(), t), vboard.board.clock_us() - c)")
    host_ms, board_us = map(int, r.stdout.split()[-2:])
    assert host_ms >= 200  # a sleep never ends early
    assert board_us == 200_000  # and moves the board's simulated clock by exactly what was asked


def test_friendly_repl_and_input(board):
    line = Line(board.port)
    try:
        line.friendly_prompt()
        line.send(b"21 * 2\r")
        assert b"42\r\n" in line.read_until(b">>> ")
        line.send(b"name = input('who? ')\r")
        # the prompt input() prints, not the echo of the typed line (which holds it too)
        line.read_until(b"')\r\nwho? ")
        line.send(b"ada\r")
        line.read_until(b">>> ")
        line.send(b"name.upper()\r")
        assert b"'ADA'" in line.read_until(b">>> ")
        # Ctrl-A / Ctrl-B switch to the raw REPL and back, as on a board.
        line.send(b"\x01")
        line.read_until(b"raw REPL; CTRL-B to exit\r\n>")
        line.send(b"print('raw', 1)\x04")
        assert line.read_until(b"\x04>") == b"OKraw 1\r\n\x04\x04>"
        line.send(b"\x02")
        assert b"MicroPython" in line.read_until(b">>> ")
    finally:
        line.close()


def test_machine_buses_reach_device_models(device_board):
    code = """
from machine import I2C, SPI, Pin, ADC
import errno
i2c = I2C(0, sda=Pin(4), scl=Pin(5))
print('scan', i2c.scan())
print('id', hex(i2c.readfrom_mem(0x68, 0, 1)[0]))
b = bytearray(2)
i2c.readfrom_mem_into(0x68, 1, b)
print('centi', (b[0] << 8) | b[1])
i2c.writeto_mem(0x68, 4, b'\\x11\\x22')
print('back', i2c.readfrom_mem(0x68, 4, 2) == b'\\x11\\x22')
try:
    i2c.readfrom_mem(0x50, 0, 1)
except OSError as e:
    print('nack', e.errno == errno.ENODEV)
spi = SPI(0)
cs = Pin(17, Pin.OUT, value=1)
print('floating', spi.read(2))
cs(0)
r = bytearray(3)
spi.write_readinto(b'\\x00\\x0f\\xf0', r)
cs(1)
print('spi', bytes(r))
import vboard_devices
print('selections', vboard_devices.inverter.selections)
print('adc', ADC(Pin(26)).read_u16(), ADC(0).read_u16())
"""
    out = device_board.mpremote("exec", code).stdout
    assert "scan [104]" in out
    assert "id 0x5a" in out
    assert "centi 3000" in out
    assert "back True" in out
    assert "nack True" in out
    assert "floating b'\\xff\\xff'" in out
    assert "spi b'\\xff\\xf0\\x0f'" in out
    assert "selections 1" in out
    assert "adc 40000 40000" in out


def test_boards_virtual_module_on_the_board(device_board):
    device_board.mpremote("cp", str(REPO / "boards" / "virtual.py"), ":virtual.py")
    r = device_board.mpremote(
        "exec", "import virtual\nb = virtual.setup()\nprint(sorted(b), b['i2c'].scan())")
    assert "['adc_rate', 'adc_temp', 'i2c', 'mlx_cs', 'spi'] [104]" in r.stdout


def test_boards_virtual_matches_board_wiring():
    def constants(path):
        tree = ast.parse(Path(path).read_text())
        return {t.id: ast.literal_eval(n.value) for n in tree.body if isinstance(n, ast.Assign)
                for t in n.targets if isinstance(t, ast.Name) and t.id.isupper()
                and isinstance(n.value, ast.Constant)}

    user = constants(REPO / "boards" / "virtual.py")
    pcb = constants(REPO / "tools" / "vboard" / "vm" / "vboard_devices.py")
    assert user["I2C_ID"] == pcb["I2C_BUS"]
    assert user["MPU6500_ADDR"] == pcb["MPU6500_ADDR"]
    assert user["SPI_ID"] == pcb["SPI_BUS"]
    assert user["MLX90609_CS"] == pcb["MLX90609_CS"]
    assert user["ADC_RATE"] == pcb["ADC_RATE"]
    assert user["ADC_TEMP"] == pcb["ADC_TEMP"]


def test_mip_install_from_local_package(board, tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "hello_vb").mkdir(parents=True)
    (pkg / "hello_vb" / "__init__.py").write_text("GREETING = 'hi from mip'\n")
    (pkg / "package.json").write_text(json.dumps({
        "urls": [["hello_vb/__init__.py", "hello_vb/__init__.py"]],
        "version": "0.1.0",
    }))
    board.mpremote("mip", "install", str(pkg / "package.json"))
    r = board.mpremote("exec", "import hello_vb\nprint(hello_vb.GREETING, hello_vb.__file__)")
    assert "hi from mip /lib/hello_vb/__init__.py" in r.stdout
    assert (board.flash / "lib" / "hello_vb" / "__init__.py").exists()


def test_port_in_use_is_a_clear_error(board, tmp_path):
    r = subprocess.run([NODE, str(SERVER), "--port", str(board.port), "--flash",
                        str(tmp_path / "other"), "--pidfile", str(tmp_path / "other.pid")],
                       capture_output=True, text=True, timeout=START_TIMEOUT)
    assert r.returncode == 3
    assert f"port {board.port}" in r.stderr and "already in use" in r.stderr
    assert "BOARD_TCP=" in r.stderr


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pty paths are Linux-specific")
def test_pty_serves_the_same_repl(tmp_path):
    b = VirtualBoard(tmp_path / "flash", extra=["--pty"]).start()
    try:
        assert b.pty and b.pty.startswith("/dev/")
        r = subprocess.run([sys.executable, "-m", "mpremote", "connect", b.pty,
                            "exec", "shared = 42\nprint('over the pty', shared)"],
                           capture_output=True, text=True, timeout=30)
        assert "over the pty 42" in r.stdout, r.stdout + r.stderr + b.log()
        # The TCP port is the same board: it sees the RAM the pty session left.
        assert b.mpremote("resume", "eval", "shared").stdout.strip() == "42"
    finally:
        b.stop()


def test_detach_then_stop(tmp_path):
    pidfile = tmp_path / "bg.pid"
    base = [NODE, str(SERVER), "--pidfile", str(pidfile)]
    r = subprocess.run(base + ["--detach", "--port", "0", "--flash", str(tmp_path / "flash")],
                       capture_output=True, text=True, timeout=START_TIMEOUT + 5)
    assert r.returncode == 0, r.stdout + r.stderr
    try:
        port = int(r.stdout.split("socket://127.0.0.1:")[1].split()[0])
        pid = json.loads(pidfile.read_text())["pid"]
        # the banner of a board in the background names the REPL command and how to stop it
        assert "REPL: mpremote connect %s repl" % (tmp_path / "tty") in r.stdout, r.stdout
        assert "stop: make board-stop" in r.stdout and "Ctrl-C" not in r.stdout
        b = VirtualBoard(tmp_path / "flash")
        b.port = port
        assert b.mpremote("eval", "1 + 1").stdout.strip() == "2"
    finally:
        r = subprocess.run(base + ["--stop"], capture_output=True, text=True, timeout=10)
    assert r.returncode == 0 and "stopped" in r.stdout
    assert not pidfile.exists()
    try:
        state = open("/proc/%d/stat" % pid).read().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        state = "gone"
    assert state in ("gone", "Z")  # Z: exited, not reaped (no init reaping in some containers)


def test_hard_reset_runs_main_py_and_mpremote_stops_it(board, tmp_path):
    main = tmp_path / "main.py"
    main.write_text("import time\nloops = 0\nwhile True:\n    loops += 1\n"
                    "    if loops == 1:\n        print('main.py looping')\n    time.sleep_ms(20)\n")
    board.mpremote("cp", str(main), ":main.py", "+", "exec", "before = 1")
    line = Line(board.port)
    try:
        line.friendly_prompt()
        line.send(b"import machine; machine.reset()\r")
        line.read_until(b"main.py looping", timeout=30)
    finally:
        line.close()
    # main.py has been looping since the reset; mpremote's Ctrl-C stops it, its globals are
    # still there and the RAM from before the reset is not
    r = board.mpremote("resume", "eval", "(loops >= 1, 'before' in globals())")
    assert r.stdout.strip() == "(True, False)"
