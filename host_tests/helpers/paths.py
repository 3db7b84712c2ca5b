"""Where things are, for tests: the repository root, lib/, and the device-side scripts."""
import os

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
LIB = os.path.join(REPO, "lib")
DEVICE = os.path.join(REPO, "host_tests", "device")


def in_ci():
    """True under CI (CI=true, as .ci/run exports), where everything the suite needs is installed."""
    return os.environ.get("CI", "").strip().lower() in ("true", "1", "yes")


def skip_unless_ci(reason):
    """Skip the calling test because something is missing here; in CI a missing thing is a
    failure, never a skip (CI has the real data, the firmware, tmux)."""
    import pytest

    if in_ci():
        pytest.fail("%s; CI=true, where it must be present: a failure, not a skip" % reason)
    pytest.skip(reason)
