"""`make demo`: a whole calibration on the virtual board, end to end, then a real log's diagnosis.

    make demo                          # the virtual board (no hardware)
    make demo BOARD=pico               # the virtual Raspberry Pi Pico: the real RP2040 firmware
    make demo PORT=/dev/ttyACM0 BOARD=pico   # the same on a real board

Steps: start the virtual board (MicroPython VM with a simulated MPU-6500, MLX90609 and analog
gyro), deploy tempcomp with mpremote, run the guided calibration session scripted (a knock
mid-capture forces a redo; a heater warms the board for the temperature points), soft-reset
and power-cycle, show the calibration came back from flash, stream compensated and
uncompensated readings through a temperature sweep on a turntable, plot the error against
temperature (out/demo.png), stop the board (always), summarise; then the fixed-point core
against float64, and the sim-to-real gap diagnosis of a real log ($TEMPCOMP_DATA or
../shared/data; skipped with a note when absent).
"""

import argparse
import ast
import json
import os
import subprocess
import sys
import time

from tools import REPO

sys.path.insert(0, REPO)

from tools.board.boardctl import BoardError, Remote, VirtualBoard  # noqa: E402

OUT = os.path.join(REPO, "out")
TIME_SCALE = 4  # simulated seconds per second: the thermal steps pass four times faster
ROOM_C = 20.0
# the session's heater, from when it is switched on; board seconds (x4), which pass with what the
# board does (bus transfers, sleeps), not with the host's clock: the first point's captures
# (about 3 s of them) are over before it warms
HEAT = [(0, ROOM_C), (6, ROOM_C), (36, 50.0)]
SWEEP = [(0, ROOM_C), (2, ROOM_C), (22, 48.0), (26, 48.0), (46, ROOM_C)]  # the chamber afterwards
SWEEP_S = 46
SPIN_DPS = 20.0  # the turntable during the sweep: about z, the MLX90609's and analog gyro's axis
POINTS = 3
STEP_C = 12.0

SESSION_VIRTUAL = r"""
import tempcomp_board, vboard_sensors
from tempcomp.session import Session
w = vboard_sensors.world
heating = []


def hands(step, attempt):
    # what the user's hands do on the virtual board before each capture
    if step == "still":
        w.place("+z")
        if attempt == 1:
            print("  (virtual board: someone knocks the table during this capture)")
            w.bump(after_ms=0, for_ms=400)
    elif step.startswith("face:"):
        w.place(step[5:])
    elif step == "warm":
        w.place("+z")
        if not heating:
            heating.append(1)
            print("  (virtual board: a heater warms it from %%g to 50 degC)" %% %(room)r)
            w.heat(%(heat)r)


Session(tempcomp_board, answers=[], hook=hands, points=%(points)d, step_c=%(step)r, packets=500,
        samples=128).run()
"""

SESSION_REAL = r"""
import tempcomp_board
from tempcomp.session import Session
Session(tempcomp_board, answers=[], pause_s=5, points=1, packets=1000).run()
"""

STATE = r"""
import tempcomp_board
from tempcomp.session import restore
s = restore(tempcomp_board)
print("STATE", repr((s.restored, s.mpu.offsets() if s.mpu else None,
                     round(s.mlx.zro_shift, 3) if s.mlx else None,
                     s.model.to_ints() if s.model else None,
                     s.adxrs.to_record() if s.adxrs and s.adxrs.coeffs else None)))
s.show()
"""

SWEEP_VIRTUAL = r"""
import time, tempcomp_board, vboard_sensors, vboard
from tempcomp.session import restore
s = restore(tempcomp_board, verbose=False)
w = vboard_sensors.world
w.place("+z")
w.spin((0, 0, %(spin)r))
w.heat(%(sweep)r)
clock = vboard.board.clock_ms
t0 = clock()
while clock() - t0 < %(secs)d * 1000:
    r = s.read(8)
    time.sleep_ms(100)  # a reading every 0.1 s of board time (0.4 s of the chamber's, x4)
    print("ROW", repr(((clock() - t0) / 1000, w.temperature_c(), r)))
"""

SWEEP_REAL = r"""
import time, tempcomp_board
from tempcomp.session import restore
s = restore(tempcomp_board, verbose=False)
t0 = time.ticks_ms()
while time.ticks_diff(time.ticks_ms(), t0) < 15000:
    r = s.read(16)
    print("ROW", repr((time.ticks_diff(time.ticks_ms(), t0) / 1000, r["temp_c"], r)))
"""

HANDS_NOTE = {"knock": "  (virtual %s: someone knocks the table during this capture)",
              "heat": "  (virtual %s: a heater warms it from %g to 50 degC)"}

SENSORS = (("mpu_gz", "MPU-6500 gyro z"), ("mlx", "MLX90609"), ("adxrs", "analog gyro (ADXRS-style)"))


def say(text=""):
    print(text, flush=True)


def header(n, text):
    say()
    say("=" * 78)
    say("[%d] %s" % (n, text))
    say("=" * 78)


class Echo:
    """Pass the board's output through; progress bars (a bare \r) redraw only on a terminal."""

    def __init__(self):
        self.tty = sys.stdout.isatty()
        self.line = ""
        self.cr = False
        self.held = False

    HIDDEN = ("ROW ", "STATE ", "HANDS ")  # values the demo parses, not for the reader

    def __call__(self, c):
        if self.tty:
            # live, but a line that starts as a hidden one is held until it is known
            if c == "\n":
                if not self.line.startswith(self.HIDDEN):
                    sys.stdout.write((self.line if self.held else "") + c)
                self.line = ""
                self.held = False
                sys.stdout.flush()
                return
            self.line += c
            if self.line.startswith(self.HIDDEN):
                return
            if any(h.startswith(self.line) for h in self.HIDDEN):
                self.held = True
                return
            sys.stdout.write(self.line if self.held else c)
            self.held = False
            if c == "\r":
                self.line = ""
            return
        # a log keeps the last state of each progress line only
        if c == "\n":
            if self.line.strip() and not self.line.startswith(self.HIDDEN):
                sys.stdout.write(self.line.rstrip() + "\n")
                sys.stdout.flush()
            self.line = ""
            self.cr = False
            return
        if self.cr:
            self.line = ""
            self.cr = False
        if c == "\r":
            self.cr = True
        else:
            self.line += c


def parse(out, tag):
    return [ast.literal_eval(line[len(tag) + 1:].strip()) for line in out.splitlines() if line.startswith(tag + " ")]


def truth(key, virtual):
    # the turntable turns about z; nothing else moves
    if not virtual:
        return 0.0
    return SPIN_DPS if key in ("mpu_gz", "mlx", "adxrs") else 0.0


def errors(rows, virtual):
    """{sensor: (temps, uncompensated errors, compensated errors)} in deg/s."""
    out = {}
    for key, _ in SENSORS:
        ts, raw, comp = [], [], []
        for _, temp, r in rows:
            if key in r and r[key][0] is not None:
                ts.append(temp)
                comp.append(r[key][0] - truth(key, virtual))
                raw.append(r[key][1] - truth(key, virtual))
        if ts:
            out[key] = (ts, raw, comp)
    return out


def plot(errs, path, title, span=None):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = [k for k, _ in SENSORS if k in errs]
    fig, axes = plt.subplots(len(keys), 1, figsize=(8, 2.6 * len(keys) + 0.6), sharex=True, squeeze=False)
    for ax, key in zip(axes[:, 0], keys):
        ts, raw, comp = errs[key]
        ax.axhline(0, color="0.6", lw=0.8)
        if span:
            ax.axvspan(span[0], span[1], color="tab:green", alpha=0.08,
                       label="calibrated span (the session's temperature points)")
        ax.plot(ts, raw, ".", ms=3, color="tab:orange",
                label="uncompensated (worst %.2f deg/s)" % max(abs(v) for v in raw))
        ax.plot(ts, comp, ".", ms=3, color="tab:blue",
                label="tempcomp (worst %.2f deg/s)" % max(abs(v) for v in comp))
        ax.set_ylabel("error, deg/s")
        ax.set_title(dict(SENSORS)[key], fontsize=10, loc="left")
        ax.legend(fontsize=8, loc="best")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("board temperature, degC")
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def table(errs, span=None):
    say("%-28s %20s %20s %20s" % ("sensor", "uncompensated", "tempcomp", "tempcomp in span"))
    for key, name in SENSORS:
        if key in errs:
            ts, raw, comp = errs[key]
            inside = [abs(c) for t, c in zip(ts, comp) if span and span[0] <= t <= span[1]]
            say("%-28s %14.3f deg/s %14.3f deg/s %20s" % (
                name, max(abs(v) for v in raw), max(abs(v) for v in comp),
                "%.3f deg/s" % max(inside) if inside else "--"))


def data_dir():
    return os.environ.get("TEMPCOMP_DATA") or os.path.join(REPO, "..", "shared", "data")


def gap_diagnosis():
    """The sim-to-real gap tool on the real TofuPilot IMU log (issue 8): the plot's path, or None
    when there are no logs to diagnose (said); DemoFailed when the conversion or the diagnosis
    fails."""
    d = data_dir()
    if not os.path.isdir(d):
        say("no real logs at %s (set TEMPCOMP_DATA=DIR): skipping the diagnosis" % os.path.abspath(d))
        return None
    real = os.path.join(OUT, "real")
    py = sys.executable
    conv = subprocess.run([py, "-m", "tools.simgap.convert", "--data", d, "--out", real], cwd=REPO,
                          capture_output=True, text=True)
    train = os.path.join(real, "tofupilot_gyro_train.csv")
    if conv.returncode != 0 or not os.path.exists(train):
        raise DemoFailed("could not convert the logs in %s: %s" % (d, conv.stderr.strip()[-2000:]))
    cmd = [py, "-m", "tools.simgap", train, "--withheld", os.path.join(real, "tofupilot_gyro_withheld.csv"),
           "--json", os.path.join(real, "tofupilot_gyro.json"), "--plot", os.path.join(real, "tofupilot_gyro.png"),
           "--export", os.path.join(real, "tofupilot_gyro_model.json")]
    say("+ python -m tools.simgap %s" % " ".join(os.path.relpath(a, REPO) if a.startswith(REPO) else a for a in cmd[3:]))
    r = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    say(r.stdout.rstrip())
    if r.returncode != 0:
        raise DemoFailed("the diagnosis failed (exit %d): %s" % (r.returncode, r.stderr.strip()[-2000:]))
    return os.path.join(real, "tofupilot_gyro.png")


class DemoFailed(Exception):
    """A step of the demo failed: the rest still runs, and the demo exits with status 1."""


class Steps:
    """The demo's later steps, each run even when one before it failed; ``failed`` names the
    failures, ``done`` what was shown, and ``exit_status()`` is 1 when anything failed."""

    def __init__(self):
        self.done = []
        self.failed = []

    def run(self, name, fn, *args):
        """fn(*args): its summary line (or None: nothing to show); a failure is said and recorded."""
        try:
            line = fn(*args)
        except (DemoFailed, BoardError, OSError, subprocess.SubprocessError) as e:
            say("FAILED: %s: %s" % (name, e))
            self.failed.append("%s: %s" % (name, str(e).splitlines()[0] if str(e) else type(e).__name__))
            return None
        if line:
            self.done.append(line)
        return line

    def exit_status(self):
        return 1 if self.failed else 0


def fixedpoint_step(*args):
    """Step 7: tools.demo.fixedpoint in the VM; DemoFailed when it fails a check or cannot run
    (args: its command-line options)."""
    r = subprocess.run([sys.executable, "-m", "tools.demo.fixedpoint", *args], cwd=REPO, capture_output=True,
                       text=True)
    say(r.stdout.rstrip())
    if r.returncode != 0:
        checks = [ln[len("CHECK FAILED: "):] for ln in r.stdout.splitlines() if ln.startswith("CHECK FAILED: ")]
        raise DemoFailed("; ".join(checks) or "exit %d: %s" % (r.returncode, r.stderr.strip()[-2000:]))
    return "compared the fixed-point core with float64 in the VM"


def gap_step():
    """Step 8: the diagnosis of the real log; (summary line, plot) or (None, None) without logs."""
    gap_png = gap_diagnosis()
    if not gap_png:
        return None
    say("gap plot: %s" % os.path.relpath(gap_png, REPO))
    with open(os.path.join(os.path.dirname(gap_png), "tofupilot_gyro.json")) as f:
        res = json.load(f)
    verdict = res["verdict"]
    left = ["%s %.1fx" % (w["axis"], w["ratio"]) for w in res["warnings"] if w["code"] == "unexplained_residual"]
    what = (", ".join(verdict) if verdict else "no catalogue effect that survives its noise model")
    if left:
        what += "; left unexplained (x the noise model's floor): " + ", ".join(left)
    return "diagnosed a real IMU log: the temperature model misses %s (%s)" % (what, os.path.relpath(gap_png, REPO))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--port", default=os.environ.get("PORT", ""),
                    help="a real board's serial port; empty (default): start the virtual board")
    ap.add_argument("--board", default=os.environ.get("BOARD", ""),
                    help="module in boards/ (virtual for the virtual board; required with --port)")
    ap.add_argument("--tcp", type=int, default=int(os.environ.get("DEMO_TCP", "0")),
                    help="loopback port for the virtual board (0: a free one)")
    a = ap.parse_args(argv)
    virtual = not a.port
    board = a.board or ("virtual" if virtual else "")
    if virtual and board not in ("virtual", "pico"):
        raise SystemExit("make demo BOARD=%s needs PORT= (a real board); without PORT, BOARD is virtual "
                         "(the VM board) or pico (the virtual Raspberry Pi Pico)" % board)
    pico = virtual and board == "pico"
    if not virtual and board in ("", "virtual"):
        raise SystemExit("make demo PORT=%s needs the board module too, e.g. BOARD=pico "
                         "(one of boards/*.py)" % a.port)
    t_start = time.time()
    png = os.path.join(OUT, "demo-pico.png" if pico else "demo.png")
    done = []
    vb = None
    echo = Echo()
    try:
        header(1, "the board")
        if pico:
            from tools.demo import pico as picodemo

            vb = VirtualBoard(os.path.join(REPO, "build", "demo-pico"), port=a.tcp, board="pico",
                              env={"VBOARD_TIME_SCALE": str(TIME_SCALE), "VBOARD_PROFILE": "0:%g" % ROOM_C})
            vb.start(timeout=60)
            port = vb.url
            say("virtual Raspberry Pi Pico on %s: the MicroPython 1.27.0 rp2 firmware on an emulated RP2040,"
                % port)
            say("  littlefs flash in %s" % os.path.relpath(vb.flash, REPO))
            say("  sensors on its real peripherals: MPU-6500 on I2C0 (GP4/GP5), MLX90609 on SPI0 (CS GP17),"
                " analog gyro on ADC0/ADC1")
            say("  world: a steady %g degC room, time runs x%d; the demo's hands (knock, faces, heater,"
                " turntable)" % (ROOM_C, TIME_SCALE))
            say("  act through the board's world control socket on the host (%s), never from the board"
                % os.path.relpath(os.path.join(vb.home, "world.sock"), REPO))
            done.append("started the virtual Pico (%s)" % port)
        elif virtual:
            vb = VirtualBoard(os.path.join(REPO, "build", "demo"), port=a.tcp,
                              env={"VBOARD_TIME_SCALE": str(TIME_SCALE), "VBOARD_PROFILE": "0:%g" % ROOM_C})
            vb.start()
            port = vb.url
            say("virtual board on %s: MicroPython %s VM, flash in %s" % (
                port, "1.27", os.path.relpath(vb.flash, REPO)))
            say("  sensors: MPU-6500 on I2C0, MLX90609 on SPI0 (CS GP17), analog gyro on ADC 26/27;"
                " time runs x%d" % TIME_SCALE)
            say("  scenario: a steady %g degC room (VBOARD_PROFILE), then the session's heater and the"
                " sweep's chamber" % ROOM_C)
            done.append("started the virtual board (%s)" % port)
        else:
            port = a.port
            say("real board on %s with boards/%s.py" % (port, board))
            say("  needs the simulated parts, so NOT done here: the knock mid-capture, the heater for")
            say("  the temperature points (the session takes one room-temperature point), the power")
            say("  cycle (you are asked to replug), the temperature sweep and the turntable (readings")
            say("  are streamed at rest, so the plot's truth is 0 deg/s at room temperature)")
        remote = Remote(port)
        live = Remote(port, echo=echo)

        header(2, "deploy tempcomp with mpremote (compiled .mpy into /lib)")
        remote.deploy_mpy(board, os.path.join(REPO, "build", "demo", "mpy"))
        say(remote.mpremote("ls", ":/lib/tempcomp").rstrip())
        done.append("deployed lib/tempcomp (.mpy) and boards/%s.py as tempcomp_board" % board)

        header(3, "the calibration session (scripted answers; what a user types is in docs/demo.md)")
        if pico:
            heated = []

            def hands(step, attempt):
                # what the user's hands do to the virtual Pico's world before each capture
                with picodemo.world(vb) as w:
                    if step == "still":
                        w.place("+z")
                        if attempt == 1:
                            say(HANDS_NOTE["knock"] % "Pico")
                            # 0.4 s of the RP2040's time (x4): the firmware spends about 0.1 s
                            # of it setting the capture up (the VM board's code takes no board time)
                            w.bump(after_ms=0, for_ms=1600)
                    elif step.startswith("face:"):
                        w.place(step[5:])
                    elif step == "warm":
                        w.place("+z")
                        if not heated:
                            heated.append(1)
                            say(HANDS_NOTE["heat"] % ("Pico", ROOM_C))
                            w.heat(HEAT)

            out = picodemo.run(port, picodemo.SESSION % dict(points=POINTS, step=STEP_C), hands, echo)
        elif virtual:
            code = SESSION_VIRTUAL % dict(heat=HEAT, points=POINTS, step=STEP_C, room=ROOM_C)
            out = live.run(code, timeout=600)
        else:
            out = live.run(SESSION_REAL, timeout=600)
        temps = [float(line.split()[2]) for line in out.splitlines() if line.strip().startswith("point at ")]
        span = (min(temps), max(temps)) if len(temps) > 1 else None
        redo = out.count("redo:")
        done.append("ran the calibration session (%d redo%s after a bad capture)" % (redo, "" if redo == 1 else "s"))

        header(4, "soft reset, then ONE call re-applies everything from flash")
        remote.soft_reset()
        out = live.run(STATE)
        states = parse(out, "STATE")
        header(5, "power cycle, then the same call")
        if virtual:
            vb.power_cycle()
        elif sys.stdin.isatty():
            input("unplug the board, plug it in again, then press Enter ")
        else:
            say("(not interactive: power cycle skipped on the real board)")
        out = live.run(STATE)
        states += parse(out, "STATE")
        same = len(states) == 2 and states[0] == states[1]
        say("calibration after the soft reset and after the power cycle: %s" % ("identical" if same else "DIFFERENT"))
        if not same:
            raise BoardError("the calibration did not come back the same: %r" % (states,))
        done.append("soft-reset and power-cycled: %s restored from /tempcomp.cal, identical both times"
                    % ", ".join(states[0][0]))

        header(6, "compensated vs uncompensated readings through a temperature sweep" if virtual
               else "compensated vs uncompensated readings at rest")
        if virtual:
            say("the board turns at %g deg/s about z on a turntable while a chamber takes it %g -> 48 -> %g degC"
                % (SPIN_DPS, ROOM_C, ROOM_C))
        if pico:
            def turntable(step, attempt):
                with picodemo.world(vb) as w:
                    w.place("+z")
                    w.spin((0, 0, SPIN_DPS))
                    w.heat(SWEEP)

            out = picodemo.run(port, picodemo.SWEEP % dict(ms=SWEEP_S * 1000 // TIME_SCALE), turntable,
                               lambda c: None)
            ticks = parse(out, "ROW")
            if not ticks:
                raise BoardError("no readings streamed:\n" + out[-2000:])
            # the chamber's true temperature at each reading's RP2040 time, from the world
            with picodemo.world(vb) as w:
                temps = w.temperature_at([ms for ms, _ in ticks])
            rows = [((ms - ticks[0][0]) * TIME_SCALE / 1000.0, c, r) for (ms, r), c in zip(ticks, temps)]
        else:
            if virtual:
                out = remote.run(SWEEP_VIRTUAL % dict(spin=SPIN_DPS, sweep=SWEEP, secs=SWEEP_S), timeout=300)
            else:
                out = remote.run(SWEEP_REAL, timeout=120)
            rows = parse(out, "ROW")
        if not rows:
            raise BoardError("no readings streamed:\n" + out[-2000:])
        say("%7s %7s | %-21s | %-21s | %-21s" % ("time s", "degC", "MPU gz comp / raw", "MLX comp / raw",
                                                  "analog comp / raw"))
        step = max(1, len(rows) // 12)
        for t, temp, r in rows[::step]:
            cells = []
            for key, _ in SENSORS:
                c, u = r.get(key, (None, None))
                cells.append("%9s / %9s" % ("--" if c is None else "%+.3f" % c, "--" if u is None else "%+.3f" % u))
            say("%7.1f %7.2f | %s" % (t, temp, " | ".join(cells)))
        errs = errors(rows, virtual)
        say()
        say("worst error against the true rate (%g deg/s about z), %d readings%s:" % (
            truth("mlx", virtual), len(rows),
            "; span = %.1f..%.1f degC, between the session's points" % span if span else ""))
        table(errs, span)
        where = "the virtual Pico (RP2040 firmware)" if pico else "the virtual board"
        title = ("tempcomp on %s: rate error vs temperature (turntable %g deg/s)" % (where, SPIN_DPS)
                 if virtual else "tempcomp on %s: rate error at rest" % board)
        plot(errs, png, title, span)
        say("plot: %s" % os.path.relpath(png, REPO))
        done.append("streamed %d readings%s; plot of raw vs compensated error: %s"
                    % (len(rows), " through %g..48 degC" % ROOM_C if virtual else "", os.path.relpath(png, REPO)))
    finally:
        if vb is not None:
            vb.stop()
            say("virtual Pico stopped" if pico else "virtual board stopped")

    steps = Steps()
    steps.done[:0] = done
    header(7, "the fixed-point core against float64 (in the MicroPython VM)")
    steps.run("the fixed-point step", fixedpoint_step)

    header(8, "sim-to-real gap: diagnosis of a real log (TofuPilot IMU thermal test, gyro)")
    diagnosed = steps.run("the diagnosis of the real log", gap_step)

    header(9, "the diagnosis on the board: export, store, restore, before/after on the withheld part")
    if diagnosed and (pico or not virtual):
        say("this step runs on the VM board, not on %s (README, The virtual Raspberry Pi Pico); "
            "host_tests/pico/test_pico.py runs the augmented model on the RP2040 firmware"
            % ("the virtual Pico" if pico else "the board on " + a.port))
    if diagnosed:
        from tools.demo import augment

        steps.run("the board step", augment.run, say, os.path.join(OUT, "real"))
    else:
        say("no diagnosis to put on the board: skipped")

    header(10, "summary")
    for line in steps.done:
        say(" - " + line)
    for line in steps.failed:
        say(" - FAILED: " + line)
    say("took %.0f s; plot: %s" % (time.time() - t_start, os.path.relpath(png, REPO)))
    if steps.failed:
        say("make demo: %d step(s) failed" % len(steps.failed))
    return steps.exit_status()


if __name__ == "__main__":
    try:
        sys.exit(main())
    except BoardError as e:
        print("\nmake demo failed: %s" % e, file=sys.stderr)
        sys.exit(1)
