"""The figure tables of README.md and docs/, rendered from `make bench`'s record (docs/bench.json).

A page holds each table between two markers::

    <!-- figures: NAME -->
    ...the table, as rendered...
    <!-- /figures -->

and BLOCKS below holds its template: text with ``{area.key}`` fields, each a figure of the record
(``{core.apply_ratio:.2f}``; ``:kb`` for bytes as KB with one decimal, ``:k`` for thousands as
"31k", ``:,`` for thousands separators), ``{area.date}`` the date that area was measured. So what
a page shows is what a run printed: ``python -m tools bench [AREA]`` measures, writes the record
and renders the pages; ``python -m tools bench --docs`` renders them again (after editing a
template); host_tests/docs/test_figures.py fails when a page's table is not the record's.
To add a table: give the figures a key (``report(..., key=)``), write the template here, put the
markers on the page and run ``python -m tools bench --docs``.
"""

import os
import re
import textwrap

from tools import REPO

BEGIN = re.compile(r"^<!-- figures: ([\w.-]+) -->$", re.M)
END = "<!-- /figures -->"


class Figure:
    """One recorded figure, formatted by the template's spec."""

    def __init__(self, area, key, row):
        self.where = "%s.%s" % (area, key)
        self.value = row["value"]
        self.row = row

    def __format__(self, spec):
        v = self.value
        if v is None:
            return "n/a"
        if spec == "" and isinstance(v, float) and v.is_integer():
            return str(int(v))  # a count or a byte figure
        if spec == "kb":
            return "%.1f" % (v / 1024.0)
        if spec == "k":
            return "%dk" % int(round(v / 1000.0))
        if spec == "x":  # a ratio: two decimals below 10, one below 100, none above
            return "%.2f" % v if v < 10 else "%.1f" % v if v < 100 else "%.0f" % v
        return format(v, spec)

    def __str__(self):
        return self.__format__("")


class Area:
    def __init__(self, name, entry):
        self._name = name
        self._entry = entry

    def __getattr__(self, key):
        if key.startswith("_"):
            raise AttributeError(key)
        rows = self._entry.get("rows", {})
        if key in rows:
            return Figure(self._name, key, rows[key])
        if key in self._entry and key != "rows":
            return self._entry[key]
        raise Missing("%s.%s" % (self._name, key))


class Missing(KeyError):
    """A figure the template needs and the record lacks (run that area)."""


class Record(dict):
    def __init__(self, rec):
        super().__init__()
        self.rec = rec

    def __missing__(self, area):
        if area == "run":
            return self.rec.get("full_run") or {}
        if area not in self.rec.get("areas", {}):
            raise Missing("%s (the whole area)" % area)
        return Area(area, self.rec["areas"][area])


# (page, block name) -> template (a str for str.format_map, or a function of the record)
BLOCKS = {}


def render(template, rec):
    text = template(Record(rec)) if callable(template) else template.format_map(Record(rec))
    return "\n\n".join(_wrap(p) for p in text.split("\n\n"))


def _wrap(paragraph):
    # prose as the pages have it (lines of at most 100 characters); tables as they are
    if paragraph.lstrip().startswith("|"):
        return paragraph
    return textwrap.fill(" ".join(paragraph.split()), width=100, break_long_words=False, break_on_hyphens=False)


def blocks(text):
    """{name: (start, end) of the rendered text between the markers} of a page."""
    out = {}
    for m in BEGIN.finditer(text):
        end = text.find("\n" + END, m.end())
        if end < 0:
            raise ValueError("figures block %r has no %s" % (m.group(1), END))
        out[m.group(1)] = (m.end() + 1, end + 1)
    return out


def pages():
    return sorted({page for page, _ in BLOCKS})


def rendered(page, rec, strict=True):
    """The page's text with every block rendered from rec (a block whose figures the record
    lacks is left as it is unless strict)."""
    path = os.path.join(REPO, page)
    with open(path, encoding="utf-8") as f:
        text = f.read()
    found = blocks(text)
    for (p, name), template in BLOCKS.items():
        if p == page and name not in found:
            raise ValueError("%s has no figures block %r (its markers)" % (page, name))
    for name in sorted(found, key=lambda n: -found[n][0]):  # from the end: offsets stay valid
        if (page, name) not in BLOCKS:
            raise ValueError("%s: figures block %r has no template in tools/bench/figures.py" % (page, name))
        try:
            body = render(BLOCKS[(page, name)], rec).rstrip("\n") + "\n"
        except Missing:
            if strict:
                raise
            continue
        a, b = found[name]
        text = text[:a] + body + text[b:]
    return text


def write_pages(rec, strict=True):
    """Render every block of every page from rec; the pages that changed."""
    changed = []
    for page in pages():
        text = rendered(page, rec, strict)
        path = os.path.join(REPO, page)
        with open(path, encoding="utf-8") as f:
            old = f.read()
        if text != old:
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
            changed.append(page)
    return changed


def missing(rec):
    """'page: block (figure)' for each block the record cannot render yet."""
    out = []
    for (page, name), template in sorted(BLOCKS.items()):
        try:
            render(template, rec)
        except Missing as e:
            out.append("%s: %s (%s)" % (page, name, e.args[0]))
    return out


# -- the templates -----------------------------------------------------------------------------

def _kb(fig):
    return "MemoryError" if fig.value is None else "%.1f KB" % (fig.value / 1024.0)


def _n(v):
    return "{:,.0f}".format(v)


def _dates(r, areas):
    """'2026-11-25' when the areas come from the full run, else each area's own date."""
    full = r["run"].get("date")
    own = {a: r[a].date for a in areas}
    if full and all(d == full for d in own.values()):
        return full
    return ", ".join("%s %s" % (a, d) for a, d in own.items())


def measured_intro(r):
    run = r["run"]
    areas = ("core", "mlx90609", "mpu6xxx", "fit", "augment", "fleet", "store", "simgap", "ram")
    when = _dates(r, areas)
    load = ", ".join("%s %.1f" % (a, r[a].load) for a in areas)
    return (
        "From `make bench` (`docs/bench.json`, the record this table is rendered from; measured %s%s), "
        "on a %d-core %s machine, Python %s, with these load averages when each area started: %s (a "
        "load above the core count slows the host and VM rows; instruction counts and heap figures do "
        "not depend on it). Where a row says VM, the figure comes from the MicroPython 1.27 WebAssembly "
        "VM (32-bit object model), each time a ratio to a floor measured in the same run, interleaved "
        "and repeated (minimum kept); AN385 rows come from the MicroPython 1.27.0 Cortex-M3 firmware "
        "under QEMU (heap measured with `gc.mem_alloc()` after `gc.collect()`); host rows from CPython "
        "on one core."
        % (when, " in %.0f min" % run["wall_min"] if run.get("wall_min") and when == run.get("date") else "",
           r["core"].cpus, r["core"].machine, r["core"].python, load))


def measured(r):
    c, m, p, f, a, fl, st, sg, ram = (r[k] for k in ("core", "mlx90609", "mpu6xxx", "fit", "augment", "fleet",
                                                     "store", "simgap", "ram"))
    mods = [k for k in r.rec["areas"]["ram"]["rows"] if k.startswith("py_tempcomp")]
    big = ram.py_largest
    rows = [
        ("bytes allocated per compensated 3-axis sample (core, VM)",
         "**%s** (also runs under `heap_lock`)" % c.alloc, "0"),
        ("same formula with float coefficients (VM)",
         "%s B per sample: at 1 kHz a GC every ~%.1f s on 100 kB free heap (derived)" % (c.float_alloc, c.float_gc_s.value),
         "contrast"),
        ("time per compensated 3-axis sample / unpacking the 6-byte burst (VM)", "**%.2fx**" % c.apply_ratio.value, "≤ 2x"),
        ("same, temperature changing on every sample (scales varying with t: the full update)",
         "%.0fx (update the temperature at a lower rate or when it changes)" % c.update_ratio.value, "—"),
        ("worst error vs float64, all 65,536 raw codes x 9 temperatures x 3 axes",
         "**%.4f output LSB**; %.2f %% of samples equal the correctly rounded value" % (c.worst.value, c.exact_pct.value),
         "≤ 0.7 + \\|y\\| × 2^-24 on any set the set-up accepts ([the fixed-point core](#the-fixed-point-core))"),
        ("MLX90609: bytes per driver read + compensate; time vs its unpack floor (VM)",
         "%s B; %.1fx (single axis)" % (m.alloc, m.ratio.value), "—"),
        ("MLX90609: worst error vs the note's equations 3-13", "%.3f LSB (1 LSB = 1 milli-°/s)" % m.worst.value, "—"),
        ("MPU-6500: bytes per captured FIFO packet / per compensated sample (VM)",
         "%s B / %s B" % (p.alloc_packet, p.alloc_sample), "0"),
        ("MPU-6500: time per captured packet vs its 12-byte unpack floor (VM)", "%.1fx" % p.packet_ratio.value, "—"),
        ("MPU-6500: time per `read_compensated` sample vs the 14-byte unpack floor (VM; the bus read is one C call, "
         "as `machine.I2C`'s), default `temp_avg=16`: temperature steady / TEMP_OUT noise of a real log / a new "
         "temperature step on every sample",
         "**%.2fx / %.2fx / %.2fx** (`read_raw`: %.2fx); with `temp_avg=1`: %.2fx / %.2fx / %.2fx" % (
             p.comp_steady16_ratio.value, p.comp_noisy16_ratio.value, p.comp_ramp16_ratio.value, p.raw_ratio.value,
             p.comp_steady1_ratio.value, p.comp_noisy1_ratio.value, p.comp_ramp1_ratio.value), "≤ 2x"),
        ("MPU-6500: bias left after calibration, datasheet noise, 6 faces",
         "gyro %.2f LSB at ±250 dps (half a register step: 2), accel %.2f mg" % (p.bias_gyro.value, p.bias_accel.value),
         "—"),
        ("AN12760 3-axis / ADXRS rate / cross-axis (constant; temperature law updated every sample): bytes per "
         "sample (VM)", "%s / %s / %s; %s B" % (f.vm_an12760_3axis_new_t_alloc, f.vm_adxrs_rate_alloc,
                                                f.vm_crossaxis_alloc, f.vm_crossaxis_law_new_t_alloc), "0"),
        ("AN12760 fixed point vs float; cross-axis correction (constant; cubic temperature law)",
         "%.4f LSB; %.2f; %.2f LSB" % (f.an12760_worst_error.value, f.crossaxis_worst_error.value,
                                        f.crossaxis_law_worst_error.value), "—"),
        ("augmented model, every term on (VM): bytes per sample; worst / RMS error vs float64",
         "%s B; %.2f / %.2f output LSB ([per-term cost](#from-a-log-to-the-board-the-augmented-model))"
         % (a.alloc, a.worst.value, a.rms.value), "0"),
        ("six-position fit of 10,000 units (3 temps x 6 orientations x 3 axes x 200 samples), one core",
         "%.1f s" % f.fit_sixpos_10000_units.value, "< 60 s"),
        ("fleet through the command line: 10,000 six-position units, one CSV each (360 rows), read + fit + device "
         "check + summary + JSON, one core", "%.1f s CPU (%.0f units/s)" % (fl.cpu_s.value, fl.units_per_s.value),
         "< 60 s"),
        ("store: 4 sensors x 24 values (VM)",
         "%s bytes; save %s ms, load %s ms (one call each, the VM's millisecond clock); lookups %s B" % (
             st.store_image_4_sensors_x_24_values, st.store_save_vm_in_memory_fs, st.store_load_of_4_records_vm,
             st.store_get_into_allocation), "—"),
        ("sim-to-real gap, read + diagnose, one core, one BLAS thread: 20k + 20k / 200k + 200k / 1M + 1M rows",
         "%.1f s, %.0f MB / %.1f s, %.0f MB / %.1f s, %.0f MB (long logs are diagnosed on every k-th row; the JSON "
         "states k in `rows.stride`)" % (
             sg.rows_20000_s.value, sg.rows_20000_mb.value, sg.rows_200000_s.value, sg.rows_200000_mb.value,
             sg.rows_1000000_s.value, sg.rows_1000000_mb.value), "< 60 s, < 1.5 GB at 1 M"),
        ("AN385 (Cortex-M3, ~140 KB heap): every module imported from `.py`",
         "%s fit; the largest, `%s`, %s" % (
             "all %d" % len(mods) if ram.py_imports.value == len(mods) else "%s of %d" % (ram.py_imports, len(mods)),
             big.value.split(".")[-1], big.row["unit"]),
         "all import"),
        ("AN385: `import tempcomp.session` from `.mpy` / frozen",
         "**%s** / %s (was 73-79 KB)" % (_kb(ram.session_mpy), _kb(ram.session_frozen)), "≤ 40 KB"),
        ("AN385: boot restoring one MPU-6500's offset registers from the store, then reads, `.mpy` / frozen",
         "**%s** / %s ([docs/ram.md](docs/ram.md))" % (_kb(ram.boot_registers_mpy), _kb(ram.boot_registers_frozen)),
         "≤ 24 KB"),
        ("AN385: the same boot with software offset(T) resumed from record `mpu_tcc` (`compensate(mpu_tcc, mpu_tc)`), "
         "`.mpy` / frozen", "**%s** / %s (was 52 KB rebuilding the `BiasModel` at boot)" % (
             _kb(ram.boot_tcc_mpy), _kb(ram.boot_tcc_frozen)), "≤ 24 KB"),
        ("AN385: the same records read from the store's const() export (`calib_const.py`), `.mpy` / frozen",
         "**%s** / %s" % (_kb(ram.boot_const_mpy), _kb(ram.boot_const_frozen)), "≤ 24 KB"),
        ("AN385: the same through the convenience `tempcomp.sensors.restore(board)`, `.mpy` / frozen",
         "%s%s / %s" % (_kb(ram.boot_sensors_mpy), _over(ram.boot_sensors_mpy, 24), _kb(ram.boot_sensors_frozen)),
         "≤ 24 KB"),
        ("AN385: software offset(T) rebuilt at boot (`compensate(BiasModel.from_ints(...))`), `.mpy` / frozen",
         "%s%s / %s (the fixed-point set-up and its exact fit; use `mpu_tcc`)" % (
             _kb(ram.boot_model_mpy), _over(ram.boot_model_mpy, 24), _kb(ram.boot_model_frozen)), "≤ 24 KB"),
    ]
    out = ["| figure | value | target |", "|---|---|---|"]
    out += ["| %s | %s | %s |" % row for row in rows]
    return "\n".join(out)


def _over(fig, budget_kb):
    v = fig.value
    if v is None or v <= budget_kb * 1024:
        return ""
    return " (**over budget** by %.1f KB)" % ((v - budget_kb * 1024) / 1024.0)


def instructions_intro(r):
    return (
        "`python -m tools bench instructions` (part of `make bench`; rendered from `docs/bench.json`), "
        "measured %s: MicroPython 1.27.0 firmware on QEMU 7.2 `mps2-an385` (Cortex-M3) and `mps2-an500` "
        "(Cortex-M7) with `-icount shift=0`, where the emulated clock advances 1 ns per executed "
        "instruction, so `time.ticks_us()` over n calls counts instructions (the host's load does not "
        "change them)." % r["instructions"].date)


def instructions(r):
    from tools.bench.instructions import README_ROWS

    i = r["instructions"]
    out = ["| instructions per call | Cortex-M3 | Cortex-M7 |", "|---|---:|---:|"]
    for key, label in README_ROWS:
        cells = []
        for board in ("an385", "an500"):
            v = getattr(i, "%s_%s" % (board, key)).value
            c = "-" if v is None else _n(v)
            cells.append("**%s**" % c if label.startswith("**") else c)
        out.append("| %s | %s |" % (label, " | ".join(cells)))
    return "\n".join(out)


def instructions_after(r):
    i, pico = r["instructions"], r["pico"]

    def m3(k):
        return getattr(i, "an385_" + k).value

    def m7(k):
        return getattr(i, "an500_" + k).value

    from tools.bench.instructions import BATCH

    return (
        "A compensated 3-axis sample costs %.2fx the careful float code and %.3fx the naive one on the "
        "Cortex-M3, and allocates nothing (the float versions allocate on every call); forced to pure Python it "
        "costs %.2fx a typical driver's float sample on the Cortex-M3 and %.2fx on the Cortex-M7 with its "
        "double-precision FPU (its frame fits the VM's 11 words on the C stack: 6,305 before, when unpacking 11 "
        "numbers into locals took the frame from the heap on every call). The batch is one `asm_thumb` call that "
        "checks the buffers itself and runs the loop: %s per sample at %d a call (152 before, with the checks in a "
        "`@micropython.native` method; on the Pico's M0+ %s cycles, its fixed cost %s cycles a call and its loop %s "
        "per sample). The per-temperature `update(t)` with scales that vary with t is the expensive step (about %s "
        "instructions; 124,000 before the quick division and the inline Horner steps): call it when the "
        "temperature changes, or every n-th sample (`temp_every`), not on every sample. With constant scales (the "
        "MPU-6xxx) it is Horner only, and `read_compensated` runs it at most once per block of `temp_avg` "
        "temperature readings (default 16): with a new temperature step on every sample it costs %.2fx `read_raw` "
        "on the Cortex-M3 (%.2fx with `temp_avg=1`, where every sample pays for the update; 244,000 instructions "
        "before this work), %.2fx with the temperature steady. `read_raw` itself costs %.2fx the 14-byte unpack "
        "floor (the replay bus: a Python method around one C call, standing in for `machine.I2C`'s)."
        % (m3("apply_be16") / m3("float_careful"), m3("apply_be16") / m3("float_naive"),
           m3("apply_be16_pure") / m3("float_driver"), m7("apply_be16_pure") / m7("float_driver"),
           _n(m3("apply_be16_n")), BATCH, _n(pico.cycles_apply_be16_n.value), _n(pico.cycles_batch_fixed.value),
           _n(pico.cycles_batch_loop.value), _n(round(m3("update"), -2)), m3("read_compensated") / m3("read_raw"),
           m3("read_compensated_avg1") / m3("read_raw"), m3("read_compensated_steady") / m3("read_raw"),
           m3("read_raw") / m3("unpack14")))


def instructions_heap(r):
    i = r["instructions"]
    return (
        "In the table, `read_compensated` with the temperature steady costs %s instructions after a "
        "collection, %s with 50 KB more live data on the heap, and %s with the loop under `heap_lock()`."
        % (_n(i.an385_read_compensated_steady.value), _n(i.an385_read_compensated_steady_live.value),
           _n(i.an385_read_compensated_steady_locked.value)))


SHRINK = (("temp_rate", "temp_rate (die lags the reading, tau 150 s)"), ("hysteresis", "hysteresis (backlash 4 degC)"),
          ("drift", "drift (80 LSB, tau 400 s)"), ("supply", "supply (120 LSB/V)"),
          ("g_sensitivity", "g_sensitivity (25/-15/10 LSB/g)"), ("cross_axis", "cross_axis (1.2 % and -0.8 %)"))


def augment_shrink(r):
    a = r["augment"]
    out = ["| effect | sim alone | augmented | ratio (host) |", "|---|---|---|---|"]
    for key, label in SHRINK:
        out.append("| %s | %.3f | %.3f | %.3f (%.3f) |" % (
            label, getattr(a, "shrink_%s_base" % key).value, getattr(a, "shrink_%s_aug" % key).value,
            getattr(a, "shrink_%s_ratio" % key).value, getattr(a, "shrink_%s_host" % key).value))
    return "\n".join(out)


# "before this version" (the pure-Python per-sample path, docs/augment.md): history, not this record's
_AUG_BEFORE = {"base": "30,820 / 114,380", "temp_rate": "+59,915", "hysteresis": "+29,960", "drift_exp": "+16,865",
               "drift_hyperbolic": "+9,580", "supply": "+25,865", "g_sensitivity": "+21,225", "cross_axis": "+54,480",
               "every": "210,150 / 333,175"}
_AUG_TERMS = (("temp_rate", "temp_rate"), ("hysteresis", "hysteresis"), ("drift_exp", "drift (exp)"),
              ("drift_hyperbolic", "drift (hyperbolic)"), ("supply", "supply"), ("g_sensitivity", "g_sensitivity"),
              ("cross_axis", "cross_axis"))


def _v(a, key):
    return getattr(a, key).value


def augment_cost(r):
    """README's cost table of the augmented model (tools/bench/augment.py, Cortex-M3 instructions)."""
    a = r["augment"]
    pl = _v(a, "m3_plain")
    rows = ["| per 3-axis sample, Cortex-M3 instructions | reading unchanged | reading changing every sample | "
            "per sample of a burst of 32 | before the kernels: unchanged / changing |", "|---|---:|---:|---:|---:|",
            "| base model (target <= 1.5x the plain sample) | %s (%.2fx) | %s | %s | %s |" % (
                _n(_v(a, "m3_base")), _v(a, "m3_base") / pl, _n(_v(a, "m3_base_t")), _n(_v(a, "m3_base_b")),
                _AUG_BEFORE["base"])]
    for k, label in _AUG_TERMS:
        rows.append("| + %s, extra | +%s | +%s | +%s | %s |" % (
            label, _n(_v(a, "m3_extra_" + k)), _n(_v(a, "m3_extra_%s_t" % k)), _n(_v(a, "m3_extra_%s_b" % k)),
            _AUG_BEFORE[k]))
    rows += ["| every term (targets: <= 8,000 changing, <= 2,000 in a burst) | %s | %s | %s | %s |" % (
                 _n(_v(a, "m3_every")), _n(_v(a, "m3_every_t")), _n(_v(a, "m3_every_b")), _AUG_BEFORE["every"]),
             "| every term, pure Python forced (`augment.use_native(False)`) | %s | %s | | the only path |" % (
                 _n(_v(a, "m3_every_pure")), _n(_v(a, "m3_every_pure_t"))),
             "| float anchor (careful float code): base / every term | %s / %s | %s / %s | | |" % (
                 _n(_v(a, "m3_base_float")), _n(_v(a, "m3_every_float")), _n(_v(a, "m3_base_float_t")),
                 _n(_v(a, "m3_every_float_t")))]
    intro = ("Per-sample cost on the Cortex-M3 firmware, from `python -m tools bench augment` (%s; executed "
             "instructions under qemu -icount, the least of 5 heap layouts, each loop after `gc.collect()`, every "
             "argument a local and `aug.apply(...)` called directly), beside the plain compensator's sample with the "
             "same base model (`Compensator.apply_be16`: %s instructions into a list, %s into an `array('i')`) and a "
             "careful float implementation of the same model:" % (a.date, _n(pl), _n(_v(a, "m3_plain_arr"))))
    after = ("The native kernels (a viper `apply`, the base's per-reading step and `apply_be16_n`, an `asm_thumb` "
             "body for a sample with terms and for the terms' share of a new reading's step, Thumb-1 only, so the "
             "Pico's M0+ runs it too) give the pure path's numbers bit for bit on every interpreter; the work is done "
             "as rarely as its inputs change (the base gain, rho, dT's terms and the cross matrix once per new "
             "reading). With the terms' step still in viper (2026-11-27), a changing reading cost temp_rate +1,590 "
             "and cross_axis +1,525 over the base, every term 7,395. Heap: the module %s (.mpy; fixedpoint %s more), the first "
             "model, which imports the native kernels, %s, a second with every term %s; %s bytes allocated per sample "
             "and per burst (heap-locked in the VM and on the firmware); worst error against float64 with every term "
             "%.2f output LSB (RMS %.2f). Details, the burst call and the arrays the kernels take: "
             "[docs/augment.md](docs/augment.md)." % (
                 _kb(a.ram_module), _kb(a.ram_fixedpoint), _kb(a.ram_first), _kb(a.ram_second), a.alloc,
                 _v(a, "worst"), _v(a, "rms")))
    return intro + "\n\n" + "\n".join(rows) + "\n\n" + after


def augment_cost_page(r):
    """docs/augment.md's cost table and heap line."""
    a = r["augment"]
    worst = max(_AUG_TERMS, key=lambda t: _v(a, "m3_extra_" + t[0]))
    rows = ["| per 3-axis sample, Cortex-M3 instructions | reading unchanged | reading changing every sample | "
            "per sample of a burst of 32 |", "|---|---:|---:|---:|",
            "| plain `Compensator.apply_be16`, into a list / an `array('i')` | %s / %s | | %s (`apply_be16_n`) |" % (
                _n(_v(a, "m3_plain")), _n(_v(a, "m3_plain_arr")), _n(_v(a, "m3_plain_b"))),
            "| base model through `Augmented` | %s (%.2fx) | %s | %s |" % (
                _n(_v(a, "m3_base")), _v(a, "m3_base") / _v(a, "m3_plain"), _n(_v(a, "m3_base_t")),
                _n(_v(a, "m3_base_b"))),
            "| largest single term's extra (%s; target <= 1,500) | +%s | +%s | +%s |" % (
                worst[1], _n(_v(a, "m3_extra_" + worst[0])), _n(_v(a, "m3_extra_%s_t" % worst[0])),
                _n(_v(a, "m3_extra_%s_b" % worst[0]))),
            "| every term | %s | %s | %s |" % (_n(_v(a, "m3_every")), _n(_v(a, "m3_every_t")), _n(_v(a, "m3_every_b"))),
            "| every term, pure Python (`use_native(False)`) | %s | %s | |" % (
                _n(_v(a, "m3_every_pure")), _n(_v(a, "m3_every_pure_t"))),
            "| every term, float anchor | %s | %s | |" % (_n(_v(a, "m3_every_float")), _n(_v(a, "m3_every_float_t")))]
    return ("Measured %s:" % a.date) + "\n\n" + "\n".join(rows) + "\n\n" + (
        "Heap (Cortex-M3, `.mpy` executed in place): the module %s (fixedpoint %s more); the first model, which "
        "imports the native kernels, %s; a second with every term %s; %s bytes allocated per sample; worst error "
        "against float64 with every term %.2f output LSB (RMS %.2f, in the VM)." % (
            _kb(a.ram_module), _kb(a.ram_fixedpoint), _kb(a.ram_first), _kb(a.ram_second), a.alloc, _v(a, "worst"),
            _v(a, "rms")))


def augment_shrink_words(r):
    a = r["augment"]
    return ("host / board, effect axis x: " + ", ".join(
        "%s %.3f / %.3f" % (key, getattr(a, "shrink_%s_host" % key).value, getattr(a, "shrink_%s_ratio" % key).value)
        for key, _ in SHRINK) + " (`python -m tools bench augment`, %s; `host_tests/augment/test_export_replay.py` "
        "recomputes them)." % a.date)


def simgap_speed(r):
    s = r["simgap"]
    out = ["| rows (training + withheld) | read + diagnose | rows/s | peak memory |", "|---|---|---|---|"]
    for n, label in ((20000, "20,000 + 20,000"), (200000, "200,000 + 200,000"), (1000000, "1,000,000 + 1,000,000")):
        out.append("| %s | %.1f s | %s | %.0f MB |" % (label, getattr(s, "rows_%d_s" % n).value,
                                                       _n(getattr(s, "rows_%d_per_s" % n).value),
                                                       getattr(s, "rows_%d_mb" % n).value))
    return "\n".join(out) + "\n\n(`python -m tools bench simgap`, %s, load average %.1f at its start.)" % (s.date, s.load)


def ram_targets(r):
    ram = r["ram"]
    rows = ram._entry["rows"]
    mods = [k[3:] for k in rows if k.startswith("py_tempcomp")]
    big = sorted(mods, key=lambda m: -(rows["py_" + m]["value"] or 0))[:2]

    def met(fig, budget_kb):
        v = fig.value
        if v is None:
            return "**not met** (MemoryError)"
        spare = budget_kb - v / 1024.0
        return ("met, with %.1f KB to spare" % spare) if spare >= 0 else ("**not met** (%.1f KB over)" % -spare)

    out = ["| target | figure | |", "|---|---|---|",
           "| every module imports from `.py` on the 140 KB heap | %s (largest: `%s` %s, `%s` %s) | %s |" % (
               "all %d" % len(mods) if ram.py_imports.value == len(mods) else "%s of %d" % (ram.py_imports, len(mods)),
               big[0], _kb(getattr(ram, "py_" + big[0])), big[1],
               _kb(getattr(ram, "py_" + big[1])), "met" if ram.py_imports.row.get("ok") else "**not met**"),
           "| `import tempcomp.session` <= 40 KB from `.mpy` | %s | %s |" % (_kb(ram.session_mpy), met(ram.session_mpy, 40)),
           "| boot path <= 24 KB from `.mpy`: offset registers restored (the part subtracts them itself), raw reads, "
           "`check(every_ms=)` | %s | %s |" % (_kb(ram.boot_registers_mpy), met(ram.boot_registers_mpy, 24)),
           "| the same with software offset(T) resumed from record `mpu_tcc` (`compensate(mpu_tcc, mpu_tc)`, "
           "`read_compensated`) | %s | %s |" % (_kb(ram.boot_tcc_mpy), met(ram.boot_tcc_mpy, 24)),
           "| the same through `tempcomp.sensors.restore` (it resumes `mpu_tcc` when the store has it) | %s | %s |" % (
               _kb(ram.boot_sensors_mpy), met(ram.boot_sensors_mpy, 24)),
           "| the same records read from the store's const() export `calib_const.py` instead of the store (below) "
           "| %s | %s |" % (_kb(ram.boot_const_mpy), met(ram.boot_const_mpy, 24)),
           "| software offset(T) rebuilt from the model at boot (`compensate(BiasModel.from_ints(...))`) | %s | %s |" % (
               _kb(ram.boot_model_mpy), met(ram.boot_model_mpy, 24)),
           "| `import tempcomp.session`, frozen into the firmware | %s | %s |" % (
               _kb(ram.session_frozen), met(ram.session_frozen, 40)),
           "| boot paths frozen into the firmware | %s (registers), %s (offset(T) from `mpu_tcc`), %s "
           "(`calib_const.py`), %s (offset(T) rebuilt from the model), %s (`sensors.restore`) | %s |" % (
               _kb(ram.boot_registers_frozen), _kb(ram.boot_tcc_frozen), _kb(ram.boot_const_frozen),
               _kb(ram.boot_model_frozen), _kb(ram.boot_sensors_frozen),
               "within 24 KB" if all(getattr(ram, "boot_%s_frozen" % b).row.get("ok") for b in
                                     ("registers", "tcc", "const", "model", "sensors")) else "**not all within 24 KB**")]
    return "Figures of `python -m tools bench ram`, %s (rendered from `docs/bench.json`):\n\n%s" % (
        ram.date, "\n".join(out))


_STEP_NOTES = ("`sensors` module (the driver's own path skips it)", "store reader, `store` and `store_format`",
               "driver, `bus` (I2C), parts table", "fixed-point core",
               "`BiasModel` with its exact fit, its set-up (`compensators()`), `compiled()`, and the offset registers' "
               "units and clamps (`mpu6xxx_units`)", "records, driver buffers", "the fitted model",
               "two 3-axis Compensators and their native kernels")


def ram_steps(r):
    rows = r["ram"]._entry["rows"]
    out = ["| step | heap kept | of which |", "|---|---:|---|"]
    prev = 0
    k = 1
    while "steps_model_%d" % k in rows:
        row = rows["steps_model_%d" % k]
        name = row["name"].split("cumulative: ", 1)[1]
        note = _STEP_NOTES[k - 1] if k - 1 < len(_STEP_NOTES) else ""
        out.append("| %s | %.1f KB | %s: %.1f KB |" % (_code_words(name), row["value"] / 1024.0, note,
                                                      (row["value"] - prev) / 1024.0))
        prev = row["value"]
        k += 1
    return "\n".join(out)


def _code_words(step):
    # the bench's step label with its code in backticks: "+ `import tempcomp.store`", "`restore(store)`"
    return re.sub(r"(import [\w.]+|[\w.]+\([\w, ]*\)|BiasModel\.from_ints|read_compensated)", r"`\1`", step)


def ram_modules(r):
    rows = r["ram"]._entry["rows"]
    out = ["| module | `.py` | `.mpy` |", "|---|---:|---:|"]
    for k in rows:
        if k.startswith("py_tempcomp"):
            m = k[3:]
            py, mp = rows[k]["value"], rows["mpy_" + m]["value"]
            out.append("| `%s` | %s | %s |" % (m, "MemoryError" if py is None else "%.1f KB" % (py / 1024.0),
                                               "MemoryError" if mp is None else "%.1f KB" % (mp / 1024.0)))
    return "One run of `python -m tools bench ram`, %s (`tools.bench.ram.measure_import`):\n\n%s" % (
        r["ram"].date, "\n".join(out))


def gapcheck(r):
    g = r["gapcheck"]

    def f(key):
        return "%s/%s" % (getattr(g, "full_" + key), getattr(g, "full_%s_n" % key))

    reduced = all(getattr(g, "reduced_" + k).row.get("ok") for k in ("singles", "pairs", "nones", "where", "shrink"))
    return (
        "Blind benchmark (`make gap-check`, %s cases, seed 1; `python -m tools bench gapcheck`, %s): every single "
        "effect named first (%s), both effects of every pair (%s), nothing claimed on the no-effect cases (%s), "
        "\"where\" by excess over the floor right in %s, final withheld RMS within 25 %% of the true noise in %s "
        "(worst %.2fx); the reduced set (%s cases, which the tests run at a seed drawn per run) at seed 7 %s." % (
            g.full_where_n, g.date, f("singles"), f("pairs"), f("nones"), f("where"), f("shrink"),
            g.full_worst_ratio.value, g.reduced_where_n,
            "meets every target too" if reduced else "misses a target (see `python -m tools bench gapcheck`)"))


def pico(r):
    """README's virtual-Pico table and the paragraph under it (tools/bench/pico.py)."""
    p = r["pico"]

    def c(key):
        return _n(getattr(p, key).value)

    spread = max(1, 150 // p.cut_ops.value) * p.cut_ops.value
    total = p.cut_old.value + p.cut_new.value + p.cut_wrong.value
    rows = ["| cycles per call, RP2040 (Cortex-M0+, 125 MHz) | value | target |", "|---|---:|---|",
            "| 3-axis `apply_be16` (native kernels, `native_m0.mpy`) | %s | <= 2,000 |" % c("cycles_apply_be16"),
            "| same, forced pure Python (what CircuitPython boards run), %s bytes | %s | no slower than the float "
            "anchor |" % (p.alloc_apply_be16_pure, c("cycles_apply_be16_pure")),
            "| batch `apply_be16_n`, per sample (32 per call) | %s | <= 150 |" % c("cycles_apply_be16_n"),
            "| its fixed cost per call (the argument checks and the calls) | %s | |" % c("cycles_batch_fixed"),
            "| its loop, per sample | %s | |" % c("cycles_batch_loop"),
            "| batch, forced pure Python, per sample | %s | |" % c("cycles_apply_be16_n_pure"),
            "| **anchor: a typical driver's float 3-axis sample** (`struct.unpack`, `(raw - offset) * scale` per "
            "axis), %s bytes | **%s** | |" % (p.alloc_float_driver, c("cycles_float_driver")),
            "| its offset and scale polynomials, per temperature reading | %s | |" % c("cycles_float_driver_update"),
            "| anchor: naive float, both polynomials on every sample | %s | |" % c("cycles_float_naive"),
            "| anchor: careful float (polynomials once per temperature, no `struct`) | %s | |" % c("cycles_float_careful"),
            "| augmented model (`augment_native_m0` + `augment_thumb`), base, reading unchanged / changing every "
            "sample | %s / %s | |" % (c("aug_base_c"), c("aug_base_t")),
            "| same, per sample of a burst of 32 | %s | |" % c("aug_base_b"),
            "| augmented model, every term on, reading unchanged / changing every sample | %s / %s | |" % (
                c("aug_every_c"), c("aug_every_t")),
            "| same, per sample of a burst of 32 | %s | |" % c("aug_every_b"),
            "| its float anchor (careful float code), every term, reading unchanged / changing | %s / %s | |" % (
                c("aug_every_float"), c("aug_every_float_t")),
            "| augmented model forced to pure Python, every term, reading unchanged / changing | %s / %s | |" % (
                c("aug_every_c_pure"), c("aug_every_t_pure")),
            "| MPU-6xxx `read_raw` through the real I2C at 400 kHz | %s | |" % c("cycles_real_read_raw"),
            "| MPU-6xxx `read_compensated` through the real I2C (%.2fx `read_raw`) | %s | <= 2x |" % (
                p.real_ratio.value, c("cycles_real_read_compensated")),
            "| same, loop under `heap_lock()` (0 bytes allocated) | %s | 0 B |" % c("cycles_real_read_compensated_locked")]
    intro = ("Cycles on the virtual Pico (`python -m tools bench pico`, rendered from `docs/bench.json`; measured %s "
             "on a %d-core machine, load average %.1f at its start, which does not change simulated cycles; net of "
             "the empty loop, each loop after `gc.collect()`; the instruction bench's and the augment bench's "
             "set-ups):" % (p.date, p.cpus, p.load))
    after = ("The pure-Python sample costs %.2fx the typical driver's float sample (which allocates %s bytes of "
             "floats each time): its frame now fits the VM's 11 words on the C stack, where unpacking its 11 numbers "
             "into locals took the frame from the heap on every call (12,698 cycles before after a collection, up to "
             "23,805 on a fuller heap). The batch's one `asm_thumb` call checks the buffers itself (type, length and "
             "items read from the objects) and runs a %s-cycle loop; before, a `@micropython.native` method did the "
             "checks and dispatch in about 5,900 cycles a call (276 per sample). The augmented model's base sample "
             "costs %.2fx the plain `apply_be16`, and every term with the reading changing %.3fx its float anchor; "
             "samples and bursts %s under `heap_lock()`. Heap at boot: %.1f KB free of %.0f KB; `import "
             "tempcomp_board, tempcomp.sensors` takes %.1f KB. Power cuts through a store save (%s flash "
             "operations), %s points (%s spread through the operations, %s at random cycles), each followed by a "
             "reboot: %s restored the old calibration, %s the new, %s (%.0f s for the whole bench area)." % (
                 p.pure_vs_driver.value, p.alloc_float_driver, c("cycles_batch_loop"), p.aug_base_vs_plain.value,
                 p.aug_every_t_vs_float.value, "ran" if p.aug_locked.row.get("ok") else "did **not** run",
                 p.heap_free.value / 1024.0, p.heap_total.value / 1024.0, p.heap_import.value / 1024.0, p.cut_ops,
                 total, spread, total - spread, p.cut_old, p.cut_new,
                 "none a wrong or lost one" if p.cut_wrong.value == 0 else "**%s a wrong or lost one**" % p.cut_wrong,
                 p.wall_s))
    return intro + "\n\n" + "\n".join(rows) + "\n\n" + after


BLOCKS.update({
    ("README.md", "gapcheck"): gapcheck,
    ("README.md", "measured-intro"): measured_intro,
    ("README.md", "measured"): measured,
    ("README.md", "instructions-intro"): instructions_intro,
    ("README.md", "instructions"): instructions,
    ("README.md", "instructions-after"): instructions_after,
    ("README.md", "instructions-heap"): instructions_heap,
    ("README.md", "pico"): pico,
    ("README.md", "augment-shrink"): augment_shrink,
    ("README.md", "augment-cost"): augment_cost,
    ("docs/augment.md", "augment-shrink-words"): augment_shrink_words,
    ("docs/augment.md", "augment-cost"): augment_cost_page,
    ("docs/simgap.md", "simgap-speed"): simgap_speed,
    ("docs/ram.md", "ram-targets"): ram_targets,
    ("docs/ram.md", "ram-steps"): ram_steps,
    ("docs/ram.md", "ram-modules"): ram_modules,
})
