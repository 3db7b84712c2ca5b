"""`make setup`'s firmware build (tools/firmware/build.py) without building: it leaves a complete
build/fw alone, refuses a source path that is not a MicroPython tree with one line naming it, and
says what it would install instead of failing when the Debian packages are missing."""
import subprocess
import sys

from paths import REPO

from tools.firmware import build


def run(*args):
    return subprocess.run([sys.executable, "-m", "tools.firmware.build", *args], cwd=REPO,
                          capture_output=True, text=True, timeout=60)


def test_a_complete_output_directory_is_left_alone(tmp_path, monkeypatch):
    for rel in build.artefacts(str(tmp_path)).values():
        p = tmp_path / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"built")
    monkeypatch.setattr(build, "debian_packages", lambda need: [])
    assert build.main(["--out", str(tmp_path)]) == 0
    assert all((tmp_path / rel).read_bytes() == b"built" for rel in build.artefacts(str(tmp_path)).values())


def test_a_wrong_source_path_is_refused_by_name(tmp_path):
    proc = run("--out", str(tmp_path / "fw"), "--micropython-src", str(tmp_path))
    assert proc.returncode == 2
    assert "is not a MicroPython/CircuitPython source tree (no py/ inside)" in proc.stderr
    assert not (tmp_path / "fw").exists()


def test_missing_packages_print_the_one_command_when_not_root(monkeypatch, capsys):
    monkeypatch.setattr(build.os, "geteuid", lambda: 1000)
    monkeypatch.setitem(build.DEBIAN, "qemu-system-arm", lambda: False)
    assert build.debian_packages(["qemu-system-arm"]) == ["qemu-system-arm"]
    assert "run:  sudo apt-get install -y qemu-system-arm" in capsys.readouterr().out
