"""Sim-to-real gap diagnosis: where the temperature model departs from a real log,
which unmodelled effect causes it, and how far adding that effect shrinks the gap."""
import os
import sys

# One BLAS thread unless asked (SIMGAP_THREADS=N, or the BLAS's own variable set by the user):
# the fits are many small solves, and on a shared machine a multi-threaded BLAS fighting for a
# busy core made a 2 s run take 32 s. Only effective before numpy is first imported.
if "numpy" not in sys.modules:
    _n = os.environ.get("SIMGAP_THREADS", "1")
    for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS"):
        os.environ.setdefault(_v, _n)

from .logio import Log, LogError, read_log  # noqa: E402,F401
