"""Register-accurate simulated sensors and buses (MicroPython-compatible, except blinka.py)."""
