"""``make bench`` (``python -m tools bench``): one module per area, each with ``bench(report)``.

May import anything in ``tools`` and ``lib``; nothing imports it.
"""
