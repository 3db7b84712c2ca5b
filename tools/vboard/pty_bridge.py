"""Pseudo-terminal end of the virtual board's serial line.

Started by server.mjs (node has no pty API): prints the pty's path on the
first line of stdout, then relays bytes both ways between the pty and its own
stdin/stdout, which are pipes to the server.
"""

import os
import pty
import select
import sys
import tty


def main():
    master, slave = pty.openpty()
    # Raw: no echo, no CR/LF translation, as a USB CDC port presents itself.
    tty.setraw(slave)
    # The starting user's only (a pty is 0620, group tty, by default).
    os.fchmod(slave, 0o600)
    # Keep our own handle on the slave side so the pty survives clients
    # opening and closing it (otherwise the master reads EIO in between).
    print(os.ttyname(slave), flush=True)
    os.set_blocking(master, False)
    inp, out = sys.stdin.fileno(), sys.stdout.fileno()
    while True:
        ready, _, _ = select.select([master, inp], [], [])
        if inp in ready:
            data = os.read(inp, 4096)
            if not data:
                return  # the server went away
            try:
                os.write(master, data)
            except BlockingIOError:
                pass  # nobody is reading the pty and its buffer is full: drop
        if master in ready:
            try:
                data = os.read(master, 4096)
            except (BlockingIOError, OSError):
                continue
            while data:
                data = data[os.write(out, data):]


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        pass
