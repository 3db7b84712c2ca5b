"""pytest set-up for every test folder: lib/ (the on-device package), the repository root (tools)
and host_tests/helpers/ (host-side test helpers) are importable; Blinka runs OS-agnostic."""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
for p in (os.path.join(REPO, "lib"), REPO, os.path.join(HERE, "helpers")):
    if p not in sys.path:
        sys.path.insert(0, p)
os.environ.setdefault("BLINKA_OS_AGNOSTIC", "1")

import pytest  # noqa: E402

from tools.firmware import mpvm as _mpvm  # noqa: E402


@pytest.fixture
def mpvm():
    """Run code in the real MicroPython VM: mpvm(code) -> stdout (raises on a Python error)."""
    return _mpvm.run


from tools.firmware import interp as _interp  # noqa: E402

_OPEN = {}  # name -> running interpreter (or the reason it cannot run), one per test session


def open_interp_once(name):
    """The session's one running interpreter ``name`` (boots it the first time); skips the test
    with the reason when it cannot run here."""
    if name not in _OPEN:
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
        pytest.skip("%s cannot run: %s" % (name, it))
    return it


@pytest.fixture(scope="session", autouse=False)
def _close_interps():
    yield
    for it in _OPEN.values():
        if not isinstance(it, str):
            it.close()
    _OPEN.clear()


@pytest.fixture(scope="session", params=_interp.INTERPRETERS)
def interp(request, _close_interps):
    """Each real interpreter in turn (wasm VM, Cortex-M3 and M7 firmware, CircuitPython), started once
    per session: interp.run(code, mounts=(), paths=()) -> stdout, raising on a Python error; interp.name."""
    return open_interp_once(request.param)
