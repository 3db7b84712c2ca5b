"""The figure tables of README.md and docs/, rendered from `make bench`'s record (docs/bench.json).

A page holds each table between two markers::

    <!-- figures: NAME -->
    ...the table, as rendered...
    <!-- /figures -->

and BLOCKS below holds its template: text with ``{area.key}`` fields, each a figure of the record
(``{core.apply_ratio:.2f}``; ``:kb`` for bytes as KB with one decimal, ``:k`` for thousands as
"31k", ``:,`` for thousands separators), ``{area.date}`` the date that area was measured. So what
a page shows is what a run printed: ``python -m tools bench [AREA]`` measures, writes the record
and renders the pages; ``python -m tools bench --docs`` renders them again (after editing a
template); host_tests/docs/test_figures.py fails when a page's table is not the record's.
To add a table: give the figures a key (``report(..., key=)``), write the template here, put the
markers on the page and run ``python -m tools bench --docs``.
"""

import os
import re

from tools import REPO

BEGIN = re.compile(r"^<!-- figures: ([\w.-]+) -->$", re.M)
END = "<!-- /figures -->"


class Figure:
    """One recorded figure, formatted by the template's spec."""

    def __init__(self, area, key, row):
        self.where = "%s.%s" % (area, key)
        self.value = row["value"]
        self.row = row

    def __format__(self, spec):
        v = self.value
        if v is None:
            return "n/a"
        if spec == "kb":
            return "%.1f" % (v / 1024.0)
        if spec == "k":
            return "%dk" % int(round(v / 1000.0))
        if spec == "x":  # a ratio: two decimals below 10, one below 100, none above
            return "%.2f" % v if v < 10 else "%.1f" % v if v < 100 else "%.0f" % v
        return format(v, spec)

    def __str__(self):
        return self.__format__("")


class Area:
    def __init__(self, name, entry):
        self._name = name
        self._entry = entry

    def __getattr__(self, key):
        if key.startswith("_"):
            raise AttributeError(key)
        rows = self._entry.get("rows", {})
        if key in rows:
            return Figure(self._name, key, rows[key])
        if key in self._entry and key != "rows":
            return self._entry[key]
        raise Missing("%s.%s" % (self._name, key))


class Missing(KeyError):
    """A figure the template needs and the record lacks (run that area)."""


class Record(dict):
    def __init__(self, rec):
        super().__init__()
        self.rec = rec

    def __missing__(self, area):
        if area == "run":
            return self.rec.get("full_run") or {}
        if area not in self.rec.get("areas", {}):
            raise Missing("%s (the whole area)" % area)
        return Area(area, self.rec["areas"][area])


# (page, block name) -> template (a str for str.format_map, or a function of the record)
BLOCKS = {}


def render(template, rec):
    if callable(template):
        return template(Record(rec))
    return template.format_map(Record(rec))


def blocks(text):
    """{name: (start, end) of the rendered text between the markers} of a page."""
    out = {}
    for m in BEGIN.finditer(text):
        end = text.find("\n" + END, m.end())
        if end < 0:
            raise ValueError("figures block %r has no %s" % (m.group(1), END))
        out[m.group(1)] = (m.end() + 1, end + 1)
    return out


def pages():
    return sorted({page for page, _ in BLOCKS})


def rendered(page, rec, strict=True):
    """The page's text with every block rendered from rec (a block whose figures the record
    lacks is left as it is unless strict)."""
    path = os.path.join(REPO, page)
    with open(path, encoding="utf-8") as f:
        text = f.read()
    found = blocks(text)
    for (p, name), template in BLOCKS.items():
        if p == page and name not in found:
            raise ValueError("%s has no figures block %r (its markers)" % (page, name))
    for name in sorted(found, key=lambda n: -found[n][0]):  # from the end: offsets stay valid
        if (page, name) not in BLOCKS:
            raise ValueError("%s: figures block %r has no template in tools/bench/figures.py" % (page, name))
        try:
            body = render(BLOCKS[(page, name)], rec).rstrip("\n") + "\n"
        except Missing:
            if strict:
                raise
            continue
        a, b = found[name]
        text = text[:a] + body + text[b:]
    return text


def write_pages(rec, strict=True):
    """Render every block of every page from rec; the pages that changed."""
    changed = []
    for page in pages():
        text = rendered(page, rec, strict)
        path = os.path.join(REPO, page)
        with open(path, encoding="utf-8") as f:
            old = f.read()
        if text != old:
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
            changed.append(page)
    return changed


def missing(rec):
    """'page: block (figure)' for each block the record cannot render yet."""
    out = []
    for (page, name), template in sorted(BLOCKS.items()):
        try:
            render(template, rec)
        except Missing as e:
            out.append("%s: %s (%s)" % (page, name, e.args[0]))
    return out
