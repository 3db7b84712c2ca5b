"""`python -m tools` lists every host command and each `<command> --help` answers with an example;
the long spellings the docs used before keep working."""
import pathlib
import subprocess
import sys

import pytest
from paths import REPO

from tools.__main__ import COMMANDS

REPO_PATH = pathlib.Path(REPO)


def run(*args):
    return subprocess.run([sys.executable, "-m", *args], cwd=REPO, capture_output=True, text=True,
                          timeout=120)


def test_help_lists_every_command():
    r = run("tools", "--help")
    assert r.returncode == 0
    for name in ("fit", "gap", "replay", "board", "deploy", "store", "bench", "demo"):
        assert name in COMMANDS
        assert "\n  %s " % name in r.stdout


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_each_command_helps_with_an_example(name):
    r = run("tools", name, "--help")
    assert r.returncode == 0, r.stderr
    assert "usage:" in r.stdout
    if name != "board":
        assert "example: python -m tools %s" % name in r.stdout


def test_unknown_command_is_one_clear_line():
    r = run("tools", "calibrate")
    assert r.returncode == 2
    assert r.stderr.splitlines()[0] == "error: unknown command 'calibrate'"
    assert "Traceback" not in r.stderr


@pytest.mark.parametrize("module", ["tools.fit", "tools.simgap"])
def test_old_spellings_keep_working(module):
    r = run(module, "--help")
    assert r.returncode == 0 and "usage:" in r.stdout
