"""The virtual Raspberry Pi Pico (tools/pico): cycles per 3-axis sample on the RP2040 (Cortex-M0+,
125 MHz, rp2040js's cycle counts), boot heap on the Pico's own heap, and power cuts through a store
save.

The compensation scripts are the instruction bench's (tools/bench/instructions.py: the same set-up,
loops net of the empty loop, best of 3 after gc.collect()), run on the real rp2 firmware with
tempcomp deployed as ``make deploy`` installs it; simulated time is exact, so ``ticks_us()`` over n
calls gives 125 cycles per microsecond. ``read_compensated`` and ``read_raw`` go through the real
I2C peripheral (400 kHz, each byte's time on the wire) to the simulated MPU-6500. The augmented
model's rows run tools/bench/augment.py's firmware script (base model, every term on) on the
library as it is in this tree. The power-cut
sweep cuts a store save at >= 200 points spread through its flash operations and reboots after
each (tools/pico/cut.mjs); every restore must give the old or the new calibration.
"""

import json
import random
import time

from tools.bench import instructions

CYCLES_PER_NS = 0.125

MPU_REAL = r"""
import micropython
from array import array
import tempcomp_board as b
from tempcomp.mpu6xxx import MPU6xxx
from tempcomp.mpu6xxx_tc import BiasModel
floor()
imu = MPU6xxx(b.i2c())
t0 = imu.temp_raw()
imu.compensate(BiasModel([(t0 - 2000, (10.5, -20.25, 3.0), (1000.0, -501.5, 2300.0)),
                          (t0, (12.0, -19.0, 2.5), (1004.0, -498.0, 2296.5)),
                          (t0 + 2000, (14.5, -17.0, 1.0), (1010.0, -493.0, 2290.0))]))
out = array("i", [0] * 7)
raw = array("i", [0] * 7)
insn("real_read_raw", imu.read_raw, (raw,), 200)
insn("real_read_compensated", imu.read_compensated, (out,), 200)
def locked(fn, a, n):
    # the loop in a function: its names are locals on the C stack. At module level each name is a
    # key of the script's globals table, and a new one stored under heap_lock() (the time
    # difference, say) raises MemoryError when that table is full and must grow; the unlock
    # in finally, because a heap left locked kills the rp2 firmware at its next soft reset
    micropython.heap_lock()
    try:
        i = 0
        t0 = time.ticks_us()
        while i < n:
            fn(a)
            i += 1
        return time.ticks_diff(time.ticks_us(), t0)
    finally:
        micropython.heap_unlock()
gc.collect()
d = locked(imu.read_compensated, out, 200)
print("INSN real_read_compensated_locked %.1f 1" % (d * 1000.0 / 200))
"""

# the batch's fixed cost per call and its loop per sample: one sample a call and 64 (the
# instruction bench's set-up)
BATCH_SPLIT = r"""
from tempcomp import fixedpoint as fp
floor()
c = fp.Compensator(%(offs)r, %(scs)r, %(t_cal)r, out_scale=1000.0)
c.update(1234)
for n in (1, 64):
    buf = bytearray(b"\x80\x00\x12\x34\x7f\xff" * n)
    out = [0] * (3 * n)
    insn("batch_call_%%d" %% n, c.apply_be16_n, (buf, out, n), 100)
"""

BOOT_HEAP = r"""
import gc
gc.collect()
f0 = gc.mem_free()
a0 = gc.mem_alloc()
import tempcomp_board
from tempcomp import sensors
gc.collect()
print("HEAP", f0 + a0, f0, gc.mem_alloc() - a0)
"""

STORE_SETUP = ("from tempcomp import store\nst = store.Store('/cut.cal')\nst.save('gyro0', (1, 2, 3))\n"
               "st.save('mlx', tuple(range(24)))\nprint(st.load('gyro0'))\n")
STORE_SAVE = "from tempcomp import store\nst = store.Store('/cut.cal')\nst.save('gyro0', (4, 5, 6))\n"
STORE_CHECK = "from tempcomp import store\nst = store.Store('/cut.cal')\nprint(st.load('gyro0'), st.load('mlx'))\n"

ROWS = [
    ("empty_loop", "empty loop (per pass; subtracted from every row)"),
    ("apply_be16", "3-axis compensated sample, apply_be16 (native kernels)"),
    ("apply_be16_pure", "same, forced pure Python"),
    ("apply_be16_n", "batch apply_be16_n, per sample (32 per call)"),
    ("batch_fixed", "  its fixed cost per call (argument checks, the calls)"),
    ("batch_loop", "  its loop, per sample"),
    ("apply_be16_n_pure", "batch, forced pure Python, per sample"),
    ("float_driver", "anchor: a typical driver's float 3-axis sample"),
    ("float_driver_update", "  its per-temperature polynomials"),
    ("float_naive", "anchor: naive float, both polynomials per sample"),
    ("float_careful", "anchor: careful float 3-axis sample"),
    ("real_read_raw", "MPU-6xxx read_raw through the real I2C (400 kHz)"),
    ("real_read_compensated", "MPU-6xxx read_compensated through the real I2C"),
    ("real_read_compensated_locked", "same, the loop under heap_lock()"),
]


AUG_ROWS = [
    ("c", "augmented model, %s, reading unchanged"),
    ("t", "  same, the temperature reading changing every sample"),
    ("b", "  same, per sample of a burst of 32 (apply_be16_n)"),
    ("c_pure", "  forced pure Python, reading unchanged"),
    ("t_pure", "  forced pure Python, reading changing"),
    ("float", "  its float anchor (careful float code), reading unchanged"),
    ("float_t", "  its float anchor, reading changing"),
]

ALLOC_ROWS = [
    ("apply_be16", "heap per call, apply_be16 (native)"),
    ("apply_be16_pure", "heap per call, apply_be16 pure Python"),
    ("float_driver", "heap per call, the typical driver's float sample"),
]


def measure(pico):
    got = {}
    setup = dict(offs=instructions.OFFS, scs=instructions.SCS, t_cal=instructions.T_CAL, batch=instructions.BATCH)
    for code in (instructions.HARNESS + instructions.CORE % setup, instructions.HARNESS + BATCH_SPLIT % setup,
                 instructions.HARNESS + MPU_REAL):
        net, extra = instructions.parse(pico.run(code, timeout=1800))
        got.update({k: v * CYCLES_PER_NS for k, v in net.items()})
        got.update({k: v for k, v in extra.items() if k.startswith("ALLOC ")})
    if "batch_call_1" in got:
        got["batch_loop"] = (got["batch_call_64"] - got["batch_call_1"]) / 63
        got["batch_fixed"] = got["batch_call_1"] - got["batch_loop"]
    return got


def augmented(pico):
    """{name: {key: cycles per 3-axis sample}} of the augmented model on the Pico, base and every
    term on: tools/bench/augment.py's firmware script (its keys: c / t the reading unchanged /
    changing every sample, b per sample of a burst, *_pure forced to pure Python, float / float_t
    its float anchor, plain the plain apply_be16; lock 'ok' when samples and bursts ran under
    heap_lock()), on the library as it is in this tree."""
    from tools.bench import augment

    res = {}
    for name, m in (("base", augment.model([])), ("every term", augment.model(list(augment.TERMS)))):
        out = pico.run("import json\n" + augment.FW_BENCH % {
            "model": json.dumps(m), "name": name, "n": 200, "pad": 0, "batch": augment.BATCH,
            "modes": [None, False], "anchor": 1, "float_model": augment.FLOAT_MODEL}, timeout=1800)
        line = [ln for ln in out.splitlines() if ln.startswith("INSN ")][0]
        res[name] = {k: (v * CYCLES_PER_NS if k != "lock" else v) for k, v in json.loads(line[5:]).items()}
    return res


def sweep(pico, n=200, seed=1):
    from tools.board import picoctl
    ref = picoctl.cut_sweep(pico.flash, STORE_SETUP, STORE_SAVE, STORE_CHECK, [])["reference"]
    ops = ref["ops"]
    rng = random.Random(seed)
    # evenly through every flash operation of the save, plus random cycles over the whole save
    per = max(1, (n * 3 // 4) // len(ops))
    cuts = [{"op": k, "frac": (i + 0.5) / per} for k in range(len(ops)) for i in range(per)]
    cuts += [{"cycle": rng.randrange(ops[0]["start"], ref["cycles"])} for _ in range(n - len(cuts))]
    res = picoctl.cut_sweep(pico.flash, STORE_SETUP, STORE_SAVE, STORE_CHECK, cuts, timeout=7200)["cuts"]
    old, new = "(1, 2, 3) %r" % (tuple(range(24)),), "(4, 5, 6) %r" % (tuple(range(24)),)
    counts = {"old": 0, "new": 0, "wrong": 0}
    for r in res:
        c = (r["check"] or "").strip()
        counts["old" if c == old else "new" if c == new else "wrong"] += 1
    return len(ops), counts


def bench(report):
    from tools.board import picoctl
    why = picoctl.missing()
    if why:
        report("virtual Pico: not available", 0, why)
        return
    t0 = time.time()
    with picoctl.PicoInterp() as pico:
        got = measure(pico)
        aug = augmented(pico)
        heap = [line.split()[1:] for line in pico.run(BOOT_HEAP).splitlines() if line.startswith("HEAP")][0]
        nops, counts = sweep(pico)
    # every row README's Pico table shows, keyed (its template: tools/bench/figures.py); the
    # targets README states are checks (ok=) that fail the bench when missed
    targets = {"apply_be16": got["apply_be16"] <= 2000, "apply_be16_pure": got["apply_be16_pure"] <= got["float_driver"],
               "apply_be16_n": got["apply_be16_n"] <= 150}
    for key, label in ROWS:
        if key in got:
            report("Pico: " + label.strip(), got[key], "cycles", key="cycles_" + key, ok=targets.get(key))
    for key, label in ALLOC_ROWS:
        if "ALLOC " + key in got:
            report("Pico: " + label, got["ALLOC " + key], "bytes", key="alloc_" + key,
                   ok=(got["ALLOC " + key] == 0) if key.startswith("apply_be16") else None)
    for name, short in (("base", "base"), ("every term", "every")):
        for key, label in AUG_ROWS:
            if key in aug[name]:
                report("Pico: " + label.strip().replace("%s", name) + (" (%s)" % name if "%s" not in label else ""),
                       aug[name][key], "cycles", key="aug_%s_%s" % (short, key))
    ev = aug["every term"]
    report("Pico: augmented model, every term, reading changing / its float anchor", ev["t"] / ev["float_t"], "x",
           key="aug_every_t_vs_float")
    report("Pico: augmented model, base / the plain apply_be16 sample", aug["base"]["c"] / aug["base"]["plain"], "x",
           key="aug_base_vs_plain")
    locked = aug["base"]["lock"] == ev["lock"] == "ok"
    report("Pico: augmented model under heap_lock(), base and every term", "ok" if locked else "FAIL", "",
           key="aug_locked", ok=locked)
    report("Pico: same, pure Python / a typical driver's float sample", got["apply_be16_pure"] / got["float_driver"],
           "x", key="pure_vs_driver")
    ratio = got["real_read_compensated"] / got["real_read_raw"]
    report("Pico: read_compensated / read_raw through the real I2C", ratio, "x", key="real_ratio", ok=ratio <= 2)
    report("Pico: heap at boot, total", int(heap[0]), "bytes", key="heap_total")
    report("Pico: heap at boot, free", int(heap[1]), "bytes", key="heap_free")
    report("Pico: import tempcomp_board + tempcomp.sensors", int(heap[2]), "bytes", key="heap_import")
    report("Pico: power cuts through a store save, flash operations of the save", nops, "", key="cut_ops")
    report("Pico: power cuts, restored the old calibration", counts["old"], "", key="cut_old")
    report("Pico: power cuts, restored the new calibration", counts["new"], "", key="cut_new")
    report("Pico: power cuts, restored a wrong or lost one", counts["wrong"], "", key="cut_wrong",
           ok=counts["wrong"] == 0)
    print("  (virtual Pico bench: %.0f s)" % (time.time() - t0), flush=True)


if __name__ == "__main__":
    bench(lambda name, value, unit, key=None, ok=None: print("%-70s %s %s" % (name, value, unit)))
