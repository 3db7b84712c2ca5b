"""The real interpreters the on-device code runs on in tests and benchmarks, and their runners:
``mpvm`` runs a script in the MicroPython WebAssembly VM (``mpvm.mjs`` under node); ``interp`` is one
API over that VM, MicroPython firmware for Cortex-M3/M7 boards under qemu and CircuitPython's unix port.

May import: ``tools`` (paths) only. Scripts it runs come from ``lib/`` and ``host_tests/device/``.
"""
