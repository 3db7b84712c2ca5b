"""Host-side tools for tempcomp, one folder per role (``python -m tools --help`` lists the commands).

- ``fit/``       fit coefficients from chamber CSVs (one unit or a fleet)
- ``simgap/``    the sim-to-real gap diagnosis of a log, and the real-log converter
- ``gapbench/``  the diagnosis' blind benchmark (generator + checker); simgap never imports it
- ``sim/``       register-accurate simulated sensors and buses (MicroPython-compatible)
- ``vboard/``    the virtual board: the MicroPython VM serving a board's REPL
- ``board/``     everything that talks to a board or builds what goes on it (deploy, .mpy, store files)
- ``firmware/``  the real interpreters the on-device code is tested on, and their runners
- ``bench/``     ``make bench``: one module per area
- ``demo/``      ``make demo``

Import rules (checked by host_tests/test_layout.py): nothing in ``lib/`` imports ``tools``;
``simgap`` imports nothing from ``gapbench``, ``bench``, ``demo`` or ``board``; ``fit``, ``sim``
and ``simgap`` import no other role's package but ``tools.fit.common``-style helpers of their own.
"""
import os

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LIB = os.path.join(REPO, "lib")
