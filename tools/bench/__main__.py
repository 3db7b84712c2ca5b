"""`make bench`: speed, memory and precision figures, measured in one run.

Each area is a module of this package with ``bench(report)``; ``core`` (the fixed-point core)
runs first, the others in name order. On-device figures come from the real interpreters
(tools/firmware/); times are ratios to a floor measured in the same run, interleaved and repeated
(the minimum of each is kept), because the VM's ticks have millisecond resolution and the host
may be busy. ``python -m tools bench [AREA ...]`` runs only the named areas.

Every figure is also written to the record ``docs/bench.json`` (the areas run replace theirs,
the others stay; an area that raises keeps its previous figures), and the figure tables of
README.md and docs/ are rendered from that record (tools/bench/figures.py), so what the pages
show is one run's output; ``--no-write`` leaves both alone, ``--docs`` only renders the pages
again from the record. A check a figure fails (a budget printed OVER, a heap-locked run that
allocated) makes the exit status 1, after every area has run.
"""

import argparse
import importlib
import os
import pkgutil
import platform
import sys
import time
import traceback

from tools import LIB

if LIB not in sys.path:
    sys.path.insert(0, LIB)


def areas():
    """The bench modules of this package, core first."""
    names = sorted(m.name for m in pkgutil.iter_modules([os.path.dirname(os.path.abspath(__file__))])
                   if not m.name.startswith("_") and m.name not in ("figures", "record"))
    return ["core"] + [n for n in names if n != "core"]


def main(argv=None):
    from tools.bench import figures, record

    ap = argparse.ArgumentParser(prog="python -m tools bench", description=__doc__.splitlines()[0])
    ap.add_argument("areas", nargs="*", metavar="AREA",
                    help="run only these areas (default all): %s" % ", ".join(areas()))
    ap.add_argument("--no-write", action="store_true",
                    help="print only: leave docs/bench.json and the pages' figure tables as they are")
    ap.add_argument("--docs", action="store_true",
                    help="measure nothing: render the pages' figure tables again from docs/bench.json")
    a = ap.parse_args(argv)
    if a.docs:
        changed = figures.write_pages(record.load())
        print("rendered from %s: %s" % (os.path.relpath(record.PATH), ", ".join(changed) or "every page up to date"))
        return 0
    unknown = [x for x in a.areas if x not in areas()]
    if unknown:
        ap.error("unknown bench area %s (areas: %s)" % (", ".join(unknown), ", ".join(areas())))
    run = record.Run(machine=platform.machine(), python=platform.python_version(), cpus=os.cpu_count())
    print("tempcomp benchmarks, %s, %s, Python %s, %d CPUs, load average %.1f" % (
        run.date, run.machine, run.python, run.cpus, run.load))
    for name in a.areas or areas():
        t0 = time.time()
        run.start(name)
        try:
            importlib.import_module("tools.bench." + name).bench(run.report)
        except Exception:  # noqa: BLE001 - the other areas still run; the exit status says it failed
            traceback.print_exc()
            run.raise_(name, "%s: the area raised %s (its previous record kept)"
                       % (name, traceback.format_exc().strip().splitlines()[-1]))
        run.end(name, time.time() - t0)
    if not a.no_write:
        rec = record.merge(record.load(), run, full=not a.areas)
        record.save(rec)
        changed = figures.write_pages(rec, strict=False)
        print("wrote %s; figure tables rendered: %s" % (os.path.relpath(record.PATH), ", ".join(changed) or "none changed"))
        for miss in figures.missing(rec):
            print("  not in the record yet (run its area): %s" % miss)
    if run.failed:
        print("make bench: %d check(s) failed:" % len(run.failed))
        for f in run.failed:
            print("  " + f)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
