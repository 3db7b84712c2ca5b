"""`make bench`: speed, memory and precision figures, measured in one run.

Each area is a module of this package with ``bench(report)``; ``core`` (the fixed-point core)
runs first, the others in name order. On-device figures come from the real interpreters
(tools/firmware/); times are ratios to a floor measured in the same run, interleaved and repeated
(the minimum of each is kept), because the VM's ticks have millisecond resolution and the host
may be busy. ``python -m tools bench [AREA ...]`` runs only the named areas.
"""

import argparse
import importlib
import os
import pkgutil
import platform
import sys
import time

from tools import LIB

if LIB not in sys.path:
    sys.path.insert(0, LIB)


def areas():
    """The bench modules of this package, core first."""
    names = sorted(m.name for m in pkgutil.iter_modules([os.path.dirname(os.path.abspath(__file__))]) if not m.name.startswith("_"))
    return ["core"] + [n for n in names if n != "core"]


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m tools bench", description=__doc__.splitlines()[0])
    ap.add_argument("areas", nargs="*", metavar="AREA",
                    help="run only these areas (default all): %s" % ", ".join(areas()))
    want = ap.parse_args(argv).areas
    unknown = [a for a in want if a not in areas()]
    if unknown:
        ap.error("unknown bench area %s (areas: %s)" % (", ".join(unknown), ", ".join(areas())))
    print("tempcomp benchmarks, %s, %s, Python %s, %d CPUs" % (
        time.strftime("%Y-%m-%d"), platform.machine(), platform.python_version(), os.cpu_count()))

    def report(name, value, unit):
        if isinstance(value, float):
            value = "%.4g" % value
        print("  %-72s %s %s" % (name, value, unit), flush=True)

    for name in want or areas():
        importlib.import_module("tools.bench." + name).bench(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
