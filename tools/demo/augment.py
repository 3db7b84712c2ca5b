"""`make demo`'s augmented-model step: the diagnosis' export of a real log stored on the virtual
board, restored after a power cycle, and run by the board over the withheld part of the log -
the sim alone (before) and the augmented model (after), both from the store."""

import json
import os
import subprocess
import sys

import numpy as np

from tools import REPO
from tools.board.boardctl import BoardError, Remote, VirtualBoard
from tools.simgap import devmodel, replay
from tools.simgap.logio import AXES, read_log

BOARD = r"""
import gc
from array import array
from tempcomp.store import Store
from tempcomp.augment import Augmented, from_store
st = Store('/tempcomp.cal')
N = %(n)d
CH = 64
buf = array('i', bytes(CH * 9 * 4))
res = array('i', bytes(CH * 3 * 4))
raw = array('i', [0, 0, 0]); out = array('i', [0, 0, 0]); acc = array('i', [0, 0, 0])


def chunk(ap, k):
    i = 0
    while i < k:
        p = i * 9
        raw[0] = buf[p + 2]; raw[1] = buf[p + 3]; raw[2] = buf[p + 4]
        acc[0] = buf[p + 6]; acc[1] = buf[p + 7]; acc[2] = buf[p + 8]
        ap(buf[p], raw, out, buf[p + 1], buf[p + 5], acc)
        q = i * 3
        res[q] = out[0]; res[q + 1] = out[1]; res[q + 2] = out[2]
        i += 1


for name in ('gyro_base', 'gyro_aug'):
    aug = Augmented(from_store(st, name))
    aug.start(%(up0)d)
    ap = aug.apply
    alloc = 0
    with open('/rows.bin', 'rb') as f, open('/out_%%s.bin' %% name, 'wb') as g:
        done = 0
        while done < N:
            k = min(CH, N - done)
            f.readinto(memoryview(buf)[:k * 9])
            gc.collect()
            a0 = gc.mem_alloc()
            chunk(ap, k)
            if done:  # the first chunk fills first-call caches
                alloc += gc.mem_alloc() - a0
            g.write(memoryview(res)[:k * 3])
            done += k
    print('RAN', name, N, alloc)
"""


def run(say, real, name="tofupilot_gyro"):
    """The step; returns the summary line. BoardError when a step fails or the board's figures are
    not the host's: the board's shrink (after / before) differs from the diagnosis' own by more
    than 0.005 + 2 %, or its compensation allocated."""
    model_path = os.path.join(real, name + "_model.json")
    held_path = os.path.join(real, name + "_withheld.csv")
    if not os.path.exists(model_path):
        raise BoardError("the diagnosis exported no model (%s)" % os.path.relpath(model_path, REPO))
    with open(model_path) as f:
        model = json.load(f)
    say("exported: base + %s; not on the board: %s" % (
        ", ".join(sorted({e["name"] for e in model["on_device"]})) or "nothing",
        ", ".join("%s (%s)" % (e["name"], e["reason"]) for e in model["not_on_device"]) or "none"))
    for note in model.get("notes", []):
        say("  note: " + note)
    store = os.path.join(real, "tempcomp.cal")
    if os.path.exists(store):
        os.remove(store)
    for rec, extra in (("gyro_base", ["--base"]), ("gyro_aug", [])):
        cmd = [sys.executable, "-m", "tools", "store", "put", store, model_path, "--name", rec] + extra
        say("+ python -m tools store put %s %s --name %s %s" % (
            os.path.relpath(store, REPO), os.path.relpath(model_path, REPO), rec, " ".join(extra)))
        r = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
        if r.returncode != 0:
            raise BoardError("store put failed: %s" % r.stderr.strip())
    held = read_log(held_path)
    dev = model["device"]
    inp = devmodel.board_inputs(dev, held, replay.uptime0(held))
    if model["base"]["t_lsb"] != dev["t_lsb"] or model["base"]["raw_lsb"] != dev["raw_lsb"]:
        raise BoardError("base and augmented models read the board differently")
    rows = np.column_stack([inp["t"], inp["dt_ms"], inp["raw"], inp["supply"], inp["acc"]]).astype("<i4")
    rows_path = os.path.join(real, name + "_rows.bin")
    rows.tofile(rows_path)
    home = os.path.join(REPO, "build", "demo-augment")
    vb = VirtualBoard(home).start()
    try:
        remote = Remote(vb.url)
        remote.deploy_mpy("virtual", os.path.join(REPO, "build", "demo", "mpy"))
        remote.mpremote("cp", store, ":/tempcomp.cal", "+", "cp", rows_path, ":/rows.bin", timeout=600)
        say("stored on the virtual board: /tempcomp.cal (records gyro_base, gyro_aug) and the withheld "
            "log's %d rows as the board reads them (/rows.bin)" % len(rows))
        vb.power_cycle()
        say("power cycle; the board restores both models from /tempcomp.cal and runs them")
        out = remote.run(BOARD % {"n": len(rows), "up0": inp["uptime0_ms"]}, timeout=900)
        ran = [ln.split() for ln in out.splitlines() if ln.startswith("RAN ")]
        if len(ran) != 2:
            raise BoardError("the board did not run both models:\n" + out[-2000:])
        local = os.path.join(home, "out")
        os.makedirs(local, exist_ok=True)
        got = {}
        for rec in ("gyro_base", "gyro_aug"):
            dst = os.path.join(local, rec + ".bin")
            remote.mpremote("cp", ":/out_%s.bin" % rec, dst)
            y = np.fromfile(dst, dtype="<i4").reshape(-1, 3) / float(dev["out_scale"])
            got[rec] = np.sqrt(np.mean((y - held.ref) ** 2, axis=0))
        allocated = [int(r[3]) for r in ran]
    finally:
        vb.stop()
    unit = model["unit"]
    host = (model.get("host") or {}).get("rms", {})
    say("withheld part of the log, %d rows, RMS of (board output - true rate) in %s:" % (len(rows), unit))
    say("  %-4s %12s %12s %8s   %s" % ("axis", "before", "after", "shrink", "host's diagnosis (%s): before -> after"
                                       % model["out_unit"]))
    for i, a in enumerate(AXES):
        b, f = got["gyro_base"][i], got["gyro_aug"][i]
        hb = host.get("base_only", {}).get(a)
        ha = host.get("augmented", {}).get(a)
        say("  %-4s %12.4g %12.4g %7.1f%%   %s" % (a, b, f, 100 * (1 - f / b),
                                                 "%.4g -> %.4g (%.1f%%)" % (hb, ha, 100 * (1 - ha / hb)) if hb else ""))
    say("bytes allocated by the board's compensation over both runs (after the first %d rows): %d"
        % (64, sum(allocated)))
    bad = []
    for i, a in enumerate(AXES):
        hb = host.get("base_only", {}).get(a)
        ha = host.get("augmented", {}).get(a)
        if hb:
            dev, ref = got["gyro_aug"][i] / got["gyro_base"][i], ha / hb
            if not abs(dev - ref) <= 0.005 + 0.02 * ref:
                bad.append("axis %s: the board's shrink %.3f, the host's %.3f" % (a, dev, ref))
    if not host:
        bad.append("the model holds no host figures to compare with")
    if sum(allocated):
        bad.append("the board's compensation allocated %d bytes" % sum(allocated))
    if bad:
        raise BoardError("the board does not reproduce the host: " + "; ".join(bad))
    return "the board ran the exported model from its store: withheld RMS %s %s -> %s" % (
        "/".join("%.3g" % v for v in got["gyro_base"]), unit, "/".join("%.3g" % v for v in got["gyro_aug"]))
