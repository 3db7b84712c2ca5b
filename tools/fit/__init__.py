"""Host-side fitting of temperature-compensation coefficients (numpy).

``python -m tools.fit an12760 DATA.csv --json OUT.json`` and friends; see docs/adi_nxp.md. A
directory of per-unit CSVs or a CSV with a ``unit`` column fits a fleet (``fleet.py``, docs/fleet.md).
Records for the device are built with the device's own ``tempcomp`` modules from ``lib/``.
"""

import os
import sys

_LIB = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "lib")
if _LIB not in sys.path:
    sys.path.insert(0, _LIB)
