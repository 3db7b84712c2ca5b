"""Where things are, for tests: the repository root, lib/, and the device-side scripts."""
import os

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
LIB = os.path.join(REPO, "lib")
DEVICE = os.path.join(REPO, "host_tests", "device")
