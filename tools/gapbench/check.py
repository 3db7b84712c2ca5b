"""Blind benchmark of the gap tool: generate labelled cases with tools.gapbench.gen, diagnose each
from its CSV files only (labels stay in labels.json, unread by the tool), then compare.

`python -m tools.gapbench.check [--small] [--seed N] [--keep DIR]` prints the scores and exits 1 when
a target is missed:
  - every single-effect case names its effect first;
  - both effects of every pair are in the verdict;
  - no effect is claimed on the no-effect cases;
  - the withheld residual after the fix is within 25 % of the true noise floor (on every axis);
  - "where" (cells by excess energy over the noise floor): an effect case's top cell has a
    positive excess, a no-effect case lists no cell.
"""
import argparse
import sys
import tempfile

from tools.gapbench import gen as gapgen
from tools.simgap.diagnose import diagnose
from tools.simgap.logio import read_log

SHRINK_TARGET = 1.25


def score_case(lab):
    res, _ = diagnose(read_log(lab["train"]), read_log(lab["withheld"]))
    verdict = res["verdict"]
    truth = lab["effects"]
    ratio = max(res["final"]["withheld_rms"].values()) / lab["true_noise"]
    before = max(res["sim_only"]["withheld_rms"].values()) / lab["true_noise"]
    if not truth:
        ok = not verdict
    elif len(truth) == 1:
        ok = bool(verdict) and verdict[0] == truth[0]
    else:
        ok = all(e in verdict for e in truth)
    extra = [e for e in verdict if e not in truth]
    # "Where" by excess over the noise floor: a case with an effect has a top cell whose
    # energy above the floor is positive; a case without one lists no cell at all.
    where = res["where"]
    where_ok = (bool(where) and where[0].get("excess", 0) > 0) if truth else not where
    return {"case": lab["case"], "truth": truth, "verdict": verdict, "attributed": ok,
            "extra": extra, "ratio": ratio, "ratio_before": before,
            "shrink_ok": ratio <= SHRINK_TARGET, "where_ok": where_ok}


def run(seed=1, full=True, outdir=None):
    with tempfile.TemporaryDirectory() as tmp:
        labels = gapgen.write_benchmark(outdir or tmp, seed, full)
        return [score_case(lab) for lab in labels]


def summary(rows):
    singles = [r for r in rows if len(r["truth"]) == 1]
    pairs = [r for r in rows if len(r["truth"]) == 2]
    nones = [r for r in rows if not r["truth"]]
    L = []
    for r in rows:
        L.append(f"{r['case']:<48} verdict={','.join(r['verdict']) or '-':<45} "
                 f"{'OK ' if r['attributed'] else 'MISS'} rms/floor {r['ratio_before']:.2f} -> "
                 f"{r['ratio']:.2f}{'' if r['shrink_ok'] else ' (over 1.25)'}")
    def frac(rs, k):
        return f"{sum(r[k] for r in rs)}/{len(rs)}"

    L.append(f"single effect named first: {frac(singles, 'attributed')}")
    L.append(f"both effects of a pair in verdict: {frac(pairs, 'attributed')}")
    L.append(f"no-effect cases with nothing claimed: {frac(nones, 'attributed')} "
             f"(false positives: {sum(len(r['verdict']) for r in nones)})")
    L.append(f"extra effects claimed on effect cases: {sum(len(r['extra']) for r in singles + pairs)}")
    L.append(f"where: top cell above the floor on effect cases, empty map without: {frac(rows, 'where_ok')}")
    L.append(f"withheld RMS within 25% of the noise floor: {frac(rows, 'shrink_ok')} "
             f"(worst {max(r['ratio'] for r in rows):.2f}x)")
    return "\n".join(L)


def passed(rows):
    return all(r["attributed"] and r["shrink_ok"] and r["where_ok"] for r in rows)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m tools.gapbench.check")
    ap.add_argument("--small", action="store_true")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep", help="write the cases here instead of a temporary directory")
    a = ap.parse_args(argv)
    rows = run(a.seed, not a.small, a.keep)
    print(summary(rows))
    return 0 if passed(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
