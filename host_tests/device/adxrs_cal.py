"""Three-point calibration of an AnalogGyro against the simulated part (runs in the VM)."""

from tempcomp.adxrs import point


def three_point(g, sim, temps, rate_dps=200.0, n=64):
    """At each temperature: VT and null at rest, then at rate_dps; returns the three points."""
    pts = []
    for t in temps:
        sim.temp_c = t
        sim.rate_dps = 0.0
        vt, v0 = g.measure(n)
        sim.rate_dps = rate_dps
        vt2, v1 = g.measure(n)
        pts.append(point((vt + vt2) / 2, v0, v1, rate_dps))
    return pts
