"""The augmented model with every term on, on each interpreter the library targets (the wasm VM,
MicroPython 1.27 firmware on a Cortex-M3 and M7 under qemu, CircuitPython 10.2.1): heap-locked
samples and bursts (the native kernels where the firmware has them), and results within the
stated precision of float64 (single-precision set-up on the
M3/M7 firmware moves a coefficient's last bits, not the output)."""
import json

import numpy as np
import seeds
from augsynth import OUT_SCALE, every_term_model, inputs

from tools.simgap import devmodel

N = 150


def test_every_term_heap_locked_and_precise_on(interp):
    m = every_term_model()
    inp, F = inputs(m, n=N, seed=seeds.seed("augment_firmware_inputs"))
    rows = np.column_stack([inp["t"], inp["dt_ms"], inp["raw"], inp["supply"], inp["acc"]]).tolist()
    out = interp.run("""
import micropython
from array import array
from tempcomp.augment import Augmented
a = Augmented(%s)
ROWS = %s
res = array('i', bytes(4 * 3 * len(ROWS)))
raw = array('i', [0, 0, 0]); out = array('i', [0, 0, 0]); acc = array('i', [0, 0, 0])
ap = a.apply
def run(lo, hi):
    i = lo
    while i < hi:
        r = ROWS[i]
        raw[0] = r[2]; raw[1] = r[3]; raw[2] = r[4]
        acc[0] = r[6]; acc[1] = r[7]; acc[2] = r[8]
        ap(r[0], raw, out, r[1], r[5], acc)
        res[3 * i] = out[0]; res[3 * i + 1] = out[1]; res[3 * i + 2] = out[2]
        i += 1
def locked(lo, hi):
    err = None
    micropython.heap_lock()
    try:
        run(lo, hi)
    except MemoryError as e:
        err = e
    micropython.heap_unlock()
    return err
run(0, 2)
print('LOCK', 'ok' if locked(2, len(ROWS)) is None else 'FAIL')
def ticked(n):
    # dt from the port's own ms clock (dt_ms=-1)
    i = 0
    while i < n:
        ap(2500, raw, out, -1, 3300, acc)
        i += 1
def ticked_locked():
    err = None
    micropython.heap_lock()
    try:
        ticked(20)
    except MemoryError as e:
        err = e
    micropython.heap_unlock()
    return err
ticked(2)
print('TICKS', 'ok' if ticked_locked() is None else 'FAIL')
bufn = bytearray(b"\\x80\\x00\\x12\\x34\\x7f\\xff" * 16); outn = array('i', [0] * 48)
def bursts(n):
    # FIFO bursts of 16, the temperature reading changing between them
    i = 0
    while i < n:
        a.apply_be16_n(2500 + i, bufn, outn, 16, 10, 3300, acc)
        i += 1
def bursts_locked():
    err = None
    micropython.heap_lock()
    try:
        bursts(8)
    except MemoryError as e:
        err = e
    micropython.heap_unlock()
    return err
bursts(1)
print('BURSTS', 'ok' if bursts_locked() is None else 'FAIL')
i = 0
while i < len(res):
    print('RES', res[i], res[i + 1], res[i + 2])
    i += 3
""" % (json.dumps(m), json.dumps(rows)), timeout=600)
    assert "LOCK ok" in out.splitlines()
    assert "TICKS ok" in out.splitlines()
    assert "BURSTS ok" in out.splitlines()
    y = np.array([ln.split()[1:] for ln in out.splitlines() if ln.startswith("RES ")], dtype=float)
    assert y.shape == (N, 3)
    want = devmodel.compensate(m, inp, F) * OUT_SCALE
    assert np.max(np.abs(y - want)) <= 1.5
