"""The fixed-point step of `make demo` runs and its compensation really beats the raw output."""

import re
import subprocess
import sys

from tools.board import build_mpy


def test_demo_prints_a_table_where_compensation_wins():
    proc = subprocess.run([sys.executable, "-m", "tools.demo.fixedpoint"], cwd=build_mpy.REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    m = re.search(r"uncompensated (\d+) mdps, compensated (\d+) mdps", proc.stdout)
    assert m, proc.stdout
    raw_err, comp_err = int(m.group(1)), int(m.group(2))
    assert comp_err * 20 < raw_err
    m = re.search(r"same calibration: ([0-9.]+) output LSB", proc.stdout)
    assert float(m.group(1)) <= 0.51
