"""python -m tools.simgap TRAIN.csv [--withheld W.csv] [--model M.json] --json OUT.json [--plot OUT.png]"""
import argparse
import json
import sys

from .diagnose import diagnose
from .logio import LogError, read_log
from .model import FixedModel
from .report import plot, text


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m tools.simgap",
                                 description="Diagnose the sim-to-real gap of a temperature log.")
    ap.add_argument("train", help="training log (CSV, see docs/simgap.md)")
    ap.add_argument("--withheld", help="a second log never used for fitting, to score on")
    ap.add_argument("--model", help="JSON with fixed sim coefficients (default: fit on TRAIN)")
    ap.add_argument("--json", required=True, help="where to write the result")
    ap.add_argument("--plot", help="where to write the PNG")
    ap.add_argument("--quiet", action="store_true", help="no text summary")
    a = ap.parse_args(argv)
    try:
        train = read_log(a.train)
        withheld = read_log(a.withheld) if a.withheld else None
        model = FixedModel.load(a.model) if a.model else None
    except LogError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    res, extras = diagnose(train, withheld, model)
    with open(a.json, "w") as f:
        json.dump(res, f, indent=1)
    if a.plot:
        plot(res, extras, a.plot)
    if not a.quiet:
        print(text(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
