"""The test session's running interpreters (tools/firmware/interp.py), each started once: ``get(name)``
boots it the first time and skips the calling test, with the reason, when it cannot run here
(in CI, CI=true, that is a failure: CI builds every interpreter)."""
import atexit

import pytest
from paths import skip_unless_ci

from tools.firmware import interp as _interp

INTERPRETERS = _interp.INTERPRETERS
_OPEN = {}  # name -> running interpreter, or the one-line reason it cannot run


def get(name):
    if name not in _OPEN:
        if not _OPEN:
            atexit.register(close_all)  # never leave a qemu behind, whoever called get()
        why = _interp.missing(name)
        if why is None:
            try:
                _OPEN[name] = _interp.open_interp(name)
            except _interp.Unavailable as e:
                why = str(e)
        if why is not None:
            _OPEN[name] = why
    it = _OPEN[name]
    if isinstance(it, str):
        skip_unless_ci("%s cannot run: %s" % (name, it))
    return it


def close_all():
    for it in _OPEN.values():
        if not isinstance(it, str):
            it.close()
    _OPEN.clear()


SMALL_HEAP = ("an385", "an500")  # ~128 KB free once the host filesystem is mounted


def run(interp, code, **kw):
    """interp.run; running out of heap on the small-heap firmware fails the test like any other
    error (README says these scripts pass there), with the failing allocation's call chain first."""
    try:
        return interp.run(code, **kw)
    except _interp.InterpError as e:
        msg = str(e)
        if interp.name in SMALL_HEAP and "MemoryError" in msg:
            tb = [ln.strip() for ln in msg.splitlines() if ln.strip().startswith(("File", "MemoryError"))]
            pytest.fail("%s: out of its ~140 KB heap: %s\n%s" % (interp.name, " <- ".join(tb[::-1][:4]), msg))
        raise
