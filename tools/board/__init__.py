"""Everything that talks to a board or builds what goes on it: ``deploy`` (mpremote install),
``build_mpy`` (mpy-cross), ``boardctl`` (start/drive the virtual board from Python) and
``storetool`` (the coefficient-store file format on the host).

May import: ``lib/tempcomp`` (the device's own code, to read and write exactly what the board
does), ``tools.firmware``. Not ``simgap``, ``gapbench``, ``bench`` or ``demo``.
"""
