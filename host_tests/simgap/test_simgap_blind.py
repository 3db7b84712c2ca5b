"""The blind benchmark with its targets, on the reduced case set (one case per effect, three
pairs, two no-effect cases and one with outliers); `make gap-check` runs the full set.

The cases come from tools/gapbench/gen.py, which shares no code with the diagnosis and builds each
effect in a shape the tool's families do not contain; the tool sees only the CSV files. One seed
drawn at random per run (printed; GAP_SEED=N repeats it); `python -m tools gap-check --small
--seeds 1-20` sweeps."""
import os

import pytest

from tools.gapbench import check as gapcheck
from tools.gapbench import gen as gapgen

SEED = int(os.environ["GAP_SEED"])  # drawn per run by host_tests/helpers/seeds.py (set it to repeat one)


@pytest.fixture(scope="module")
def rows(tmp_path_factory):
    print("\nblind set (reduced) at seed %d (GAP_SEED=%d repeats it)" % (SEED, SEED))
    rows = gapcheck.run(seed=SEED, full=False, outdir=str(tmp_path_factory.mktemp("blind")),
                        jobs=min(2, os.cpu_count() or 1))
    print(gapcheck.summary(rows))
    return rows


def test_reduced_set_has_every_kind_of_case():
    kinds = gapgen.cases(full=False)
    singles = {c[1][0] for c in kinds if len(c[1]) == 1}
    assert singles == set(gapgen.EFFECT_NAMES)
    assert sum(len(c[1]) == 2 for c in kinds) >= 3
    assert sum(not c[1] for c in kinds) >= 3 and any(c[2] for c in kinds)


# Issue 22: the reduced set with the noise branch's fixes (dfe2275), swept over seeds 1-20 (python -m
# tools gap-check --small, seeds 1-9 by the noise branch, 10-20 on main 3e677d0, 2026-11-27): every
# target at 19 of 20 seeds; at seed 20 the single offset_temperature case got no verdict (3.21x).
# These two checks each hold on 19/20, within the target, but at the random seed of a run
# they fail about 1 run in 20: a miss is an XFAIL with its seed, a pass an XPASS. Every other check
# here must pass at any seed. Seeds 20, 105 and 64346 meet every target since held-out segments are
# scored only where the rows their fit keeps have been (docs/simgap.md, fourth round of 2026-11-28);
# the markers stay until a sweep of 50 or more seeds shows no miss.
SEED_20 = ("issue 22: 19/20 seeds of the reduced set (seed 20: offset_temperature not named, 3.21x);"
           " the 1.25x check also missed at GAP_SEED=51330 (1.28x) and 64346 (offset_temperature named,"
           " 2.25x), both make-test runs; seeds 101-112: 11/12 (105: offset_temperature not named, 3.46x);"
           " 20, 105 and 64346 met since the held-out range fix (3b63ac5), not yet swept over 50 seeds")


@pytest.mark.xfail(strict=False, reason=SEED_20)
def test_every_single_effect_named_first(rows):
    bad = [(r["case"], r["verdict"]) for r in rows if len(r["truth"]) == 1 and not r["attributed"]]
    assert not bad, "seed %d: %s" % (SEED, bad)


def test_both_effects_of_each_pair_in_verdict(rows):
    bad = [(r["case"], r["verdict"]) for r in rows if len(r["truth"]) == 2 and not r["attributed"]]
    assert not bad, "seed %d: %s" % (SEED, bad)


def test_nothing_claimed_without_an_effect(rows):
    bad = [(r["case"], r["verdict"]) for r in rows if not r["truth"] and r["verdict"]]
    assert not bad, "seed %d: %s" % (SEED, bad)


@pytest.mark.xfail(strict=False, reason=SEED_20)
def test_withheld_residual_within_25_percent_of_true_noise(rows):
    bad = [(r["case"], round(r["ratio"], 3)) for r in rows if r["ratio"] > 1.25]
    assert not bad, "seed %d: %s" % (SEED, bad)
    # ... and the effects were real gaps to begin with.
    assert all(r["ratio_before"] > 1.05 for r in rows if r["truth"])


def test_where_by_excess_over_the_floor(rows):
    # An effect case's top cell carries energy above the noise floor; a no-effect case lists none.
    # (Issue 22: it missed at GAP_SEED=98609, the 1 degC reading's map empty under a gate 11.5
    # times the excess's null spread; with the gate at its spread (where.AXIS_Z) it held on seeds
    # 1-120 and 98609, where_ok computed from the same residual the diagnosis maps.)
    bad = [r["case"] for r in rows if not r["where_ok"]]
    assert not bad, "seed %d: %s" % (SEED, bad)


def test_the_documented_scores_are_these_codes():
    # README's blind-benchmark sentence is rendered from make bench's record (the gapcheck area runs the
    # full set at seed 1 and this reduced set at seed 7). Both are deterministic for a given code, so the
    # record keeps a fingerprint of the code it measured: a change to the diagnosis, the generator or the
    # pinned libraries that was not measured again fails here (running the sets again would take minutes)
    from tools.bench import gapcheck as bench_gapcheck
    from tools.bench import record

    rows = record.load()["areas"]["gapcheck"]["rows"]
    assert "source" in rows, "docs/bench.json's gapcheck area has no code fingerprint: run `python -m tools bench gapcheck`"
    assert rows["source"]["value"] == bench_gapcheck.source(), (
        "the gap diagnosis, its blind generator or the pinned libraries changed since docs/bench.json's gapcheck "
        "figures were measured: run `python -m tools bench gapcheck` (it renders the pages) and commit the record")
