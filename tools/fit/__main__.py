"""Command line: fit coefficients from chamber CSVs, write a readable JSON and the device records.

    python -m tools.fit an12760 DATA.csv --json OUT.json [--order 3] [--t-room 25]
    python -m tools.fit adxrs DATA.csv --json OUT.json
    python -m tools.fit sixpos DATA.csv --json OUT.json --counts-per-g 16384

One unit: the JSON holds the fit's fields and ``record`` (the device's int record); ``--record
FILE`` writes that list alone, ``--store FILE --name NAME`` saves it into a tempcomp.store file.

A fleet: DATA is a directory of per-unit CSVs or one CSV with a ``unit`` column. The JSON is then
``{"units": {unit_id: {the fields of a one-unit fit}}, "summary": {...}}``, ``--record`` writes
``{unit_id: record}``, ``--summary FILE.csv`` the per-unit table (residual, outlier flag, main
coefficients), and the summary is printed. ``--dask ADDRESS`` runs the per-unit fits on a Dask
cluster (docs/fleet.md).

Every record is checked with the device's own code before it is written; the JSON is strict (no
NaN or Infinity). Bad input exits with status 2 and one line naming the file and line; nothing
is written then. Warnings go to stderr.
"""

import sys

from tools import hostio
from tools.fit import fleet
from tools.fit.common import FitError

MAX_WARNINGS = 10


def _check_store(path):
    from tempcomp.store import Store, StoreError

    try:
        st = Store(path)
        st.refresh()
    except (StoreError, ValueError, OSError) as e:
        raise hostio.HostError("--store %s: %s" % (path, e)) from None
    return st


def _save_store(st, name, res):
    from tempcomp.store import StoreError

    try:
        st.save(name, res["record"])
        if "cross_record" in res:
            st.save(name + "_cross", res["cross_record"])
    except (StoreError, ValueError, OSError) as e:
        raise hostio.HostError("--store %s: %s" % (st.path, e)) from None


def _one(args, opts):
    st = _check_store(args.store) if args.store else None
    res = fleet.fit_unit(args.cmd, args.csv, opts)
    outputs = [(args.json, hostio.dumps(res, indent=2))]
    if args.record:
        outputs.append((args.record, hostio.dumps(res["record"])))
    for w in res.get("warnings", []):
        print("warning: %s" % w, file=sys.stderr)
    if st is not None:
        _save_store(st, args.name, res)
    hostio.write_all(outputs)
    return 0


def _fleet(args, opts):
    if args.store:
        raise hostio.HostError("--store saves one unit's record; a fleet's records are in the JSON "
                               "(units.ID.record) and in --record")
    units = fleet.units_of(args.csv, args.cmd)
    show = sys.stderr.isatty() if args.progress is None else args.progress
    progress = fleet.progress_bar(len(units), enabled=show)
    client = None
    if args.dask:
        from distributed import Client

        try:
            client = Client(args.dask, timeout=args.dask_wait)
            client.wait_for_workers(1, timeout=args.dask_wait)
        except (OSError, TimeoutError) as e:
            if client is not None:
                client.close()
            raise hostio.HostError("--dask %s: no scheduler with a worker answered within %g s (%s)"
                                   % (args.dask, args.dask_wait, e)) from None
    try:
        results, failed = fleet.run(args.cmd, units, opts, progress, client)
    finally:
        progress.close()
        if client is not None:
            client.close()
    if failed and not args.skip_bad:
        first = next(iter(failed.values()))
        more = " (%d of %d units failed; --skip-bad fits the others and lists these)" % (len(failed), len(units)) \
            if len(failed) > 1 else ""
        raise hostio.HostError(first + more)
    if not results:
        raise hostio.HostError("%s: no unit could be fitted (first: %s)" % (args.csv, next(iter(failed.values()))))
    summary = fleet.summarise(args.cmd, results, failed, z=args.outlier_z)
    outputs = [(args.json, hostio.dumps({"units": results, "summary": summary}, indent=1))]
    if args.record:
        outputs.append((args.record, hostio.dumps({u: r["record"] for u, r in results.items()})))
    if args.summary:
        outputs.append((args.summary, fleet.table_csv(summary)))
    warned = [(u, w) for u, r in results.items() for w in r.get("warnings", [])]
    for u, w in warned[:MAX_WARNINGS]:
        print("warning: unit %s: %s" % (u, w), file=sys.stderr)
    if len(warned) > MAX_WARNINGS:
        print("warning: %d more warning(s) in the JSON (units.ID.warnings)" % (len(warned) - MAX_WARNINGS),
              file=sys.stderr)
    for u, msg in failed.items():
        print("warning: skipped %s" % msg, file=sys.stderr)
    hostio.write_all(outputs)
    print(fleet.summary_text(summary))
    return 0


def main(argv=None):
    p = hostio.Parser(prog="python -m tools.fit", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)

    def common(sp):
        sp.add_argument("csv", help="chamber data CSV with a header row, or a fleet: a directory of per-unit "
                                    "CSVs or a CSV with a 'unit' column")
        sp.add_argument("--json", required=True, help="write the readable result here")
        sp.add_argument("--record", help="also write the device's coefficient record (JSON list of ints; "
                                         "a fleet: {unit: record})")
        sp.add_argument("--store", help="also save the record(s) into this tempcomp.store file (one unit)")
        sp.add_argument("--name", help="record name in --store (sixpos adds NAME_cross)")
        sp.add_argument("--temp-tol", type=float, default=1.0,
                        help="rows within this many degC belong to one temperature (default 1)")
        f = sp.add_argument_group("fleet (a directory or a CSV with a unit column)")
        f.add_argument("--summary", metavar="CSV", help="write the per-unit summary table here")
        f.add_argument("--outlier-z", type=float, default=5.0,
                       help="flag a unit this many robust sigmas from the fleet's median (default 5)")
        f.add_argument("--skip-bad", action="store_true",
                       help="fit the other units when some fail (listed in the summary) instead of stopping")
        f.add_argument("--progress", action="store_true", default=None, help="progress bar even when "
                                                                              "stderr is not a terminal")
        f.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
        f.add_argument("--dask", metavar="ADDRESS", help="run the per-unit fits on this Dask scheduler "
                                                         "(tcp://host:8786)")
        f.add_argument("--dask-wait", type=float, default=60.0, metavar="S",
                       help="wait this long for the scheduler and a first worker (default 60 s)")

    a = sub.add_parser("an12760", help="Offset/TCO/SENtol/TCS of one axis (NXP AN12760)")
    common(a)
    a.add_argument("--order", type=int, default=1, help="TCO/TCS law order 1..3 (3 needs >= 4 temperatures)")
    a.add_argument("--t-room", type=float, default=25.0, help="reference temperature degC (default 25)")
    a.add_argument("--full-scale-mg", type=float, default=None,
                   help="range limit in mg: readings at it are reported as saturation")

    d = sub.add_parser("adxrs", help="analog gyro null/scale quadratics in VT (ADI three-point)")
    common(d)

    s = sub.add_parser("sixpos", help="six-position / multi-orientation accelerometer fit per temperature")
    common(s)
    s.add_argument("--counts-per-g", type=float, required=True, help="nominal sensitivity (counts per g)")
    s.add_argument("--order", type=int, default=1, help="temperature law order of each coefficient (1..3)")
    s.add_argument("--t-room", type=float, default=25.0)
    s.add_argument("--ellipsoid", action="store_true",
                   help="orientations unknown (9..12 of them): fit an ellipsoid instead of known +-1 g")
    s.add_argument("--raw-min", type=int, default=-32768)
    s.add_argument("--raw-max", type=int, default=32767)

    args = p.parse_args(argv)
    if args.store and not args.name:
        p.error("--store needs --name")
    try:
        opts = fleet.options(args.cmd, order=getattr(args, "order", 1), t_room=getattr(args, "t_room", 25.0),
                             temp_tol=args.temp_tol, full_scale_mg=getattr(args, "full_scale_mg", None),
                             counts_per_g=getattr(args, "counts_per_g", None),
                             ellipsoid=getattr(args, "ellipsoid", False),
                             raw_range=(getattr(args, "raw_min", -32768), getattr(args, "raw_max", 32767)))
        for path, what in ((args.json, "JSON"), (args.record, "record"), (args.summary, "summary")):
            hostio.check_output(path, what)
        if fleet.is_fleet(args.csv):
            return _fleet(args, opts)
        return _one(args, opts)
    except (FitError, hostio.HostError) as e:
        return hostio.fail(e)


if __name__ == "__main__":
    sys.exit(main())
