"""Blind benchmark of the gap tool: generate labelled cases with tools.gapbench.gen, diagnose each
from its CSV files only (labels stay in labels.json, unread by the tool), then compare.

`python -m tools.gapbench.check [--small] [--seed N] [--keep DIR]` prints the scores and exits 1 when
a target is missed (`--set wander` / `--set both`: the wander set of tools/gapbench/wander.py,
scored by tools/gapbench/wandercheck.py, which says its own targets):
  - every single-effect case names its effect first;
  - both effects of every pair are in the verdict;
  - no effect is claimed on the no-effect cases;
  - the withheld residual after the fix is within 25 % of the true noise floor (on every axis);
  - "where" (cells by excess energy over the noise floor): an effect case's top cell has a
    positive excess, a no-effect case lists no cell.
"""
import argparse
import json
import multiprocessing
import os
import sys
import tempfile
import time

from tools.gapbench import gen as gapgen
from tools.gapbench import wander, wandercheck
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


def run(seed=1, full=True, outdir=None, jobs=1):
    with tempfile.TemporaryDirectory() as tmp:
        labels = gapgen.write_benchmark(outdir or tmp, seed, full)
        if jobs <= 1:
            return [score_case(lab) for lab in labels]
        with multiprocessing.Pool(jobs) as pool:
            return pool.map(score_case, labels, chunksize=1)


def sweep(seeds, full=True, outdir=None, jobs=1):
    """run() at every seed: {seed: rows}, printed seed by seed, then the table: per case, the
    seeds where it met every target, and the seeds where every case did."""
    out = {}
    for s in seeds:
        rows = run(s, full, outdir and os.path.join(outdir, "seed%d" % s), jobs)
        out[s] = rows
        bad = [r["case"] for r in rows if not (r["attributed"] and r["shrink_ok"] and r["where_ok"])]
        print("seed %d: %s" % (s, "every target met" if not bad else "missed " + ", ".join(
            "%s (verdict %s, %.2fx)" % (r["case"], ",".join(r["verdict"]) or "-", r["ratio"])
            for r in rows if r["case"] in bad)), flush=True)
    return out


def sweep_table(by_seed):
    seeds = sorted(by_seed)
    cases = [r["case"] for r in by_seed[seeds[0]]]
    L = ["gen set over %d seed(s): per case, seeds meeting every target (named / alone or nothing "
         "claimed, withheld RMS <= 1.25x the floor, where) and the worst RMS ratio" % len(seeds)]
    for c in cases:
        rs = [next(r for r in by_seed[s] if r["case"] == c) for s in seeds]
        ok = [r["attributed"] and r["shrink_ok"] and r["where_ok"] for r in rs]
        miss = [str(s) for s, k in zip(seeds, ok) if not k]
        L.append("  %-32s %2d/%d  named %2d/%d  rms ok %2d/%d  worst %.2fx%s" % (
            c, sum(ok), len(ok), sum(r["attributed"] for r in rs), len(rs),
            sum(r["shrink_ok"] for r in rs), len(rs), max(r["ratio"] for r in rs),
            ("  missed at seed " + ",".join(miss)) if miss else ""))
    allok = sum(passed(by_seed[s]) for s in seeds)
    L.append("seeds meeting every target on every case: %d/%d" % (allok, len(seeds)))
    return "\n".join(L)


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
    ap = argparse.ArgumentParser(
        prog="python -m tools.gapbench.check",
        description="Blind benchmark of the gap diagnosis. --set gen (default): the 27 cases of "
                    "tools/gapbench/gen.py at one --seed. --set wander: the random-walk situations of "
                    "tools/gapbench/wander.py over --seeds. --set both: the two in turn.")
    ap.add_argument("--set", dest="which", choices=("gen", "wander", "both"), default="gen")
    ap.add_argument("--small", action="store_true", help="gen: the reduced case set")
    ap.add_argument("--seed", type=int, default=1, help="gen: the seed (default 1)")
    ap.add_argument("--keep", help="write the cases here instead of a temporary directory")
    ap.add_argument("--seeds", help="seeds, e.g. 1-20 or 3,7 (wander: default 1-20; gen: instead of "
                                    "--seed, with a table of how many seeds meet every target)")
    ap.add_argument("--logs", type=int, default=3, help="wander: logs per situation per seed (default 3)")
    ap.add_argument("--situations", help="wander: comma-separated subset of %s" % ",".join(wander.SITUATIONS))
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                    help="diagnoses run in parallel (default min(2, cores); gen: with --seeds)")
    ap.add_argument("--reading-lsb", type=float, help="wander: read the temperature in steps of this "
                                                       "many degC (default the generator's 1/340; 1 = whole "
                                                       "degrees); temp_quantization is then the reading's")
    ap.add_argument("--json", help="wander: write every log's scores here")
    ap.add_argument("-v", "--verbose", action="store_true", help="wander: one line per log as it finishes")
    a = ap.parse_args(argv)
    ok = True
    if a.which in ("gen", "both"):
        if a.seeds:
            try:
                gseeds = wandercheck.parse_seeds(a.seeds)
            except ValueError as e:
                ap.error(str(e))
            by_seed = sweep(gseeds, not a.small, a.keep and os.path.join(a.keep, "gen"), a.jobs)
            print(sweep_table(by_seed))
            ok &= all(passed(r) for r in by_seed.values())
        else:
            rows = run(a.seed, not a.small, a.keep and os.path.join(a.keep, "gen"))
            print(summary(rows))
            ok &= passed(rows)
    if a.which in ("wander", "both"):
        try:
            seeds = wandercheck.parse_seeds(a.seeds or "1-20")
            sits = wander.SITUATIONS if not a.situations else tuple(a.situations.split(","))
            bad = [s for s in sits if s not in wander.SITUATIONS]
            if bad or a.logs < 1 or a.jobs < 1:
                raise ValueError("unknown situation(s) %s (one of %s)" % (",".join(bad), ",".join(wander.SITUATIONS))
                                 if bad else "--logs and --jobs must be >= 1")
            if a.reading_lsb is not None and not (0 < a.reading_lsb <= 10):
                raise ValueError("--reading-lsb %g: a temperature step in degC, above 0 and at most 10"
                                 % a.reading_lsb)
        except ValueError as e:
            ap.error(str(e))
        if a.which == "both":
            print()
        t0 = time.perf_counter()

        def progress(row, k, n):
            if a.verbose:
                print("[%d/%d] %s" % (k, n, wandercheck.log_line(row)), flush=True)

        wrows = wandercheck.run(seeds, a.logs, sits, a.jobs, a.keep and os.path.join(a.keep, "wander"), progress,
                                a.reading_lsb)
        ok &= wandercheck.report(wrows)
        wall = time.perf_counter() - t0
        diag = sum(r["diagnose_s"] for r in wrows)
        print("%d diagnoses in %.0f s wall (%d job(s)); per diagnosis %.1f s mean, %.1f s worst; "
              "generating %.2f s mean" % (len(wrows), wall, a.jobs, diag / len(wrows),
                                          max(r["diagnose_s"] for r in wrows),
                                          sum(r["generate_s"] for r in wrows) / len(wrows)))
        if a.json:
            with open(a.json, "w") as f:
                json.dump(wrows, f, indent=1)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
