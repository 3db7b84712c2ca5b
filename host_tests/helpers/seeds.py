"""The random numbers of a test run: tests whose data are random take their seeds from here, so
every run tries other data, and a failure is repeated with the same data by setting the run's
seed, which pytest prints at the end of every run (host_tests/conftest.py):

    TEMPCOMP_SEED=123456 make test

``seed(name)`` is the run's seed for one use (a test or a data set), ``seeds(name, n)`` n of them;
the same TEMPCOMP_SEED gives the same numbers to the same names. The gap diagnosis' blind sets take
their own seeds, GAP_SEED and WANDER_SEED (their tools' --seed), drawn here too.

Every seed drawn is put in the environment: pytest-xdist's workers are processes started after this
module runs in the controller, and each one must draw the same data (and the seeds printed at the
end must be the ones the tests used)."""
import os
import random
import zlib

ENV = "TEMPCOMP_SEED"


def _run_seed():
    v = os.environ.get(ENV, "").strip()
    if v:
        try:
            return int(v)
        except ValueError:
            raise SystemExit("%s=%r: need an integer" % (ENV, v)) from None
    return random.SystemRandom().randrange(1, 1000000)


RUN = _run_seed()
os.environ[ENV] = str(RUN)
BLIND = ("GAP_SEED", "WANDER_SEED")
for _name in BLIND:
    if not os.environ.get(_name, "").strip():
        os.environ[_name] = str(random.SystemRandom().randint(1, 100000))


def seed(name, k=0, run=None):
    """A seed in [0, 2**31) for the named use, from the run's seed (or from the run seed
    `run`, to repeat one use of a past run's data: a regression kept at the seed it failed)."""
    return zlib.crc32(("%d/%s/%d" % (RUN if run is None else run, name, k)).encode()) & 0x7FFFFFFF


def seeds(name, n):
    return [seed(name, k) for k in range(n)]


def note():
    return "%s=%d %s (this run's random data; set them to repeat it)" % (
        ENV, RUN, " ".join("%s=%s" % (n, os.environ[n]) for n in BLIND))
