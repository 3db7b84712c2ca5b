"""`make demo` and `make bench` exit with status 1 when a check they print fails, after running
the rest: each failure is brought about through the job's real path (a real measurement against
a bound it misses, a real command that refuses its input), never by a stand-in that reports
failure."""
import json
import os

import augsynth
import pytest
import seeds
from paths import skip_unless_ci

from tools.bench import __main__ as bench_main
from tools.bench import ram as bench_ram
from tools.board.boardctl import BoardError
from tools.demo import __main__ as demo
from tools.demo import augment as demo_augment
from tools.firmware import interp as fw
from tools.simgap import export
from tools.simgap.diagnose import diagnose


def test_the_demo_fails_when_the_fixed_point_check_fails(capsys):
    # the fixed-point step's own check (tools.demo.fixedpoint) against a bound its result misses
    steps = demo.Steps()
    assert steps.run("the fixed-point step", demo.fixedpoint_step, "--bound", "0.01") is None
    assert steps.exit_status() == 1
    assert len(steps.failed) == 1 and "more than 0.01" in steps.failed[0], steps.failed
    # the same step with the documented bound passes, and later steps still run after a failure
    assert steps.run("the fixed-point step", demo.fixedpoint_step) == "compared the fixed-point core with float64 in the VM"
    assert steps.exit_status() == 1 and len(steps.done) == 1
    ok = demo.Steps()
    ok.run("the fixed-point step", demo.fixedpoint_step)
    assert ok.exit_status() == 0 and not ok.failed
    assert "FAILED: the fixed-point step" in capsys.readouterr().out


def test_the_demo_fails_when_the_board_step_fails(tmp_path):
    # the board step with an exported model whose store record `store put` refuses (a frac out of
    # range): it used to say "store put failed" and return as if skipped
    k = seeds.seed("exit_status/log")  # the logs of this run
    tr, wh = augsynth.make("drift", seed=k), augsynth.make("drift", withheld=True, seed=k)
    res, _ = diagnose(tr, wh)
    path = tmp_path / "tofupilot_gyro_model.json"
    model = export.write(str(path), res, tr)  # what `gap --export` writes
    model["store"]["frac"][0] = 99
    path.write_text(json.dumps(model))
    said = []
    with pytest.raises(BoardError, match="store put failed"):
        demo_augment.run(said.append, str(tmp_path))
    steps = demo.Steps()
    steps.run("the board step", demo_augment.run, said.append, str(tmp_path))
    assert steps.exit_status() == 1 and "store put failed" in steps.failed[0]
    # no exported model at all is a failure too, not a skip
    os.remove(tmp_path / "tofupilot_gyro_model.json")
    steps.run("the board step", demo_augment.run, said.append, str(tmp_path))
    assert len(steps.failed) == 2 and "exported no model" in steps.failed[1]


def test_bench_exits_1_after_an_area_fails_and_runs_the_rest(monkeypatch, capsys):
    # simgap at 5 rows: the diagnosis refuses a log that short, so the area raises; store runs after
    monkeypatch.setenv("BENCH_SIMGAP_ROWS", "5")
    assert bench_main.main(["simgap", "store", "--no-write"]) == 1
    out = capsys.readouterr().out
    assert "store image, 4 sensors x 24 values" in out  # the area after the failure ran
    assert "make bench: 1 check(s) failed:" in out and "simgap: the area raised" in out


def test_bench_exits_1_when_a_budget_is_over(monkeypatch, capsys):
    # the RAM area's session budget row, measured on the Cortex-M3 firmware, against a budget of
    # 1 KB that the real import (about 17 KB) is over: printed OVER, exit status 1
    why = fw.missing("an385")
    if why:
        skip_unless_ci("an385 cannot run: %s" % why)
    monkeypatch.setenv("BENCH_RAM", "session")
    monkeypatch.setattr(bench_ram, "BUDGET_SESSION", 1024)
    assert bench_main.main(["ram", "--no-write"]) == 1
    out = capsys.readouterr().out
    lines = [ln for ln in out.splitlines() if "`import tempcomp.session` from .mpy" in ln]
    assert len(lines) == 2 and "OVER" in lines[0], out  # the row, and its line in the failure list
    assert "make bench:" in out and "check(s) failed" in out
