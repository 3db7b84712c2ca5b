"""Fitting a production line: many units in one run, one coefficient record per unit, a summary.

The input is a directory of per-unit CSVs (the unit id is the file name without ``.csv``) or
one CSV with a ``unit`` column. ``fit_unit`` is the per-unit function: it takes one unit's data
(a path, or the unit's columns) and plain options, returns the same fields a one-unit
``python -m tools fit`` writes, record included, and checks that record with the device's own
code (``tempcomp.an12760`` / ``adxrs`` / ``crossaxis``) before anyone can store it. It has no
state and pickles, so the same function runs unchanged under a distributed engine::

    from distributed import Client
    from tools.fit import fleet
    client = Client("tcp://scheduler:8786")           # or LocalCluster()
    units = fleet.units_of("line7/", "sixpos")        # [(unit_id, source)]
    futs = client.map(fleet.fit_unit_safe, ["sixpos"] * len(units), [s for _, s in units],
                      [opts] * len(units), [u for u, _ in units])

``run`` is the one-machine loop (with a progress bar) and the ``--dask`` path of the command
line; ``summarise`` builds the table: per-unit residual, outlier units flagged by a robust
z-score (median and MAD over the fleet) of the residual and of the main coefficients.
"""

import os
import sys

import numpy as np

from tools.fit.common import FitError

# per subcommand: required columns, optional columns, text columns
COLUMNS = {
    "an12760": (("temp_c", "ref_g", "out_mg"), (), ()),
    "adxrs": (("temp_c", "vt_mv", "rate_dps", "out_mv"), (), ()),
    "sixpos": (("temp_c", "orient", "ax", "ay", "az"), ("gx", "gy", "gz"), ("orient",)),
}
UNIT = "unit"


def options(cmd, order=1, t_room=25.0, temp_tol=1.0, full_scale_mg=None, counts_per_g=None,
            ellipsoid=False, raw_range=(-32768, 32767)):
    """The plain (picklable) options dict fit_unit takes."""
    if cmd not in COLUMNS:
        raise FitError("unknown fit %r (one of %s)" % (cmd, ", ".join(COLUMNS)))
    if cmd == "sixpos" and not (counts_per_g is not None and np.isfinite(counts_per_g) and counts_per_g > 0):
        raise FitError("--counts-per-g must be a positive number of counts per g, got %r" % (counts_per_g,))
    if order not in (1, 2, 3):
        raise FitError("--order must be 1, 2 or 3 (a temperature law of that order), got %r" % (order,))
    if raw_range[0] >= raw_range[1]:
        raise FitError("--raw-min %d must be below --raw-max %d (the part's output range)" % tuple(raw_range))
    if not (np.isfinite(temp_tol) and temp_tol > 0):
        raise FitError("--temp-tol must be a positive number of degC, got %r" % (temp_tol,))
    if not np.isfinite(t_room):
        raise FitError("--t-room must be a finite temperature, got %r" % (t_room,))
    return {"order": int(order), "t_room": float(t_room), "temp_tol": float(temp_tol),
            "full_scale_mg": full_scale_mg, "counts_per_g": counts_per_g, "ellipsoid": bool(ellipsoid),
            "raw_range": tuple(raw_range)}


def read_unit(cmd, path):
    """One unit's columns from its own CSV."""
    from tools.fit.fastcsv import read_table

    req, opt, txt = COLUMNS[cmd]
    return read_table(path, req, opt, txt)


def fit_unit(cmd, source, opts, name=None):
    """Fit one unit: source is a CSV path or the unit's columns; the one-unit result with "record".

    FitError (message naming the file and line where it can) when the data cannot support the
    fit or the device would refuse the record.
    """
    from tempcomp import record

    label = name or (source if isinstance(source, str) else "unit")
    cols = read_unit(cmd, source) if isinstance(source, str) else source
    try:
        if cmd == "an12760":
            from tools.fit import an12760

            res = an12760.fit(cols["temp_c"], cols["ref_g"], cols["out_mg"], order=opts["order"],
                              t_room=opts["t_room"], temp_tol=opts["temp_tol"],
                              full_scale_mg=opts["full_scale_mg"], lines=cols["_line"])
            off, tco, sen, tcs = an12760.axis_tuple(res)
            t = res["temperatures_c"]
            vals = [res["t_room_c"], t[0], t[-1], 1.0, off] + (tco + [0.0] * 3)[:3] + [sen] + (tcs + [0.0] * 3)[:3]
            res["record"] = record.pack(record.KIND_AN12760, vals)
        elif cmd == "adxrs":
            from tools.fit import adxrs

            res = adxrs.fit_table(cols, temp_tol=opts["temp_tol"])
            res["record"] = adxrs.record_ints(res)
        else:
            from tools.fit import sixpos

            res = sixpos.fit_table(cols, label, opts["counts_per_g"], order=opts["order"], t_room=opts["t_room"],
                                   ellipsoid=opts["ellipsoid"], raw_range=opts["raw_range"],
                                   temp_tol=opts["temp_tol"])
            res["record"] = sixpos.record_ints(res)
    except FitError as e:
        raise FitError(_named(label, e)) from None
    except ValueError as e:  # numbers the record cannot hold (tempcomp.record refuses them)
        raise FitError("%s: %s" % (label, e)) from None
    device_check(cmd, res, opts, label)
    return res


def _named(label, e):
    msg = str(e)
    return msg if msg.startswith(label) else "%s: %s" % (label, msg)


class _ADC:
    """A constant ADC channel: the device check needs channels, never reads them."""

    def read_u16(self):
        return 32768


def device_check(cmd, res, opts, label="unit"):
    """Build the device's compensator from the record, as the board will: FitError if it refuses."""
    from tempcomp.an12760 import AN12760

    try:
        if cmd == "an12760":
            AN12760.from_record(res["record"], 1000.0)  # out_mg: one count per mg
        elif cmd == "sixpos":
            from tempcomp.crossaxis import CrossAxis

            AN12760.from_record(res["record"], opts["counts_per_g"])
            CrossAxis.from_record(res["cross_record"])
        else:
            from tempcomp.adxrs import AnalogGyro

            # the usual wiring: a 5 V gyro read by a 3.3 V ADC through a 2:1 divider
            AnalogGyro(_ADC(), _ADC(), vref_mv=3300, divider=2.0).load_record(res["record"])
    except ValueError as e:
        raise FitError("%s: the device would refuse this record: %s" % (label, e)) from None


def fit_unit_safe(cmd, source, opts, name=None):
    """fit_unit that returns ("ok", result) or ("error", message) instead of raising (for map())."""
    try:
        return "ok", fit_unit(cmd, source, opts, name)
    except FitError as e:
        return "error", str(e)


# -- the fleet's units ------------------------------------------------------------------------

def is_fleet(path):
    """True when path is a directory or a CSV whose header has a ``unit`` column."""
    if os.path.isdir(path):
        return True
    try:
        with open(path, "rb") as f:
            head = f.readline(65536)
    except OSError:
        return False
    head = head.lstrip(b"\xef\xbb\xbf").decode("utf-8", "replace")
    return UNIT in [c.strip().strip('"') for c in head.split(",")]


def units_of(path, cmd):
    """[(unit_id, source)]: a directory's ``*.csv`` (source = its path) or one CSV split by ``unit``."""
    if os.path.isdir(path):
        try:
            names = sorted(n for n in os.listdir(path) if n.lower().endswith(".csv"))
        except OSError as e:
            raise FitError("%s: cannot list the directory: %s" % (path, e.strerror)) from None
        if not names:
            raise FitError("%s: no *.csv files in the directory (one CSV per unit)" % path)
        return [(n[:-4], os.path.join(path, n)) for n in names]
    from tools.fit.fastcsv import read_table

    req, opt, txt = COLUMNS[cmd]
    cols = read_table(path, req + (UNIT,), opt, txt + (UNIT,))
    ids = np.array(cols[UNIT], dtype=object)
    empty = np.flatnonzero(ids == "")
    if empty.size:
        raise FitError("%s line %d: the unit cell is empty" % (path, cols["_line"][empty[0]]))
    ids = ids.astype(str)
    uniq, first, inv = np.unique(ids, return_index=True, return_inverse=True)
    order = np.argsort(inv, kind="stable")
    bounds = np.concatenate(([0], np.cumsum(np.bincount(inv, minlength=len(uniq)))))
    out = []
    for k in np.argsort(first):  # units in order of first appearance
        rows = order[bounds[k]:bounds[k + 1]]
        unit = {}
        for c, v in cols.items():
            if c == UNIT:
                continue
            unit[c] = [v[i] for i in rows] if isinstance(v, list) else v[rows]
        unit["_file"] = path
        out.append((str(uniq[k]), unit))
    return out


def progress_bar(total, enabled=True):
    """The fleet's progress bar on stderr: tqdm, with its rate and time left; ``update(1)`` per
    unit, ``close()`` at the end. ``python -m tools fit`` shows it on a terminal (``--progress``
    forces it into a pipe or log)."""
    from tqdm import tqdm

    return tqdm(total=total, unit="unit", disable=not enabled or total <= 0, file=sys.stderr, mininterval=0.2,
                dynamic_ncols=True)


def run(cmd, units, opts, progress=None, client=None):
    """Fit every (unit_id, source); ({unit_id: result}, {unit_id: error message}).

    client: a ``distributed.Client`` to run fit_unit on its workers, else one process here.
    progress: a bar (``progress_bar``) told of each unit done.
    """
    results = {}
    failed = {}
    if client is None:
        for uid, src in units:
            status, val = fit_unit_safe(cmd, src, opts, _label(uid, src))
            (results if status == "ok" else failed)[uid] = val
            if progress is not None:
                progress.update(1)
        return results, failed
    from distributed import as_completed

    futs = client.map(fit_unit_safe, [cmd] * len(units), [s for _, s in units], [opts] * len(units),
                      [_label(u, s) for u, s in units], pure=False)
    ids = {f.key: u for f, (u, _) in zip(futs, units)}
    for fut in as_completed(futs):
        status, val = fut.result()
        (results if status == "ok" else failed)[ids[fut.key]] = val
        if progress is not None:
            progress.update(1)
    order = [u for u, _ in units]
    return {u: results[u] for u in order if u in results}, {u: failed[u] for u in order if u in failed}


def _label(uid, src):
    if isinstance(src, str):
        return src
    return "%s unit %s" % (src["_file"], uid) if "_file" in src else "unit %s" % uid


# -- the summary --------------------------------------------------------------------------------

def unit_metrics(cmd, res):
    """(residual, {coefficient: value}) of one unit: what the summary compares across the fleet."""
    if cmd == "an12760":
        resid = max(r["rms_mg"] for r in res["residuals"])
        coeffs = {"offset_mg": res["offset_mg"], "tco_mg_per_c": res["tco_mg_per_c"], "sen_tol": res["sen_tol"],
                  "tcs_per_c": res["tcs_per_c"]}
    elif cmd == "adxrs":
        resid = max(abs(p["null_error_dps"]) for p in res["points"])
        coeffs = {"v0_mv": res["v0_mv"][0], "s_mv_per_dps": res["s_mv_per_dps"][0]}
    else:
        resid = max(max(t["residual_rms_mg"]) for t in res["temperatures"])
        coeffs = {}
        for ax in res["axes"]:
            coeffs["offset_mg_" + ax["axis"]] = ax["offset_mg"]
            coeffs["sen_tol_" + ax["axis"]] = ax["sen_tol"]
    return float(resid), coeffs


RESIDUAL = {"an12760": "worst per-temperature rms residual (mg)",
            "adxrs": "worst null error at a calibration temperature (dps)",
            "sixpos": "worst per-temperature, per-axis rms residual (mg)"}
MIN_UNITS = 5  # below this a median/MAD says nothing about what is typical


def _robust_z(x):
    med = float(np.median(x))
    mad = float(np.median(np.abs(x - med))) * 1.4826
    if mad == 0.0:
        mad = max(1e-12, 1e-9 * abs(med))
    return (x - med) / mad, med, mad


def summarise(cmd, results, failed, z=5.0):
    """Summary dict: per-unit residual and flags, outlier units, the criteria, failed units."""
    ids = list(results)
    n = len(ids)
    table = []
    resid = np.empty(n)
    coeffs = {}
    for i, u in enumerate(ids):
        r, c = unit_metrics(cmd, results[u])
        resid[i] = r
        for k, v in c.items():
            coeffs.setdefault(k, np.empty(n))[i] = v
    flags = [[] for _ in ids]
    stats = {}
    if n >= MIN_UNITS:
        # residuals are positive and skewed (a worst rms): compared on a log scale
        zr, med, mad = _robust_z(np.log(np.maximum(resid, 1e-300)))
        stats["residual"] = {"median": float(np.exp(med)), "scaled_mad_log": mad}
        for i in np.flatnonzero(zr > z):
            flags[i].append("residual %.3g is %.1fx the fleet's median %.3g (%.1f robust sigma on a log scale)"
                            % (resid[i], resid[i] / np.exp(med), np.exp(med), zr[i]))
        for k, x in coeffs.items():
            zk, med, mad = _robust_z(x)
            stats[k] = {"median": med, "scaled_mad": mad}
            for i in np.flatnonzero(np.abs(zk) > z):
                flags[i].append("%s %.4g is %.1f robust sigma from the fleet's median %.4g" % (k, x[i], zk[i], med))
    for i, u in enumerate(ids):
        row = {"unit": u, "residual": float(resid[i]), "outlier": bool(flags[i])}
        for k, x in coeffs.items():
            row[k] = float(x[i])
        if flags[i]:
            row["why"] = flags[i]
        table.append(row)
    note = None
    if n < MIN_UNITS:
        note = ("%d unit(s): too few to say what is typical, no outlier flagged (needs %d or more)"
                % (n, MIN_UNITS))
    return {
        "fit": cmd,
        "units": n,
        "failed": dict(failed),
        "residual": RESIDUAL[cmd],
        "outlier_rule": "|x - median| > %g x 1.4826 MAD over the fleet, for log(residual) (upper side) and "
                        "for each of %s" % (z, ", ".join(coeffs) or "the coefficients"),
        "outliers": [r["unit"] for r in table if r["outlier"]],
        "stats": stats,
        "note": note,
        "table": table,
    }


def summary_text(s, max_rows=20):
    """The summary as a short text table (every outlier and failed unit, then counts)."""
    lines = ["%s fleet: %d unit(s) fitted, %d failed, %d outlier(s); residual = %s"
             % (s["fit"], s["units"], len(s["failed"]), len(s["outliers"]), s["residual"])]
    if s["note"]:
        lines.append("  " + s["note"])
    if "residual" in s["stats"]:
        st = s["stats"]["residual"]
        lines.append("  residual: median %.4g, spread (scaled MAD of its log) %.3g" % (st["median"], st["scaled_mad_log"]))
    shown = [r for r in s["table"] if r["outlier"]]
    for r in shown[:max_rows]:
        lines.append("  OUTLIER %-16s residual %-10.4g %s" % (r["unit"], r["residual"], "; ".join(r["why"])))
    if len(shown) > max_rows:
        lines.append("  ... %d more outlier(s) in the JSON summary" % (len(shown) - max_rows))
    for u, msg in list(s["failed"].items())[:max_rows]:
        lines.append("  FAILED  %-16s %s" % (u, msg))
    if len(s["failed"]) > max_rows:
        lines.append("  ... %d more failed unit(s) in the JSON summary" % (len(s["failed"]) - max_rows))
    return "\n".join(lines)


def table_csv(s):
    """The summary table as CSV text (one row per fitted unit, then the failed ones)."""
    keys = [k for k in (s["table"][0] if s["table"] else {}) if k not in ("unit", "residual", "outlier", "why")]
    out = [",".join(["unit", "status", "residual"] + keys + ["why"])]
    for r in s["table"]:
        why = "; ".join(r.get("why", [])).replace('"', "'")
        out.append(",".join([_cell(r["unit"]), "outlier" if r["outlier"] else "ok", "%.6g" % r["residual"]]
                            + ["%.8g" % r[k] for k in keys] + ['"%s"' % why]))
    for u, msg in s["failed"].items():
        out.append(",".join([_cell(u), "failed", ""] + [""] * len(keys) + ['"%s"' % msg.replace('"', "'")]))
    return "\n".join(out) + "\n"


def _cell(s):
    return '"%s"' % s.replace('"', "'") if ("," in s or '"' in s) else s
