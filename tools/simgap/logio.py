"""Reading the diagnosis CSV schema (see docs/simgap.md) into arrays.

The reader is strict on purpose: a silently mis-parsed column would show up later as a
"sim-to-real gap" and be blamed on the sensor, so every bad cell is reported by line and column.
"""
import csv
import io
from dataclasses import dataclass, field

import numpy as np

from tools.hostio import HostError, number, read_text

REQUIRED = ("time_s", "temp_c", "out_x", "out_y", "out_z", "ref_x", "ref_y", "ref_z")
OPTIONAL = ("supply_v", "acc_x", "acc_y", "acc_z", "chamber_c", "run")
AXES = ("x", "y", "z")
# no log holds a reading near this (time stamps in s, degC, LSB, mV); squaring such a cell in a
# least-squares fit overflows to inf
LIMIT = 1e12


class LogError(ValueError):
    """A log that cannot be used; the message names the file, line and column."""


@dataclass
class Log:
    name: str
    t: np.ndarray            # s
    temp: np.ndarray         # the part's own temperature reading, degC
    out: np.ndarray          # (N, 3) raw output
    ref: np.ndarray          # (N, 3) true input
    meta: dict = field(default_factory=dict)
    supply: np.ndarray | None = None
    acc: np.ndarray | None = None      # (N, 3) g, seen by a gyro
    chamber: np.ndarray | None = None
    run: np.ndarray | None = None      # int run index 0..R-1 in order of appearance

    def __len__(self):
        return len(self.t)

    @property
    def unit(self):
        return self.meta.get("out_unit", "LSB")

    def subset(self, idx):
        """Rows idx (bool mask or index array) as a new Log, optional columns kept."""
        def pick(a):
            return None if a is None else a[idx]

        return Log(self.name, self.t[idx], self.temp[idx], self.out[idx], self.ref[idx],
                   dict(self.meta), pick(self.supply), pick(self.acc), pick(self.chamber),
                   pick(self.run))


# Line breaks str.splitlines() knows besides "\n": a text without them splits on "\n" alone.
_BREAKS = ("\r", "\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\u2029")


def _head_lines(text):
    """(the lines up to the header - the first neither blank nor '#' -, offset of the body) when
    text breaks lines at "\n" only, so these are exactly splitlines()'s first lines; else None.
    A million-row log then never becomes a million str objects (200 MB) on the fast path."""
    if any(c in text for c in _BREAKS):
        return None
    out, pos = [], 0
    while pos < len(text):
        e = text.find("\n", pos)
        e = len(text) if e < 0 else e
        line = text[pos:e]
        out.append(line)
        pos = e + 1
        if line.strip() and not line.startswith("#"):
            return out, pos
    return None


def _fast_table(header_line, text, start, skip):
    """([header row], [ncols float arrays of N rows]) when the body (text from offset start, the
    line after header_line; `skip` lines of text come before it) is plain numbers that the
    strict parser would accept unchanged, else None (then the strict parser runs and names the
    first bad cell). pandas' C reader parses a million-row log in about a second (numpy's
    fromstring took 6 s) to the same doubles as float() (round-trip exact); a line with more
    fields than the first is a ParserError, one with fewer gets NaN, and either sends the log
    to the strict parser."""
    end = len(text)
    while end > start and text[end - 1].isspace():     # trailing blank lines are tolerated
        end -= 1
    nrows = text.count("\n", start, end) + 1 if end > start else 0
    if nrows < 10 or '"' in header_line or text.find('"', start, end) >= 0:
        return None
    header = next(csv.reader([header_line]))
    ncols = len(header)
    if text.count(",", start, end) != (ncols - 1) * nrows or text.find("\n\n", start, end) >= 0:
        return None
    import pandas as pd  # lazily: only the fast path needs it

    try:
        # bytes, not a StringIO: that holds the text again at up to 4 bytes a character
        df = pd.read_csv(io.BytesIO(text.encode()), header=None, skiprows=skip, nrows=nrows,
                         dtype=float, na_filter=False, skip_blank_lines=False,
                         quoting=csv.QUOTE_NONE, engine="c")
    except (ValueError, OverflowError):
        return None
    if df.shape != (nrows, ncols):
        return None
    # column by column: the frame's to_numpy() would interleave a copy of the whole table
    cols = [np.asarray(df[j].to_numpy(), float) for j in range(ncols)]
    if not all(np.all(np.isfinite(c)) and not np.any(np.abs(c) >= LIMIT) for c in cols):
        return None
    return [header], cols


def read_log(path, text=None):
    """Read a log file (or `text` if given, `path` then only names it in errors)."""
    name = str(path)
    if text is None:
        try:
            text = read_text(path)
        except HostError as e:
            raise LogError(str(e)) from None
    head = _head_lines(text)
    lines = head[0] if head else text.splitlines()
    meta = {}
    lineno = 0
    # Metadata lines come before the header; blank lines there are tolerated.
    while lineno < len(lines) and (lines[lineno].startswith("#") or not lines[lineno].strip()):
        line = lines[lineno].lstrip("#").strip()
        lineno += 1
        if not line:
            continue
        if ":" not in line:
            raise LogError(f"{name}: line {lineno}: metadata must be '# key: value', got {line!r}")
        k, v = line.split(":", 1)
        meta[k.strip()] = v.strip()
    if lineno >= len(lines):
        raise LogError(f"{name}: no header line (expected columns {', '.join(REQUIRED)})")
    header_line = lineno + 1
    if head:
        fast = _fast_table(lines[lineno], text, head[1], lineno + 1)
        if not fast:
            lines = text.splitlines()   # the strict parser's lines (the same first ones)
    else:
        fast = _fast_table(lines[lineno], "\n".join(lines[lineno + 1:]), 0, 0)
    rows = fast[0] if fast else list(csv.reader(io.StringIO("\n".join(lines[lineno:]))))
    header = [h.strip() for h in rows[0]]
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise LogError(f"{name}: line {header_line}: header lacks required column(s) "
                       f"{', '.join(missing)}")
    dup = sorted({h for h in header if header.count(h) > 1 and h in REQUIRED + OPTIONAL})
    if dup:
        raise LogError(f"{name}: line {header_line}: column(s) {', '.join(dup)} appear twice")
    wanted = [c for c in REQUIRED + OPTIONAL if c in header]
    col = {c: header.index(c) for c in wanted}
    data = {c: [] for c in wanted}
    if fast:
        # Every cell parsed as a finite number within LIMIT and every line has the header's
        # field count: the strict loop below would accept it all, so skip it.
        data = {c: fast[1][col[c]] for c in wanted}
    for i, row in enumerate(rows[1:] if not fast else ()):
        ln = header_line + 1 + i
        if not row or (len(row) == 1 and not row[0].strip()):
            continue  # a trailing blank line is not an error
        if len(row) != len(header):
            raise LogError(f"{name}: line {ln}: {len(row)} fields, header has {len(header)}")
        for c in wanted:
            cell = row[col[c]].strip()
            try:
                v = number(cell)
            except ValueError:
                raise LogError(f"{name}: line {ln}, column {col[c] + 1} ({c}): "
                               f"not a number: {cell!r}") from None
            if not np.isfinite(v):
                raise LogError(f"{name}: line {ln}, column {col[c] + 1} ({c}): "
                               f"not a finite number: {cell!r}")
            if abs(v) >= LIMIT:
                raise LogError(f"{name}: line {ln}, column {col[c] + 1} ({c}): "
                               f"{cell} is beyond any logged reading (|value| < {LIMIT:g}); a typo?")
            data[c].append(v)
    n = len(data["time_s"])
    if n < 10:
        raise LogError(f"{name}: only {n} data rows; at least 10 are needed")
    arr = {c: np.asarray(v, dtype=float) for c, v in data.items()}
    t = arr["time_s"]
    back = np.flatnonzero(np.diff(t) < 0)
    if "run" not in arr and back.size:
        k = back[0] + 1
        raise LogError(f"{name}: line {header_line + 1 + k}, column {col['time_s'] + 1} "
                       f"(time_s): time goes backwards (give a 'run' column if the file "
                       f"holds several runs)")
    def stack(cs):
        return np.column_stack([arr[c] for c in cs])

    acc_cols = ("acc_x", "acc_y", "acc_z")
    have_acc = [c in arr for c in acc_cols]
    if any(have_acc) and not all(have_acc):
        raise LogError(f"{name}: line {header_line}: acc_x, acc_y, acc_z must come together")
    run = None
    if "run" in arr:
        # Runs are numbered in order of appearance so withheld logs never share ids by accident.
        _, first, inv = np.unique(arr["run"], return_index=True, return_inverse=True)
        order = np.argsort(np.argsort(first))
        run = order[inv].astype(int)
    return Log(name=name, t=t, temp=arr["temp_c"], out=stack(("out_x", "out_y", "out_z")),
               ref=stack(("ref_x", "ref_y", "ref_z")), meta=meta,
               supply=arr.get("supply_v"), acc=stack(acc_cols) if all(have_acc) else None,
               chamber=arr.get("chamber_c"), run=run)


def write_log(path, log_cols, meta=None):
    """Write columns {name: 1-D array} as a diagnosis CSV (used by the converter and the
    benchmark generator, which must produce exactly what read_log accepts)."""
    names = list(log_cols)
    n = len(log_cols[names[0]])
    with open(path, "w", newline="") as f:
        for k, v in (meta or {}).items():
            f.write(f"# {k}: {v}\n")
        f.write(",".join(names) + "\n")
        cols = [np.asarray(log_cols[c]) for c in names]
        for i in range(n):
            f.write(",".join(_fmt(c[i]) for c in cols) + "\n")


def _fmt(v):
    if float(v).is_integer() and abs(v) < 1e15:
        return str(int(v))
    return f"{float(v):.9g}"
