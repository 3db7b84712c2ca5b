"""``make demo`` (``python -m tools demo``): the virtual board end to end, and the fixed-point
core's own demonstration. May import anything in ``tools`` and ``lib``; nothing imports it."""
