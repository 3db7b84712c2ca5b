"""Bench hook for ``make bench``: a production line through the command line, units per second.

10,000 simulated six-position units (3 temperatures x 6 orientations x 20 samples: 360 rows each,
one CSV per unit in a temporary directory) go through ``python -m tools fit sixpos DIR`` as a
subprocess: read, fit, device check of every record, summary, JSON out. Reported: the child's CPU
time (one core: the command is single-threaded) and wall time, as units per second; writing the
CSVs is not timed. Run alone: ``.venv/bin/python -m tools bench fleet``.
"""

import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

from tools import REPO

UNITS = 10000


def bench(report, units=UNITS):
    from tools.fit import simulate as S

    with tempfile.TemporaryDirectory(prefix="tempcomp-fleet-") as d:
        S.fleet_files(os.path.join(d, "units"), units, np.random.default_rng(1), samples=20)
        out = os.path.join(d, "fleet.json")
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        p = subprocess.run([sys.executable, "-m", "tools", "fit", "sixpos", os.path.join(d, "units"),
                            "--counts-per-g", "16384", "--order", "2", "--json", out, "--no-progress"],
                           cwd=REPO, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if p.returncode != 0:
            raise RuntimeError("fleet fit failed: %s" % p.stderr.strip())
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        with open(out) as f:
            summary = json.load(f)["summary"]
    report("fit_fleet_%d_units_cpu" % units, cpu, "s (one core, command line end to end; target < 60)", key="cpu_s")
    report("fit_fleet_units_per_s", units / cpu, "units/s (CPU time)", key="units_per_s")
    report("fit_fleet_units_per_s_wall", units / wall, "units/s (wall time, this machine's load)", key="units_per_s_wall")
    report("fit_fleet_outliers_among_good_units", len(summary["outliers"]), "units (simulated: all good)", key="outliers")


if __name__ == "__main__":
    bench(lambda name, value, unit, key=None, ok=None: print("%-40s %12.4g %s" % (name, value, unit)))
