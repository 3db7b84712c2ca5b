"""The virtual Pico behind the hardened front end (tools/vboard/server.mjs --board pico): its flash
image and world control socket never followed through a link planted in their place, and
`--stop` stopping only the board its pid file names. Its pid file and log are in
host_tests/board/test_vboard_attacks.py (test_pid_file_and_log_are_not_written_through_links,
board=pico)."""

import json
import os
import subprocess

import pytest
from paths import skip_unless_ci
from vboard_line import CEILING, NODE, SERVER, VirtualBoard

from tools.board import picoctl


@pytest.fixture(autouse=True)
def firmware():
    why = picoctl.missing()
    if why:
        skip_unless_ci("virtual Pico cannot run: " + why)


def pico(run, **kw):
    return VirtualBoard(run / "flash.img", extra=["--board", "pico", "--no-pty"], **kw)


def test_world_socket_and_flash_image_are_not_followed(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    run = tmp_path / "pico"
    run.mkdir()
    # a link where the world control socket goes: the board starts without the channel and
    # leaves the link (and its target) alone; so for a file of someone else's
    os.symlink(victim, run / "world.sock")
    b = pico(run).start()
    try:
        assert "exists and is not this user's socket: no world control" in b.log()
        assert "world control" not in "".join(x for x in b.lines if x.startswith("  "))
        r = b.mpremote("exec", "print(1 + 1)", timeout=CEILING)
        assert r.stdout.strip() == "2"
    finally:
        b.stop()
    assert (run / "world.sock").is_symlink() and victim.read_text() == "precious\n"
    # a link where the flash image goes: refused, the target never written
    os.remove(run / "world.sock")
    os.remove(run / "flash.img")  # the image the first start made
    os.symlink(victim, run / "flash.img")
    b = pico(run)
    try:
        b.start()  # the front end may be up before the RP2040 thread refuses the image
    except RuntimeError:
        pass
    try:
        assert b.proc.wait(CEILING) != 0, b.log()
    finally:
        b.stop()
    assert "is a symbolic link: the flash image is not written through links" in b.log()
    assert victim.read_text() == "precious\n"


def test_stop_stops_only_the_pico_its_pid_file_names(tmp_path):
    # a VM board and a virtual Pico side by side, each with its own pid file: stopping the
    # Pico by its file leaves the VM board running, and its world socket goes with it
    vm = VirtualBoard(tmp_path / "vm" / "flash").start()
    (tmp_path / "pico").mkdir()
    p = pico(tmp_path / "pico").start()
    try:
        own = tmp_path / "pico" / ("board-%d.pid" % id(p))
        assert json.loads(own.read_text())["pid"] == p.proc.pid
        assert (tmp_path / "pico" / "world.sock").exists()
        r = subprocess.run([NODE, str(SERVER), "--board", "pico", "--stop", "--pidfile", str(own)],
                           capture_output=True, text=True, timeout=CEILING)
        assert r.returncode == 0 and "stopped" in r.stdout, r.stdout + r.stderr
        p.proc.wait(CEILING)
        assert vm.proc.poll() is None
        assert vm.mpremote("exec", "print(6 * 7)").stdout.strip() == "42"
        assert not (tmp_path / "pico" / "world.sock").exists()
    finally:
        p.stop()
        vm.stop()
