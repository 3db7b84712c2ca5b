"""python -m tools.simgap.replay MODEL.json LOG.csv --json OUT.json [--base-only]

Runs the on-device code (lib/tempcomp/augment.py, unchanged) in the real MicroPython VM over a
log's rows in order, feeding it only what a board sees - the time step, the temperature
reading, the raw codes, and the supply/accelerometer readings - as the integers the model's
LSBs give, and writes

    {"rms": {axis: RMS(compensated - ref)}, "unit": ref unit, "rows": n,
     "allocated_per_sample": bytes, "heap_locked": true, ...}

MODEL.json is what `python -m tools.simgap ... --export MODEL.json` wrote: "device" is the
augmented model, "base" the sim alone (`--base-only`). A model JSON holding just a device
model (augment.py's dict) works too."""
import base64
import json
import os
import sys
import tempfile

import numpy as np

from tools import hostio
from tools.firmware import mpvm

from . import devmodel
from .logio import AXES, LogError, read_log

_WARM = 2  # rows run before measuring (first-call caches)
_MEASURE = 2000  # rows whose allocation is counted with gc.mem_alloc; the rest run heap-locked

_VM = """
import gc, json, micropython, binascii
from array import array
from tempcomp.augment import Augmented

def loop(ap, buf, res, lo, hi, raw, out, acc):
    # ap: the bound method, made once outside (making one allocates)
    i = lo
    while i < hi:
        p = i * 9
        raw[0] = buf[p + 2]
        raw[1] = buf[p + 3]
        raw[2] = buf[p + 4]
        acc[0] = buf[p + 6]
        acc[1] = buf[p + 7]
        acc[2] = buf[p + 8]
        ap(buf[p], raw, out, buf[p + 1], buf[p + 5], acc)
        q = i * 3
        res[q] = out[0]
        res[q + 1] = out[1]
        res[q + 2] = out[2]
        i += 1

def locked(ap, buf, res, lo, hi, raw, out, acc):
    # the lock inside a function: a MemoryError is caught here (at module level this port hangs)
    err = None
    micropython.heap_lock()
    try:
        loop(ap, buf, res, lo, hi, raw, out, acc)
    except MemoryError as e:
        err = e
    micropython.heap_unlock()
    return err

STARTS = %(starts)r  # rows before which the board powers on again (a new run, the clock restarting)
nxt = [0]


def phase(fn, aug, ap, buf, res, lo, hi, raw, out, acc):
    # rows lo..hi in order, a power-on (aug.start, which may allocate) between segments
    a = lo
    while nxt[0] < len(STARTS) and STARTS[nxt[0]] < hi:
        b = STARTS[nxt[0]]
        if b > a:
            r = fn(ap, buf, res, a, b, raw, out, acc)
            if r is not None:
                return r
        aug.start(0)
        nxt[0] += 1
        a = b
    return fn(ap, buf, res, a, hi, raw, out, acc)


def main():
    with open('/data/model.json') as f:
        m = json.load(f)
    aug = Augmented(m)
    aug.start(%(up0)d)
    n = %(n)d
    buf = array('i', bytes(n * 9 * 4))
    with open('/data/rows.bin', 'rb') as f:
        f.readinto(buf)
    res = array('i', bytes(n * 3 * 4))
    raw = array('i', [0, 0, 0])
    out = array('i', [0, 0, 0])
    acc = array('i', [0, 0, 0])
    ap = aug.apply
    w = min(n, %(warm)d)
    phase(loop, aug, ap, buf, res, 0, w, raw, out, acc)
    k = min(n, w + %(measure)d)
    for b in STARTS:  # end the measured rows at a power-on: start() is set-up, not a sample
        if w < b < k:
            k = b
            break
    gc.collect()
    a0 = gc.mem_alloc()
    s0 = nxt[0]
    phase(loop, aug, ap, buf, res, w, k, raw, out, acc)
    a1 = gc.mem_alloc()
    restarts = nxt[0] - s0
    gc.collect()
    mark = nxt[0]
    err = phase(locked, aug, ap, buf, res, k, n, raw, out, acc)
    if err is not None:
        print('LOCKFAIL', repr(err))
        nxt[0] = mark
        phase(loop, aug, ap, buf, res, k, n, raw, out, acc)
    print('RESTARTS', restarts, len(STARTS))
    print('ALLOC', a1 - a0, k - w)
    print('CLAMPED', aug.clamped(), aug.comp.clamped)
    mv = memoryview(res)
    j = 0
    while j < n * 3:
        e = min(n * 3, j + 768)
        print('R', binascii.b2a_base64(bytes(mv[j:e])).decode().strip())
        j = e

main()
"""


class ReplayError(ValueError):
    pass


def run_device(dev, inp, timeout=None):
    """Run augment.Augmented(dev) over the board inputs in the VM; returns (out ints (N, 3),
    info dict with allocated_per_sample, heap_locked, clamped)."""
    n = len(inp["t"])
    rows = np.column_stack([inp["t"], inp["dt_ms"], inp["raw"], inp["supply"], inp["acc"]])
    if np.any(np.abs(rows) >= 2 ** 30):
        raise ReplayError("a board input beyond the small-int range; check the model's LSBs")
    heap = max(4, int(n * 48 * 1.3 / 2 ** 20) + 3)
    with tempfile.TemporaryDirectory() as d:
        with open(os.path.join(d, "model.json"), "w") as f:
            json.dump(dev, f)
        rows.astype("<i4").tofile(os.path.join(d, "rows.bin"))
        code = _VM % {"n": n, "up0": inp.get("uptime0_ms", 0), "warm": _WARM, "measure": _MEASURE,
                      "starts": [int(v) for v in inp.get("starts", [])]}
        stdout = mpvm.run(code, mounts=[d + ":/data"], heap="%dm" % heap,
                          timeout=timeout or max(120, n // 200))
    chunks = []
    info = {"heap_locked": True}
    for line in stdout.splitlines():
        if line.startswith("R "):
            chunks.append(base64.b64decode(line[2:]))
        elif line.startswith("ALLOC "):
            _, b, k = line.split()
            info["allocated_per_sample"] = int(b) / max(1, int(k))
        elif line.startswith("LOCKFAIL"):
            info["heap_locked"] = False
            info["lock_error"] = line[9:]
        elif line.startswith("RESTARTS "):
            _, r, total = line.split()
            info["power_ons"] = int(total)
            if int(r):  # start() in the measured rows allocates by design (set-up, not a sample)
                info["allocated_includes_power_on"] = True
        elif line.startswith("CLAMPED "):
            _, a, c = line.split()
            info["clamped"] = int(a) + int(c)
    out = np.frombuffer(b"".join(chunks), dtype="<i4").reshape(-1, 3)
    if out.shape[0] != n:
        raise ReplayError("the VM returned %d rows of %d:\n%s" % (out.shape[0], n, stdout[-2000:]))
    return out.astype(np.int64), info


def load_model(path):
    try:
        d = hostio.load_json(path)
    except hostio.HostError as e:
        raise LogError(str(e)) from None
    if not isinstance(d, dict) or ("device" not in d and "t_lsb" not in d):
        raise LogError("%s: not an exported model (no 'device' section; write one with "
                       "python -m tools gap ... --export %s)" % (path, path))
    return d


def uptime0(log):
    """Seconds the board had been on at the log's first row (meta power_on_s), else 0."""
    try:
        return max(0.0, float(log.t[0]) - float(log.meta["power_on_s"]))
    except (KeyError, ValueError):
        return 0.0


def replay(model, log, base_only=False):
    dev = model.get("device", model)
    if base_only:
        dev = model.get("base") or dict(dev, features=[], offset_terms=None, gain_terms=None, cross=None)
    inp = devmodel.board_inputs(dev, log, uptime0(log))
    out, info = run_device(dev, inp)
    y = out / float(dev.get("out_scale", 1.0))
    err = y - log.ref
    rms = {AXES[a]: float(np.sqrt(np.mean(err[:, a] ** 2))) for a in range(3)}
    res = {"rms": rms, "unit": log.meta.get("ref_unit", "ref unit"), "rows": len(log),
           "allocated_per_sample": info.get("allocated_per_sample"),
           "heap_locked": info["heap_locked"], "clamped": info.get("clamped", 0),
           "raw_clipped": inp["raw_clipped"], "power_ons": info.get("power_ons", 0),
           "model": "base" if base_only else "augmented"}
    if "lock_error" in info:
        res["lock_error"] = info["lock_error"]
    return res, y


def main(argv=None):
    ap = hostio.Parser(prog="python -m tools.simgap.replay",
                                 description="Run the on-device compensation over a log in the real "
                                             "MicroPython VM and report the RMS error per axis.")
    ap.add_argument("model", help="MODEL.json written by --export")
    ap.add_argument("log", help="log CSV (docs/simgap.md schema)")
    ap.add_argument("--json", required=True, help="where to write the result")
    ap.add_argument("--base-only", action="store_true", help="apply the base model alone")
    a = ap.parse_args(argv)
    try:
        hostio.check_output(a.json, "JSON")
        model = load_model(a.model)
        log = read_log(a.log)
    except (LogError, hostio.HostError) as e:
        return hostio.fail(e)
    try:
        res, _ = replay(model, log, a.base_only)
    except (LogError, ReplayError, ValueError) as e:
        return hostio.fail(e)
    except (KeyError, TypeError, IndexError) as e:  # a model file edited or cut by hand
        return hostio.fail("%s: not a usable exported model (%s %s); write it again with python -m tools gap "
                           "... --export" % (a.model, type(e).__name__, e))
    try:
        hostio.write_all([(a.json, hostio.dumps(res, indent=1))])
    except hostio.HostError as e:
        return hostio.fail(e)
    print("%s model on %s (%d rows): RMS %s %s; %s bytes allocated per sample%s" % (
        res["model"], a.log, res["rows"],
        " ".join("%s %.4g" % (k, v) for k, v in res["rms"].items()), res["unit"],
        res["allocated_per_sample"], "" if res["heap_locked"] else " (NOT allocation-free)"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
