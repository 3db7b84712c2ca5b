"""Guided calibration at the board's REPL: what to do, progress while it captures, checks, redo.

Type at the REPL (lib/tempcomp and your boards/ module, as tempcomp_board, on the board)::

    import tempcomp_board
    from tempcomp.session import Session
    Session(tempcomp_board).run()

It finds the parts (MLX90609, MPU-6xxx, analog gyro), shows the MLX90609 EEPROM health, then:

1. still: board flat, component side up, still: the MPU's offset registers and the
   MLX90609's re-zero are captured (a text progress bar with elapsed time and samples);
2. face: board turned with +x up: a second capture measures the residual on another face;
3. warm: board left still while it warms (or cools): a bias point every ``step_c`` degrees,
   ``points`` of them, for the MPU's offset(T) and the analog gyro's null(T);
4. with ``model="/model.json"`` (a file from ``python -m tools gap ... --export`` copied to the
   board): the exported augmented model is loaded instead of the temperature points or after
   them (the session asks), checked by building it, and saved as record ``model_name``;

then shows the result (bias per axis, residual, EEPROM health) and saves it to the store.
After a reset, ONE call re-applies everything: ``tempcomp.session.restore(tempcomp_board)``
(the same as ``tempcomp.sensors.restore``).

Every capture is checked, by the drivers' own checks where they have them (the MPU's "moved
during capture", "turned during capture", "gyro bias beyond the part's datasheet range",
"saturated", "not lying on a face", "too few packets", implausible reads) and here for the
MLX90609 and the analog gyro (rate spread, saturated codes). A failed step prints the reason
and asks: [r]edo (default), [s]kip the step, [q]uit. Nothing is saved before the end.

A steady turn about the vertical leaves gravity where it is, and below the part's zero-rate
tolerance (MPU-6050: 20 deg/s) it looks like bias; the check on another face catches it: after
the zero, the gyro must read within ``max_residual_dps`` on the +x face, else the session says
so and offers to redo the zero (the previous offsets are put back first). An ICM-20602 that
rewrites its accel trim during the session is found by ``check()`` before saving.

Scripted (tests, ``make demo``, a rig): ``answers`` is a list of replies used instead of
input() (an exhausted list answers with each prompt's default), ``hook(step, attempt)`` runs
just before each capture (a robot arm, or the virtual board's ``vboard_sensors.world``), and
``pause_s`` waits before each capture so a person can follow printed instructions::

    Session(tempcomp_board, answers=[], points=3, step_c=8).run()
"""

import time

from tempcomp import sensors as _sensors


def _now_ms():
    # time.ticks_ms on MicroPython; time.monotonic (CircuitPython, CPython) elsewhere
    f = getattr(time, "ticks_ms", None)
    if f is not None:
        return f()
    return int(time.monotonic() * 1000)  # pyright: ignore[reportAttributeAccessIssue]


def _since_ms(t0):
    # ticks_diff keeps differences right across the ticks_ms wrap-around
    d = getattr(time, "ticks_diff", None)
    return d(_now_ms(), t0) if d is not None else _now_ms() - t0


_BAR = 20
_SHOW_MS = 250  # progress line refresh
_GYRO_REG_DPS = 32.8  # gyro offset register LSB: 1/32.8 deg/s
_ACCEL_WORD_MG = 1000.0 / 2048  # accel offset word LSB: 1/2048 g
_MLX_CODE_MAX = 2047
_ADC_MAX = 65535


class CaptureError(OSError):
    """A capture that must not be used: the board moved, an output saturated, too few samples."""


class Aborted(Exception):
    """The user quit the session (nothing saved)."""


def restore(board, path=_sensors.STORE_PATH, which=_sensors.ALL, verbose=True):
    """After a reset: open the board's parts and re-apply the saved calibration (one call)."""
    return _sensors.restore(board, path, which, verbose)


class Progress:
    """A one-line text progress bar: label [####......] 40% 1.2 s 400/1000 samples."""

    def __init__(self, label, total):
        self.label = label
        self.total = total
        self.t0 = _now_ms()
        self._shown = -_SHOW_MS
        self.show(0)

    def elapsed_s(self):
        return _since_ms(self.t0) / 1000.0

    def show(self, done, extra="", force=False):
        now = _since_ms(self.t0)
        if not force and now - self._shown < _SHOW_MS:
            return
        self._shown = now
        tot = self.total if self.total > 0 else 1
        n = _BAR * min(done, tot) // tot
        print("\r  %s [%s%s] %3d%% %5.1f s %d/%d samples%s   " % (
            self.label, "#" * n, "." * (_BAR - n), 100 * min(done, tot) // tot, now / 1000.0,
            done, self.total, extra), end="")

    def done(self, done, extra=""):
        self.show(done, extra, True)
        print()


class Session:
    """One calibration session on the parts of a board module (see the module docstring).

    store_path: where the result is saved. points: temperature points for offset(T) (1 = room
    temperature only, no waiting). step_c: least temperature change between points, degC.
    wait_s: how long to wait for each change before asking. packets: MPU capture length
    (1 kHz samples); samples: MLX90609 and analog gyro samples per capture. max_bias_dps:
    a larger MPU gyro bias means the board turned (None: the part's datasheet zero-rate
    range, ``MPU6xxx.zro_limit_dps()``). max_residual_dps: the most the gyro may read on the
    +x face after the zero before the zero is called into doubt.
    """

    def __init__(self, board, store_path=_sensors.STORE_PATH, which=_sensors.ALL, answers=None,
                 hook=None, pause_s=0, points=3, step_c=5.0, wait_s=900, packets=1000, samples=256,
                 max_tries=5, max_bias_dps=None, max_residual_dps=1.0, model=None, model_name="gyro_aug"):
        if points < 1:
            raise ValueError("points must be >= 1, got %r" % (points,))
        if not step_c > 0:
            raise ValueError("step_c must be > 0 degC, got %r" % (step_c,))
        self.board = board
        self.store_path = store_path
        self.which = which
        self.answers = None if answers is None else list(answers)
        self.hook = hook
        self.pause_s = pause_s
        self.points = points
        self.step_c = step_c
        self.wait_s = wait_s
        self.packets = packets
        self.samples = samples
        self.max_tries = max_tries
        self.max_bias_dps = max_bias_dps
        self.max_residual_dps = max_residual_dps
        self.model_path = model  # a MODEL.json from `python -m tools gap ... --export`, on the board
        self.model_name = model_name
        self._attempts = {}  # hook attempt numbers per step, counted across redo loops
        self.s = _sensors.Sensors(board)  # the parts, found when run() starts
        self.result = {}  # type: dict

    # ---- talking to the user ------------------------------------------------------------
    def ask(self, prompt, default=""):
        """input(prompt), or the next scripted answer (echoed), or default when they ran out."""
        if self.answers is None:
            a = input(prompt).strip().lower()
            return a or default
        a = self.answers.pop(0) if self.answers else default
        print(prompt + a)
        return a.strip().lower() or default

    def _step(self, name, title, instruction, action):
        # Runs action() until it succeeds, the user skips (None) or quits (Aborted).
        print()
        print("== %s ==" % title)
        tries = 0
        while True:
            tries += 1
            print(instruction)
            a = self.ask("Press Enter to start ([s] skip, [q] quit): ")
            if a == "q":
                raise Aborted("quit at step %r" % name)
            if a == "s":
                print("  skipped")
                return None
            if self.pause_s:
                print("  starting in %d s" % self.pause_s)
                time.sleep(self.pause_s)
            if self.hook is not None:
                n = self._attempts.get(name, 0) + 1
                self._attempts[name] = n
                self.hook(name, n)
            try:
                return action()
            except OSError as e:  # the drivers' and our capture checks, bus faults
                print()
                print("  ! %s" % (e,))
            if self.answers is not None and tries >= self.max_tries:
                raise Aborted("step %r failed %d times" % (name, tries))
            a = self.ask("  [r]edo this step, [s]kip it, [q]uit? ", "r")
            if a == "q":
                raise Aborted("quit at step %r" % name)
            if a == "s":
                print("  skipped")
                return None
            print("  redo:")

    # ---- captures ---------------------------------------------------------------------------
    def _mpu_calibrate(self, mpu):
        # calibrate() refuses a turn (gravity moving, or a bias beyond max_bias_dps / the part's
        # datasheet range) before it writes anything
        p = Progress("MPU-6xxx  ", self.packets)
        regs = mpu.calibrate(packets=self.packets, max_bias_dps=self.max_bias_dps)
        p.done(self.packets)
        return regs

    def _mpu_point(self, mpu):
        p = Progress("MPU-6xxx  ", self.packets)
        pt = mpu.bias_point(packets=self.packets, max_bias_dps=self.max_bias_dps)
        p.done(self.packets)
        return pt

    def _still_capture(self, label, name, read, code_max, dps_per_code, limit_dps=5):
        # mean (temperature, rate code) at rest from read() -> (t, code), refusing a saturated
        # output or a board that moved (the checks the drivers' own zero captures do not make)
        n = self.samples
        p = Progress(label, n)
        st = sr = 0
        lo = code_max
        hi = 0
        for i in range(n):
            t, r = read()
            st += t
            sr += r
            lo = min(lo, r)
            hi = max(hi, r)
            if r <= 0 or r >= code_max:
                raise CaptureError("%s rate output saturated (ADC code %d): not at rest, or not wired?" % (name, r))
            p.show(i + 1)
        p.done(n)
        spread = (hi - lo) * dps_per_code
        if spread > limit_dps:
            raise CaptureError(
                "the board moved during the %s capture: rate spread %.1f deg/s (limit %d); "
                "keep it still" % (name, spread, limit_dps))
        return st / n, sr / n

    def _mlx_capture(self, g, s0):
        # (TEMPOUT mV, rate code) at rest
        return self._still_capture("MLX90609  ", "MLX90609", lambda: (g.tempout_mv(), g.rate_code()),
                                   _MLX_CODE_MAX, 1.0 / s0)

    def _adxrs_capture(self, g):
        # (VT mV, rate mV) at rest
        q = g.mv_per_code
        t, r = self._still_capture("analog    ", "analog gyro", g.read_codes, _ADC_MAX,
                                   q / self.s.adxrs_mv_per_dps)
        return t * q, r * q

    # ---- steps ----------------------------------------------------------------------------
    def _still(self):
        s = self.s
        out = {}
        if s.mpu is not None:
            out["mpu"] = self._mpu_calibrate(s.mpu)
        mlx = s.mlx
        table = mlx.table if mlx is not None else None
        if mlx is not None and table is not None:
            t, code = self._mlx_capture(mlx, table.s0("digital"))
            # the re-zero rezero() would make (LSB), applied now; saved at the end
            out["mlx"] = d = code - mlx.zro_at(t)
            mlx.use_table(table, mlx.zro_shift + d)
        return out

    def _face(self):
        mpu = self.s.mpu
        if mpu is None:
            return None
        t, gy, ac = self._mpu_point(mpu)
        g, a = mpu.offsets()
        return ([(gy[k] - g[k]) / _GYRO_REG_DPS for k in range(3)],
                [(ac[k] - (a[k] & ~1)) * _ACCEL_WORD_MG for k in range(3)])

    def _point(self):
        s = self.s
        pt = {"temp_c": s.temp_c()}
        if s.mpu is not None:
            pt["mpu"] = self._mpu_point(s.mpu)
        if s.adxrs is not None:
            pt["adxrs"] = self._adxrs_capture(s.adxrs)
        mlx = s.mlx
        if mlx is not None and mlx.table is not None:
            n = self.samples
            acc = 0
            for _ in range(n):
                acc += mlx.rate()
            pt["mlx_residual"] = acc / (float(mlx.out_scale) * n)
        return pt

    def _zero_and_face(self):
        # the zero at rest, then the check on another face; a residual there means one of the
        # two captures was taken while the board turned: offer to redo both
        r = self.result
        mpu = self.s.mpu
        rounds = 0
        while True:
            rounds += 1
            before = mpu.offsets() if mpu is not None else None
            still = self._step("still", "Zero at rest",
                               "Lay the board flat, component side (+z) up, and keep it still.", self._still)
            if still:
                r.update(still)
            if mpu is None or not still or "mpu" not in still:
                return
            res = self._step("face:+x", "Check on another face",
                             "Turn the board so its +x edge points up, and keep it still.", self._face)
            if res is None:
                return
            r["residual"] = res
            worst = max(abs(v) for v in res[0])
            if worst <= self.max_residual_dps:
                return
            print()
            print("  ! after the zero the gyro reads %+.2f %+.2f %+.2f deg/s on the +x face (limit %.1f): "
                  "the board was turning during the zero or this check (a slow turn about the vertical "
                  "looks like bias in one capture)" % (-res[0][0], -res[0][1], -res[0][2], self.max_residual_dps))
            if self.answers is not None and rounds >= self.max_tries:
                a = "q"
            else:
                a = self.ask("  [r]edo the zero and this check, [k]eep the zero, [q]uit? ", "r")
            if a == "k":
                print("  kept")
                return
            if before is not None:
                mpu.apply(before[0], before[1])  # the offsets from before this zero
            if a == "q":
                raise Aborted("the zero failed its check on another face %d time(s); previous offsets "
                              "put back" % rounds)
            r.pop("mpu", None)
            r.pop("residual", None)
            print("  redo:")

    def _wait_for_change(self, taken):
        # None when the temperature moved step_c away from every point taken; else the reply
        t0 = _now_ms()
        while True:
            t = self.s.temp_c()
            if t is None:
                return "s"
            d = min(abs(t - x["temp_c"]) for x in taken)
            el = _since_ms(t0) / 1000.0
            n = int(_BAR * min(d, self.step_c) / self.step_c)
            print("\r  %.2f degC, %.2f from the nearest point (need %.1f) [%s%s] %5.1f s   " % (
                t, d, self.step_c, "#" * n, "." * (_BAR - n), el), end="")
            if d >= self.step_c:
                print()
                return None
            if el > self.wait_s:
                print()
                a = self.ask("  no %.1f degC change in %d s: [w]ait more, [s]top with %d point(s), [q]uit? "
                             % (self.step_c, self.wait_s, len(taken)), "s")
                if a != "w":
                    return a
                t0 = _now_ms()
            time.sleep(0.2)

    def _warm(self):
        taken = []
        while len(taken) < self.points:
            if taken:
                a = self._wait_for_change(taken)
                if a == "q":
                    raise Aborted("quit while waiting for the temperature")
                if a is not None:
                    break
            k = len(taken) + 1
            pt = self._step(
                "warm", "Temperature point %d of %d" % (k, self.points),
                "Keep the board still, lying on any face." if k == 1 else
                "The temperature moved: keep the board still for this point.",
                self._point)
            if pt is not None:
                taken.append(pt)
                print("  point at %.2f degC" % pt["temp_c"])
            elif not taken:
                return []
        return taken

    # ---- fitting and saving -------------------------------------------------------------------
    def _fit_adxrs(self, g, pts):
        sc = self.s.adxrs_mv_per_dps
        p = sorted(x["adxrs"] for x in pts)
        if len(p) >= 3:
            a, b, c = p[0], p[len(p) // 2], p[-1]
            g.set_three_point((a[0], a[1], sc), (b[0], b[1], sc), (c[0], c[1], sc))
        elif len(p) == 2:
            slope = (p[1][1] - p[0][1]) / (p[1][0] - p[0][0])
            g.set_quadratics(p[0][0], (p[0][1], slope), (sc,), (p[0][0], p[1][0]))
        else:
            g.set_single(p[0][1], sc)

    def run(self):
        """The whole session; saves at the end. Returns None (the REPL would echo a dict after the
        report): the result is in ``self.result``. Quitting (``q``) ends it with a message and
        nothing saved; a scripted session (``answers=[...]``) raises Aborted instead."""
        print("tempcomp calibration session")
        s = _sensors.open_sensors(self.board, self.which)
        self.s = s
        for name in s.missing:
            print("  - %s" % s.missing[name])
        if not s.found():
            raise OSError("no sensor answered: check the wiring and the board module")
        print("  found: %s" % ", ".join(s.found()))
        r = self.result
        mlx = s.mlx
        if mlx is not None:
            h = mlx.health()
            t = mlx.table
            if t is None:
                print("  MLX90609: no usable look-up table (%s); not calibrated here" % (mlx.table_error,))
            else:
                d = h["vote_disagreements"]
                print("  MLX90609 EEPROM: VERSION %d, %d deg/s full scale, TC %d/%d/%d mV, %d voted bits "
                      "disagree (%s)" % (t.version, t.full_scale_dps, t.tc[0], t.tc[1], t.tc[2], d,
                                         "EEPROM degrading!" if d else "healthy"))
        mpu = s.mpu
        if mpu is not None:
            print("  %s at I2C 0x%02x, %.2f degC" % (mpu.part, mpu.address, mpu.temp_c100() / 100.0))
        try:
            if mpu is not None or mlx is not None:
                self._zero_and_face()
            how = self._ask_model()
            if (mpu is not None or s.adxrs is not None) and how != "i":
                r["points"] = self._warm()
            if how in ("i", "a"):
                self._load_model()
        except Aborted as e:
            print()
            print("session ended: %s; nothing saved" % (e,))
            if self.answers is None:
                return None  # a person quit: the message is the answer, not a traceback
            raise
        self._apply_and_save()
        self._report()

    def _ask_model(self):
        # with an exported model on the board: load it instead of the temperature points, or after
        if self.model_path is None:
            return "n"
        print()
        print("== Exported model ==")
        print("%s holds a model from the gap diagnosis (python -m tools gap ... --export)." % self.model_path)
        while True:
            a = self.ask("load it [i]nstead of the temperature points, [a]fter them, or [n]ot? [a] ", "a")
            if a in ("i", "a", "n"):
                return a
            if a == "q":
                raise Aborted("quit at the model step")

    def _load_model(self):
        # checked by building it as the board will (set-up refuses a model it cannot run)
        import json

        from tempcomp import augment

        path = self.model_path
        if path is None:
            return
        while True:
            try:
                with open(path) as f:
                    d = json.load(f)
                st = d["store"]
                vals = [int(v) for v in st["values"]]
                fr = [int(v) for v in st["frac"]]
                augment.Augmented(augment.unpack([vals[i] / (2.0 ** fr[i]) for i in range(len(vals))]))
                on = []
                for e in d.get("on_device", []):
                    if e["name"] not in on:
                        on.append(e["name"])
                self.result["model"] = {"name": self.model_name, "values": vals, "frac": fr, "effects": on,
                                        "not_on_device": [e["name"] for e in d.get("not_on_device", [])]}
                print("  model: base + %s" % (", ".join(on) or "nothing (the base model)"))
                return
            except (OSError, ValueError, KeyError, TypeError, IndexError) as e:
                print("  ! cannot use %s: %s" % (self.model_path, e))
            a = self.ask("[r]edo (after fixing the file), [s]kip the model, [q]uit? [r] ", "r")
            if a == "s":
                return
            if a == "q":
                raise Aborted("quit at the model step")

    def _apply_and_save(self):
        # loaded here, at the end: the session's heap during the captures stays small (docs/ram.md)
        from tempcomp.mpu6xxx_tc import BiasModel, compiled, merge_points
        from tempcomp.store import Store

        s = self.s
        r = self.result
        st = Store(self.store_path)
        saved = []
        if s.mlx is not None and "mlx" in r:
            s.mlx.save(st, _sensors.MLX)
            saved.append(_sensors.MLX)
        mpu = s.mpu
        if mpu is not None and "mpu" in r:
            n = mpu.check()  # an ICM-20602 may have rewritten its trim during the session
            if n:
                print("  ! %s changed %d offset register(s) by itself during the session (a known "
                      "ICM-20602 fault): written back" % (mpu.part, n))
            r["trim_changes"] = mpu.trim_changes
            mpu.save(st, _sensors.MPU)
            saved.append(_sensors.MPU)
        pts = r.get("points") or []
        mpts = [x["mpu"] for x in pts if "mpu" in x]
        if mpu is not None and mpts:
            n = len(mpts)
            mpts, same = merge_points(mpts)
            if same:
                print("  ! %d temperature points had the same MPU temperature reading as another (%s): "
                      "the temperature did not move between them; averaged, the fit uses %d point(s)" % (
                          n - len(mpts), ", ".join("%.2f degC" % (mpu.temp_c100(t) / 100.0) for t in same),
                          len(mpts)))
            model = BiasModel(mpts)
            mpu.compensate(model)
            s.model = model
            mi = model.to_ints()
            st.save_record(_sensors.MPU_TC, mi, part=mpu.part, kind=2)  # KIND_MPU_POLY
            saved.append(_sensors.MPU_TC)
            # its set-up for the offsets and ranges just saved: a boot then resumes it without
            # the fixed-point set-up (tempcomp.mpu6xxx_rt, docs/ram.md)
            st.save_record(_sensors.MPU_TCC, compiled(mpu, mi), part=mpu.part, kind=2)
            saved.append(_sensors.MPU_TCC)
        apts = [x for x in pts if "adxrs" in x]
        if s.adxrs is not None and apts:
            self._fit_adxrs(s.adxrs, apts)
            st.save_record(_sensors.ADXRS, s.adxrs.to_record(), kind=3)  # KIND_ADI_3POINT
            saved.append(_sensors.ADXRS)
        m = r.get("model")
        if m is not None:
            from tempcomp.store import KIND_AUGMENT

            st.save_record(m["name"], m["values"], kind=KIND_AUGMENT, frac=m["frac"])
            saved.append(m["name"])
        r["saved"] = saved

    def _report(self):
        s = self.s
        r = self.result
        print()
        print("== Result ==")
        mlx = s.mlx
        table = mlx.table if mlx is not None else None
        if mlx is not None and table is not None and "mlx" in r:
            h = mlx.health()
            print("MLX90609: re-zero %+.2f LSB (%+.3f deg/s); EEPROM: %d voted bits disagree, %d refusals" % (
                mlx.zro_shift, mlx.zro_shift / table.s0("digital"), h["vote_disagreements"], h["refusals"]))
        mpu = s.mpu
        if mpu is not None and "mpu" in r:
            g, a = r["mpu"]
            f = mpu.factory
            print("%s gyro bias x/y/z: %+.3f %+.3f %+.3f deg/s (offset registers %d %d %d)" % (
                mpu.part, -g[0] / _GYRO_REG_DPS, -g[1] / _GYRO_REG_DPS, -g[2] / _GYRO_REG_DPS, g[0], g[1], g[2]))
            print("%s accel offsets x/y/z: %d %d %d (factory %d %d %d)" % (
                mpu.part, a[0], a[1], a[2], f[0], f[1], f[2]))
        if "residual" in r:
            g, a = r["residual"]
            print("residual on the +x face: gyro %+.3f %+.3f %+.3f deg/s, accel %+.1f %+.1f %+.1f mg" % (
                g[0], g[1], g[2], a[0], a[1], a[2]))
        pts = r.get("points") or []
        if pts:
            print("temperature points:")
            for x in pts:
                line = "  %6.2f degC" % x["temp_c"]
                if "mpu" in x:
                    gy = x["mpu"][1]
                    line += "  MPU gyro bias %+.3f %+.3f %+.3f deg/s" % (
                        -gy[0] / _GYRO_REG_DPS, -gy[1] / _GYRO_REG_DPS, -gy[2] / _GYRO_REG_DPS)
                if "mlx_residual" in x:
                    line += "  MLX residual %+.3f deg/s" % x["mlx_residual"]
                if "adxrs" in x:
                    line += "  analog null %.1f mV at VT %.1f mV" % (x["adxrs"][1], x["adxrs"][0])
                print(line)
        m = r.get("model")
        if m is not None:
            print("augmented model: base + %s%s; on the board: tempcomp.augment.Augmented("
                  "tempcomp.augment.from_store(Store(%r), %r))" % (
                      ", ".join(m["effects"]) or "nothing",
                      " (not on the board: %s)" % ", ".join(m["not_on_device"]) if m["not_on_device"] else "",
                      self.store_path, m["name"]))
        print("saved to %s: %s" % (self.store_path, ", ".join(r.get("saved") or ()) or "nothing"))
        print("after a reset: import tempcomp_board, tempcomp.session; "
              "s = tempcomp.session.restore(tempcomp_board)")
