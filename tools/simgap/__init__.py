"""Sim-to-real gap diagnosis: where the temperature model departs from a real log,
which unmodelled effect causes it, and how far adding that effect shrinks the gap."""

from .logio import Log, LogError, read_log  # noqa: F401
