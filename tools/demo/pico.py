"""`make demo BOARD=pico`: the board-side steps of the demo on the virtual Raspberry Pi Pico.

The real RP2040 firmware on the emulated RP2040 (tools/pico) cannot reach the simulated world
its sensors sit in, as a real board cannot move the table it lies on: the hands of the demo
(lay the board on a face, knock it, heat it, the turntable) are the host's, through the board's
world control socket (tools/pico/control.mjs, picoctl.WorldControl). Where the session or the
sweep needs them, the board prints ``HANDS <step> <attempt>`` and waits for a line on its
stdin; the host moves the world, then sends that line.
"""

import codecs
import os

from tools.board.boardctl import BoardError
from tools.board.picoctl import WorldControl

SESSION = r"""
import sys, tempcomp_board
from tempcomp.session import Session


def hands(step, attempt):
    # the rig's hands are the host's (make demo): ask for this step's, then wait until done
    print("HANDS", step, attempt)
    sys.stdin.readline()


Session(tempcomp_board, answers=[], hook=hands, points=%(points)d, step_c=%(step)r, packets=500,
        samples=128).run()
"""

SWEEP = r"""
import sys, time, tempcomp_board
from tempcomp.session import restore
s = restore(tempcomp_board, verbose=False)
print("HANDS sweep 1")
sys.stdin.readline()
t0 = time.ticks_ms()
while time.ticks_diff(time.ticks_ms(), t0) < %(ms)d:
    r = s.read(8)
    time.sleep_ms(100)  # a reading every 0.1 s of the RP2040's time
    print("ROW", repr((time.ticks_ms(), r)))
"""


def world(vb):
    """The world control of a virtual Pico started as boardctl.VirtualBoard(board="pico")."""
    return WorldControl(os.path.join(vb.home, "world.sock"))


def run(url, code, hands, echo, timeout=900):
    """Run code on the board at url through its raw REPL (after a soft reset, as ``mpremote
    run`` does), echoing its output; at each ``HANDS step attempt`` line call
    hands(step, attempt), then answer the board's wait. Returns the output."""
    from mpremote.transport import TransportError
    from mpremote.transport_serial import SerialTransport

    t = SerialTransport(url, baudrate=115200)
    dec = codecs.getincrementaldecoder("utf-8")("replace")
    out = []
    line = [""]

    def consume(b):
        if b == b"\x04":
            return
        for c in dec.decode(b):
            out.append(c)
            echo(c)
            if c != "\n":
                line[0] += c
                continue
            text = line[0].strip()
            line[0] = ""
            if text.startswith("HANDS "):
                _, step, attempt = text.split()
                hands(step, int(attempt))
                t.serial.write(b"\r\n")

    try:
        t.enter_raw_repl(soft_reset=True)
        t.exec_raw_no_follow(code)
        _, err = t.follow(timeout, data_consumer=consume)
        t.exit_raw_repl()
    except TransportError as e:
        raise BoardError("the virtual Pico stopped answering: %s" % e) from None
    finally:
        t.close()
    if err:
        raise BoardError("the script on the virtual Pico failed:\n%s\n%s" % (
            "".join(out)[-2000:], err.decode("utf-8", "replace")))
    return "".join(out)
