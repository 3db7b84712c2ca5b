"""python -m tools.simgap TRAIN.csv [--withheld W.csv] [--model M.json] --json OUT.json [--plot OUT.png]"""
import io
import json
import sys

import numpy as np

from tools import hostio

from .diagnose import diagnose
from .logio import LIMIT, LogError, read_log
from .model import FixedModel
from .report import plot, text


def _huge(obj, where):
    """(key path, value) of the first number in a JSON document at or beyond LIMIT, or None."""
    if isinstance(obj, (int, float)) and not isinstance(obj, bool):
        return None if abs(obj) < LIMIT else (where, obj)
    items = obj.items() if isinstance(obj, dict) else enumerate(obj) if isinstance(obj, list) else ()
    for k, v in items:
        bad = _huge(v, "%s.%s" % (where, k) if isinstance(obj, dict) else "%s[%d]" % (where, k))
        if bad:
            return bad
    return None


def main(argv=None):
    ap = hostio.Parser(prog="python -m tools.simgap",
                       description="Diagnose the sim-to-real gap of a temperature log.")
    ap.add_argument("train", help="training log (CSV, see docs/simgap.md)")
    ap.add_argument("--withheld", help="a second log never used for fitting, to score on")
    ap.add_argument("--model", help="JSON with fixed sim coefficients (default: fit on TRAIN)")
    ap.add_argument("--json", required=True, help="where to write the result")
    ap.add_argument("--plot", help="where to write the PNG")
    ap.add_argument("--quiet", action="store_true", help="no text summary")
    ap.add_argument("--export", metavar="MODEL.json",
                    help="write the augmented model for the board (lib/tempcomp/augment.py)")
    ap.add_argument("--sensitivity", type=float,
                    help="with --export: out units per ref unit where the log never moves the input")
    a = ap.parse_args(argv)
    try:
        hostio.check_output(a.json, "JSON")
        hostio.check_output(a.plot, "plot")
        hostio.check_output(a.export, "exported model")
        if a.plot and not a.plot.lower().endswith(".png"):
            raise hostio.HostError("%s: --plot writes a PNG; give a name ending in .png" % a.plot)
        train = read_log(a.train)
        withheld = read_log(a.withheld) if a.withheld else None
        if a.model:  # encoding, syntax and absurd numbers named here; the fields by FixedModel
            bad = _huge(hostio.load_json(a.model), "model")
            if bad:
                raise hostio.HostError("%s: %s = %r is beyond any sim coefficient (|value| < %g)"
                                       % (a.model, bad[0], bad[1], LIMIT))
        model = FixedModel.load(a.model) if a.model else None
    except (LogError, hostio.HostError) as e:
        return hostio.fail(e)
    try:
        res, extras = diagnose(train, withheld, model)
    except (np.linalg.LinAlgError, FloatingPointError) as e:
        return hostio.fail("%s: the log cannot support the diagnosis's fit (%s): check it for constant or "
                           "extreme columns" % (a.train, e))
    try:
        outputs = [(a.json, json.dumps(res, indent=1, allow_nan=False) + "\n")]
    except ValueError:
        return hostio.fail("%s: the diagnosis came out as %s = NaN/inf (extreme values in the log?); "
                           "nothing written" % (a.train, hostio.nonfinite(res)))
    if a.plot:
        buf = io.BytesIO()
        try:
            plot(res, extras, buf)
        except (ValueError, RuntimeError, OverflowError) as e:
            return hostio.fail("%s: cannot draw the plot (%s); nothing written" % (a.plot, e))
        outputs.append((a.plot, buf.getvalue()))
    try:
        hostio.write_all(outputs)  # the JSON only together with its plot
    except hostio.HostError as e:
        return hostio.fail(e)
    if not a.quiet:
        print(text(res))
    if a.export:
        from .export import ExportError, write
        try:
            exp = write(a.export, res, train, a.sensitivity)
        except ExportError as e:
            print(f"error: --export: {e}", file=sys.stderr)
            return 2
        if not a.quiet:
            on = sorted({e["name"] for e in exp["on_device"]})
            print(f"exported {a.export}: base + {', '.join(on) or 'nothing (the base model)'}"
                  + "".join(f"\n  not on the board: {e['name']} ({e['axis']}): {e['reason']}"
                            for e in exp["not_on_device"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
