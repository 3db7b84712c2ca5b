"""Command line: fit coefficients from a chamber CSV, write a readable JSON and the device record.

    python -m tools.fit an12760 DATA.csv --json OUT.json [--order 3] [--t-room 25]
    python -m tools.fit adxrs DATA.csv --json OUT.json
    python -m tools.fit sixpos DATA.csv --json OUT.json --counts-per-g 16384

Every subcommand also takes ``--record FILE`` (the device's int record as a JSON list). Data
problems exit with status 2 and a message naming the row/temperature at fault; warnings go
to stderr.
"""

import argparse
import json
import sys

from tools.fit.common import FitError


def _an12760(args):
    from tempcomp import record
    from tools.fit import an12760
    from tools.fit.common import numeric, read_csv

    cols = read_csv(args.csv, ["temp_c", "ref_g", "out_mg"])
    T = numeric(cols, "temp_c", args.csv)
    g = numeric(cols, "ref_g", args.csv)
    y = numeric(cols, "out_mg", args.csv)
    res = an12760.fit(T, g, y, order=args.order, t_room=args.t_room, temp_tol=args.temp_tol,
                      full_scale_mg=args.full_scale_mg, lines=cols["_line"])
    off, tco, sen, tcs = an12760.axis_tuple(res)
    t = res["temperatures_c"]
    vals = [res["t_room_c"], t[0], t[-1], 1.0, off] + (tco + [0.0] * 3)[:3] + [sen] + (tcs + [0.0] * 3)[:3]
    return res, record.pack(record.KIND_AN12760, vals)


def _adxrs(args):
    from tools.fit import adxrs

    res = adxrs.fit_csv(args.csv, temp_tol=args.temp_tol)
    return res, adxrs.record_ints(res)


def _sixpos(args):
    from tools.fit import sixpos

    res = sixpos.fit_csv(args.csv, counts_per_g=args.counts_per_g, order=args.order, t_room=args.t_room,
                         ellipsoid=args.ellipsoid, raw_range=(args.raw_min, args.raw_max),
                         temp_tol=args.temp_tol)
    return res, sixpos.record_ints(res)


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m tools.fit", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)

    def common(sp):
        sp.add_argument("csv", help="chamber data CSV with a header row")
        sp.add_argument("--json", required=True, help="write the readable result here")
        sp.add_argument("--record", help="also write the device's coefficient record (JSON list of ints)")
        sp.add_argument("--store", help="also save the record(s) into this tempcomp.store file")
        sp.add_argument("--name", help="record name in --store (sixpos adds NAME_cross)")
        sp.add_argument("--temp-tol", type=float, default=1.0,
                        help="rows within this many degC belong to one temperature (default 1)")

    a = sub.add_parser("an12760", help="Offset/TCO/SENtol/TCS of one axis (NXP AN12760)")
    common(a)
    a.add_argument("--order", type=int, default=1, help="TCO/TCS law order 1..3 (3 needs >= 4 temperatures)")
    a.add_argument("--t-room", type=float, default=25.0, help="reference temperature degC (default 25)")
    a.add_argument("--full-scale-mg", type=float, default=None,
                   help="range limit in mg: readings at it are reported as saturation")
    a.set_defaults(run=_an12760)

    d = sub.add_parser("adxrs", help="analog gyro null/scale quadratics in VT (ADI three-point)")
    common(d)
    d.set_defaults(run=_adxrs)

    s = sub.add_parser("sixpos", help="six-position / multi-orientation accelerometer fit per temperature")
    common(s)
    s.add_argument("--counts-per-g", type=float, required=True, help="nominal sensitivity (counts per g)")
    s.add_argument("--order", type=int, default=1, help="temperature law order of each coefficient (1..3)")
    s.add_argument("--t-room", type=float, default=25.0)
    s.add_argument("--ellipsoid", action="store_true",
                   help="orientations unknown (9..12 of them): fit an ellipsoid instead of known +-1 g")
    s.add_argument("--raw-min", type=int, default=-32768)
    s.add_argument("--raw-max", type=int, default=32767)
    s.set_defaults(run=_sixpos)

    args = p.parse_args(argv)
    if args.store and not args.name:
        p.error("--store needs --name")
    try:
        res, ints = args.run(args)
    except FitError as e:
        print("error: %s" % e, file=sys.stderr)
        return 2
    except OSError as e:
        print("error: %s" % e, file=sys.stderr)
        return 2
    for w in res.get("warnings", []):
        print("warning: %s" % w, file=sys.stderr)
    res["record"] = ints
    with open(args.json, "w") as f:
        json.dump(res, f, indent=2)
        f.write("\n")
    if args.record:
        with open(args.record, "w") as f:
            json.dump(ints, f)
            f.write("\n")
    if args.store:
        try:
            from tempcomp.store import Store
        except ImportError:
            print("error: --store needs tempcomp.store, which this checkout does not have yet; "
                  "use --record and load the JSON list on the board", file=sys.stderr)
            return 2
        st = Store(args.store)
        st.save(args.name, ints)
        if "cross_record" in res:
            st.save(args.name + "_cross", res["cross_record"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
