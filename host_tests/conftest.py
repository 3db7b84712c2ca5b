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
