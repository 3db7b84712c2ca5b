"""What a fleet summary must say whatever the simulated fleet's seed (host_tests/fit/test_fleet*.py)."""


def check_flags(summary, noisy):
    """The noisy units are flagged for their residual, and no other unit is: a good unit may still
    be flagged for a coefficient in the tail of the fleet (its true offset or sensitivity is drawn
    at random; against the median and MAD of a few dozen units that happens in about one seed in
    20 with 24 units, one in 5 with 12), never for its fit."""
    table = {r["unit"]: r for r in summary["table"]}
    for u in noisy:
        assert u in summary["outliers"] and any(w.startswith("residual") for w in table[u]["why"]), table[u]
    for u in summary["outliers"]:
        if u not in noisy:
            assert table[u]["why"] and not any(w.startswith("residual") for w in table[u]["why"]), table[u]
