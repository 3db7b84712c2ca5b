"""The record of `make bench` (docs/bench.json): every figure a run printed, per area, with when,
where and under what load it was measured. ``python -m tools bench AREA`` replaces that area's
entry and keeps the others, so a change that moves one area's figures refreshes that area alone;
a full ``make bench`` replaces them all (the pages then say one run's date). The figure tables of
README.md and docs/ are rendered from this file (tools/bench/figures.py) and a test checks they
still are (host_tests/docs/test_figures.py)."""

import json
import math
import os
import re
import time

from tools import REPO

PATH = os.path.join(REPO, "docs", "bench.json")


def slug(name):
    """A row's default key: its printed name in lower case, words joined by _."""
    return re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")


class Run:
    """One run's figures as report() receives them; ``failed`` lists the checks that failed."""

    def __init__(self, machine, python, cpus):
        self.date = time.strftime("%Y-%m-%d")
        self.machine, self.python, self.cpus = machine, python, cpus
        self.load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        self.areas = {}
        self.failed = []
        self.raised = set()     # areas that raised: their figures are partial, not a record
        self._area = None

    def start(self, area):
        self._area = area
        self.areas[area] = {"date": self.date, "started": time.strftime("%Y-%m-%d %H:%M"),
                            "machine": self.machine, "python": self.python, "cpus": self.cpus,
                            "load": _num(os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")),
                            "rows": {}}

    def end(self, area, wall):
        self.areas[area]["wall_s"] = round(wall, 1)

    def fail(self, what):
        self.failed.append(what)

    def raise_(self, area, what):
        """The area raised: the run fails, and merge() keeps the area's previous record."""
        self.raised.add(area)
        self.fail(what)

    def report(self, name, value, unit, key=None, ok=None):
        """Print one figure and record it; ok=False marks a check it fails (budget, target)."""
        shown = "%.4g" % value if isinstance(value, float) else value
        mark = "" if ok is None else ("  ok" if ok else "  OVER/FAIL")
        print("  %-72s %s %s%s" % (name, shown, unit, mark), flush=True)
        area = self.areas[self._area]
        k = key or slug(name)
        if k in area["rows"]:
            raise ValueError("bench area %s reports %r twice" % (self._area, k))
        row = {"name": name, "value": _num(value), "unit": unit}
        if ok is not None:
            row["ok"] = bool(ok)
            if not ok:
                where = name if name.startswith(self._area) else "%s: %s" % (self._area, name)
                self.fail("%s = %s %s" % (where, shown, unit))
        area["rows"][k] = row


def _num(v):
    if isinstance(v, float):
        if not math.isfinite(v):
            return None  # strict JSON: a figure that could not be measured
        return float("%.6g" % v)
    return v


def load(path=PATH):
    if not os.path.exists(path):
        return {"areas": {}}
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def merge(rec, run, full):
    """The record with the run's areas replaced (a full run: the whole record). An area that
    raised keeps its previous entry (or has none): the rows it printed before raising are a
    partial measurement, and a fault must not overwrite the last complete one."""
    old = rec.get("areas", {})
    out = {"about": __doc__.split("\n\n")[0].replace("\n", " "), "full_run": rec.get("full_run"),
           "areas": {} if full else dict(old)}
    for k, v in run.areas.items():
        if k not in run.raised:
            out["areas"][k] = v
        elif k in old:
            out["areas"][k] = old[k]
    if full:
        walls = [a.get("wall_s", 0) for a in run.areas.values()]
        out["full_run"] = {"date": run.date, "wall_min": round(sum(walls) / 60.0, 1), "load": _num(run.load),
                           "machine": run.machine, "python": run.python, "cpus": run.cpus}
    out["areas"] = {k: out["areas"][k] for k in sorted(out["areas"])}
    return out


def save(rec, path=PATH):
    text = json.dumps(rec, indent=1, allow_nan=False, ensure_ascii=False) + "\n"
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(tmp, path)
