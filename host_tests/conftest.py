import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for p in (os.path.join(REPO, "lib"), REPO, os.path.dirname(os.path.abspath(__file__))):
    if p not in sys.path:
        sys.path.insert(0, p)
os.environ.setdefault("BLINKA_OS_AGNOSTIC", "1")

import mpvm as _mpvm  # noqa: E402
import pytest  # noqa: E402


@pytest.fixture
def mpvm():
    """Run code in the real MicroPython VM: mpvm(code) -> stdout (raises on a Python error)."""
    return _mpvm.run
