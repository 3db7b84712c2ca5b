"""Random MPU-6xxx offset(T) models for the set-up tests: ``random_cases(n, seed)`` gives
(mpu_tc record, (GYRO_CONFIG, ACCEL_CONFIG), gyro offset registers, accel offset words,
probe temperatures) tuples the tests feed to every interpreter and to CPython."""


def random_cases(n, seed):
    # mpu_tc records of 1..6 points over spans from 40 raw counts to most of the int16 range,
    # register values drifting as a quadratic plus capture noise, in 1/16 LSB; offsets held near
    # the model's middle value; every gyro and accel range
    import random

    rng = random.Random(seed)
    cases = []
    while len(cases) < n:
        npts = rng.randint(1, 6)
        span = rng.choice([40, 700, 3000, 12000, 30000])
        lo = rng.randint(-20000, 15000 - span)
        ts = sorted(rng.sample(range(lo, lo + span + 1), npts))
        mid = (ts[0] + ts[-1]) // 2
        ints = [npts]
        rows = [[t] for t in ts]
        bases = []
        for k in range(6):
            base = rng.uniform(-600, 600) if k < 3 else rng.uniform(-6000, 6000)
            slope = rng.uniform(-1, 1) * (20.0 if k < 3 else 60.0) / max(span, 1)
            curv = rng.uniform(-1, 1) * (10.0 if k < 3 else 30.0) / max(span, 1) ** 2
            for r, t in zip(rows, ts):
                v = base + slope * (t - mid) + curv * (t - mid) ** 2 + rng.gauss(0, 0.3)
                r.append(int(round(v * 16)))
            bases.append(int(round(base)) + rng.randint(-40, 40))
        for r in rows:
            ints += r
        w = max(ts[-1] - ts[0], 2)
        probe = [ts[0] - w, ts[0] - 1, mid, ts[-1] + 1, ts[-1] + w // 3]
        fs = (8 * rng.randint(0, 3), 8 * rng.randint(0, 3))
        cases.append((ints, fs, bases[:3], bases[3:], probe))
    return cases
