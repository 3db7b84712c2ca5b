"""`make bench` figures of the sim-to-real gap diagnosis (issue 8)."""


def bench(report):
    from tools.simgap.bench import measure

    n, read_s, diag_s, verdict = measure()
    report("simgap: read %d-row log + %d-row withheld log" % (n, n), read_s, "s")
    report("simgap: diagnose them (target < 5 s on one core)", diag_s, "s")
    report("simgap: total", read_s + diag_s, "s")
