"""`make bench` figures of the gap diagnosis' blind benchmark (tools/gapbench/check.py, what
`make gap-check` runs): the scores of the full set (27 cases, seed 1) and of the reduced set the
tests run (host_tests/simgap/test_simgap_blind.py, seed 7), each a check (a missed target makes
`make bench` exit 1). Deterministic: the generator and the diagnosis are seeded, so the figures
belong to the code that gave them: the record keeps a fingerprint of that code (``source``), and
host_tests/simgap/test_simgap_blind.py fails when the code differs from it (a change that was not
measured again), instead of running the set again at the record's seed on every `make test`."""

import glob
import hashlib
import os

from tools import REPO
from tools.gapbench import check as gapcheck

# what the scores depend on: the diagnosis, the project's generator and scoring, this file, and the
# versions of the host libraries that compute the numbers
SOURCES = ("tools/simgap/*.py", "tools/gapbench/gen.py", "tools/gapbench/check.py", "tools/bench/gapcheck.py")
LIBRARIES = ("numpy", "scipy", "pandas", "statsmodels", "arch", "AllanTools")

SETS = (("full", 1, True), ("reduced", 7, False))


def scores(rows):
    """{key: (hits, cases)} of one run, as tools.gapbench.check.summary counts them."""
    singles = [r for r in rows if len(r["truth"]) == 1]
    pairs = [r for r in rows if len(r["truth"]) == 2]
    nones = [r for r in rows if not r["truth"]]
    return {"singles": (sum(r["attributed"] for r in singles), len(singles)),
            "pairs": (sum(r["attributed"] for r in pairs), len(pairs)),
            "nones": (sum(r["attributed"] for r in nones), len(nones)),
            "where": (sum(r["where_ok"] for r in rows), len(rows)),
            "shrink": (sum(r["shrink_ok"] for r in rows), len(rows))}


def _code(path):
    """A Python file's code without its comments and docstrings (an edit of the words does not
    make the figures stale), as ast.dump gives it."""
    import ast

    with open(path, "rb") as f:
        tree = ast.parse(f.read())
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr) and \
                isinstance(body[0].value, ast.Constant) and isinstance(body[0].value.value, str):
            node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree).encode()


def source():
    """sha256 (first 16 hex digits) of SOURCES' code, file by file in sorted path order, and of
    LIBRARIES' installed versions."""
    from importlib import metadata

    h = hashlib.sha256()
    for lib in LIBRARIES:
        h.update(("%s==%s\n" % (lib, metadata.version(lib))).encode())
    for pattern in SOURCES:
        for path in sorted(glob.glob(os.path.join(REPO, pattern))):
            h.update(os.path.relpath(path, REPO).replace(os.sep, "/").encode())
            h.update(_code(path))
    return h.hexdigest()[:16]


def bench(report):
    report("gapcheck: fingerprint of the code measured", source(), "", key="source")
    for name, seed, full in SETS:
        rows = gapcheck.run(seed=seed, full=full)
        for key, (hits, n) in scores(rows).items():
            report("gapcheck: %s set (seed %d), %s" % (name, seed, key), hits, "of %d" % n,
                   key="%s_%s" % (name, key), ok=hits == n)
            report("gapcheck: %s set, cases of %s" % (name, key), n, "", key="%s_%s_n" % (name, key))
        report("gapcheck: %s set, worst withheld RMS / true noise" % name, max(r["ratio"] for r in rows), "x",
               key="%s_worst_ratio" % name)
        report("gapcheck: %s set, extra effects claimed on effect cases" % name,
               sum(len(r["extra"]) for r in rows if r["truth"]), "", key="%s_extra" % name)
