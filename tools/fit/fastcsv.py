"""Chamber CSVs into columns, fast enough for a fleet (millions of rows), with errors naming file and line.

The common file (no quoting, one comma per cell boundary) is split in bulk and its numeric
columns converted by numpy in one call each; a file with quotes goes through the csv module.
Whatever the path, a problem is a FitError naming the file, the line (header = line 1) and the
column, the same message the slow path gives, because a failed bulk conversion is redone cell by
cell only to find the culprit.
"""

import csv
import io
import math

import numpy as np

from tools.fit.common import FitError
from tools.hostio import HostError, number, read_text

# no chamber reading comes near this: a cell beyond it is a typo or garbage, and squaring it
# in a least-squares fit would overflow to inf
LIMIT = 1e12


def read_table(path, required, optional=(), text_cols=(), text=None):
    """{column: values} of a CSV with a header: numeric columns float64 arrays, text columns lists
    of stripped str; ``_line`` is each row's line number. ``text`` (when given) is the file's
    content, ``path`` then only names it."""
    if text is None:
        try:
            text = read_text(path)
        except HostError as e:
            raise FitError(str(e)) from None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise FitError("%s is empty: expected a header line with columns %s" % (path, ",".join(required)))
    quoted = '"' in text
    if quoted:
        try:
            rows = list(csv.reader(io.StringIO(text)))
        except csv.Error as e:
            raise FitError("%s: not a readable CSV: %s" % (path, e)) from None
        header = [h.strip() for h in rows[0]]
        body = rows[1:]
        nums = list(range(2, len(body) + 2)) if len(rows) == len(lines) else None
        if nums is None:  # quoted newlines: line numbers from the reader
            nums = []
            r = csv.reader(io.StringIO(text))
            next(r)
            for _ in r:
                nums.append(r.line_num)
    else:
        header = [h.strip() for h in lines[0].split(",")]
        body = [ln.split(",") for ln in lines[1:]]
        nums = range(2, len(body) + 2)
    missing = [c for c in required if c not in header]
    if missing:
        raise FitError("%s line 1: missing column(s) %s; the header is %s (need %s)"
                       % (path, ",".join(missing), ",".join(header) or "empty", ",".join(required)))
    dup = sorted({c for c in header if c and header.count(c) > 1 and (c in required or c in optional)})
    if dup:
        raise FitError("%s line 1: column(s) %s appear twice" % (path, ",".join(dup)))
    keep = [i for i, r in enumerate(body) if any(x.strip() for x in r)]
    if len(keep) != len(body):
        body = [body[i] for i in keep]
        nums = [nums[i] for i in keep]
    if not body:
        raise FitError("%s has a header but no data rows" % path)
    lines_arr = np.asarray(nums, dtype=np.int64)
    width = len(header)
    short = [k for k, r in enumerate(body) if len(r) < width]
    if short:
        k = short[0]
        raise FitError("%s line %d: %d cells, the header has %d (a truncated line or a deleted cell?)"
                       % (path, lines_arr[k], len(body[k]), width))
    wanted = list(required) + [c for c in optional if c in header and c not in required]
    # float() reads '124_956' as 124956 (Python's digit grouping): in a log that is a damaged
    # '124.956'; one search of the body decides whether the cells need the per-cell check
    grouped = "_" in text[len(lines[0]):]
    out = {"_line": lines_arr}
    for name in wanted:
        j = header.index(name)
        cells = [r[j] for r in body]
        if name in text_cols:
            out[name] = [c.strip() for c in cells]
        else:
            out[name] = to_numbers(cells, name, lines_arr, path, grouped)
    return out


def to_numbers(cells, name, lines, path, grouped=True):
    """float64 array of cells; FitError naming the first cell that is not a finite, sane number
    (a cell with an underscore is not one; ``grouped=False``: the caller knows none has one)."""
    try:
        arr = np.array(cells, dtype=np.float64)
    except (ValueError, OverflowError):
        arr = None
    if arr is not None and grouped and any("_" in c for c in cells):
        arr = None
    if arr is not None:
        bad = ~(np.abs(arr) < LIMIT)  # NaN, inf and absurd magnitudes
        if not bad.any():
            return arr
        k = int(np.argmax(bad))
    else:
        k = next(i for i, s in enumerate(cells) if not _number(s))
    s = cells[k].strip()
    try:
        v = number(s)
    except ValueError:
        raise FitError("%s line %d: column %s is %r, not a number" % (path, lines[k], name, s)) from None
    if not math.isfinite(v):
        raise FitError("%s line %d: column %s is %s; remove or re-measure that row" % (path, lines[k], name, s))
    raise FitError("%s line %d: column %s is %s, beyond any sensor reading (|value| < %g); a typo?"
                   % (path, lines[k], name, s, LIMIT))


def _number(s):
    try:
        v = number(s)
    except ValueError:
        return False
    return abs(v) < LIMIT
