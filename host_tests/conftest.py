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
# One BLAS thread (set before numpy loads OpenBLAS): the host fits solve thousands of small
# least-squares systems, and a second OpenBLAS thread that has to wait for a busy core makes each
# product wait for a scheduler tick - the blind gap benchmark took 133 s instead of 12 s that way.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pytest  # noqa: E402

from tools.firmware import mpvm as _mpvm  # noqa: E402


@pytest.fixture
def mpvm():
    """Run code in the real MicroPython VM: mpvm(code) -> stdout (raises on a Python error)."""
    return _mpvm.run


import interps as _interps  # noqa: E402  (host_tests/helpers/interps.py)


@pytest.fixture(scope="session")
def _close_interps():
    yield
    _interps.close_all()


@pytest.fixture(scope="session", params=_interps.INTERPRETERS)
def interp(request, _close_interps):
    """Each real interpreter in turn (wasm VM, Cortex-M3 and M7 firmware, CircuitPython), started once
    per session: interp.run(code, mounts=(), paths=()) -> stdout, raising on a Python error; interp.name.
    One interpreter only: @pytest.mark.parametrize("interp", ["an385"], indirect=True)."""
    return _interps.get(request.param)


import seeds as _seeds  # noqa: E402  (host_tests/helpers/seeds.py)


def pytest_report_header(config):
    return _seeds.note()


def pytest_terminal_summary(terminalreporter):
    # at the end too (pytest -q shows no header): the seed to repeat a failure with
    terminalreporter.write_line(_seeds.note())
