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


# Issue 22: the reduced set's misses at seed 20 (offset_temperature not named, 3.21x), GAP_SEED 105
# and 64346 were carried as known gaps (xfail) until the held-out range fix (3b63ac5); on a4653fb
# `python -m tools gap-check --small` met every target on seeds 1-8 and 19-60 (50 seeds, 2026-11-28),
# so these checks must pass at any seed.
def test_every_single_effect_named_first(rows):
    bad = [(r["case"], r["verdict"]) for r in rows if len(r["truth"]) == 1 and not r["attributed"]]
    assert not bad, "seed %d: %s" % (SEED, bad)


def test_both_effects_of_each_pair_in_verdict(rows):
    bad = [(r["case"], r["verdict"]) for r in rows if len(r["truth"]) == 2 and not r["attributed"]]
    assert not bad, "seed %d: %s" % (SEED, bad)


def test_nothing_claimed_without_an_effect(rows):
    bad = [(r["case"], r["verdict"]) for r in rows if not r["truth"] and r["verdict"]]
    assert not bad, "seed %d: %s" % (SEED, bad)


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


def test_power_on_pair_that_masks_itself_found_together(tmp_path):
    # The full set's drift + turn_on_bias case at seed 13 (case seed 13017): each effect alone
    # predicted the held-out segments worse (a run's constant fitted on its settled half misses
    # its warm-up half; a warm-up fitted across runs takes their different offsets), so nothing
    # was named and the withheld residual stayed 3.6x the floor until the pair was tried
    # together (select.Greedy._joint). The generator's truth, not the tool, says what is there.
    effects = ("drift", "turn_on_bias")
    train, withheld = gapgen.make_case(effects, 13 * 1000 + 17)
    lab = {"case": "pair-drift+turn_on_bias", "effects": list(effects),
           "train": str(tmp_path / "t.csv"), "withheld": str(tmp_path / "w.csv"),
           "true_noise": gapgen.TRUE_FLOOR}
    gapgen.write_csv(lab["train"], train, gapgen.META)
    gapgen.write_csv(lab["withheld"], withheld, gapgen.META)
    r = gapcheck.score_case(lab)
    assert r["attributed"] and not r["extra"], r
    assert r["shrink_ok"], r
