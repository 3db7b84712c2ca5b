"""The augmented model's kernels (lib/tempcomp/augment.py's pure Python, augment_native's viper,
augment_thumb's asm_thumb): on every interpreter the native path (where there is one, with its
asm_thumb and its viper sample body) gives the pure path's numbers bit for bit, single samples and
bursts alike, over ordinary inputs and every input at the ends of its range; the pure path gives
CPython's numbers on the interpreters that set up in double precision; the layout the three
modules share agrees; bad calls are refused by name before anything is written."""
import ast
import base64
import json
import os
from array import array

import numpy as np
import pytest
from augsynth import every_term_model, inputs
from paths import skip_unless_ci
from seeds import seed

from tempcomp import augment
from tools import REPO
from tools.bench.augment import TERMS, model
from tools.board import picoctl

LIB = os.path.join(REPO, "lib", "tempcomp")
N = 96  # samples per scenario


def _consts(name):
    tree = ast.parse(open(os.path.join(LIB, name)).read())
    out = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Call) and \
                getattr(node.value.func, "id", "") == "const" and isinstance(node.targets[0], ast.Name):
            out[node.targets[0].id] = eval(compile(ast.Expression(node.value.args[0]), name, "eval"),
                                           {k: v for k, v in out.items()})
    return out


def test_the_three_kernels_share_one_layout():
    pure, viper, thumb = _consts("augment.py"), _consts("augment_native.py"), _consts("augment_thumb.py")
    shared = set(pure) & set(viper)
    assert len(shared) > 80
    assert {k: viper[k] for k in shared} == {k: pure[k] for k in shared}
    for name in ("augment_vrun.py", "augment_pure.py"):
        other = _consts(name)
        assert len(other) > 50 and other == {k: pure[k] for k in other}, name
    # the asm kernel's byte offsets: word index * 4 (the run block from its own base)
    blocks = {"_AXB4": "_AXB", "_AXS4": "_AXS", "_RUN4": "_SRC", "_TREC4": "_TREC", "_FREC4": "_FREC"}
    run = {"_SRC4", "_OUTP4", "_NS4", "_MODE4", "_STR4", "_ROFF4", "_AOFF4", "_DTR4", "_HASF4",
           "_NHYP4", "_PHYP4", "_UPMAX4", "_TC4", "_PTF4", "_DTI4"}
    axis = {"_GH4", "_GL4", "_B4", "_RHO4", "_DS4", "_ES4", "_FO4", "_AF4", "_OT4", "_GT4", "_CR4", "_Y04",
            "_INV4", "_Y4", "_KM4", "_RAW4", "_SOT4", "_SGT4", "_RS4", "_RR4"}
    checked = 0
    for k, v in thumb.items():
        if not k.endswith("4"):
            if k in pure:
                assert v == pure[k], k
            continue
        word = blocks.get(k, k[:-1])
        if k in run:
            assert v == 4 * (pure[word] - pure["_SRC"]), k
        elif k in axis:
            assert v == 4 * pure[word], k
        elif word[:3] == "_SC" and word[3:].isdigit():
            assert v == 4 * (pure["_SCR"] + int(word[3])), k
        else:
            assert v == 4 * pure[word], k
        checked += 1
    assert checked > 40


def scenarios():
    """[(name, model, rows, bursts)]: rows are one sample's inputs each (t, dt_ms, raw x3, supply,
    acc x3); a burst (start, n, layout) covers rows whose dt_ms and supply (and t and acc unless the
    layout reads them) hold across it, as a FIFO burst's do. The inputs are the run's
    (TEMPCOMP_SEED)."""
    rng = np.random.default_rng(seed("augment_kernels/extremes"))
    models = [("base", model([]))] + [(n, model([n])) for n in TERMS] + [("every term", model(list(TERMS))),
                                                                       ("every kind, every axis", every_term_model())]
    out = []
    for name, m in models:
        inp, _ = inputs(m, n=N, seed=seed("augment_kernels/" + name))
        rows = np.column_stack([inp["t"], inp["dt_ms"], inp["raw"], inp["supply"], inp["acc"]])
        rows[:, 2:5] = np.clip(rows[:, 2:5], -32768, 32767)
        bursts = []
        for start, n, lay in ((10, 32, 0), (45, 17, 1), (63, 1, 0), (66, 28, 1)):
            seg = rows[start:start + n]
            seg[:, 1] = seg[0, 1]
            seg[:, 5] = seg[0, 5]
            if lay == 0:
                seg[:, 0] = seg[0, 0]
                seg[:, 6:] = seg[0, 6:]
            bursts.append((start, n, lay))
        out.append((name, m, rows, bursts))
    # every input at the ends of its range and beyond (clamped, counted); steps across the whole
    # temperature range; dt from 0 to hours
    m = every_term_model()
    t_lo, t_hi = augment.Augmented(m).comp.t_in
    ext = np.column_stack([rng.choice([t_lo - 500, t_lo, t_hi, t_hi + 500, 2500], N),
                           rng.choice([0, 1, 999, 65535, 3600000, 10 ** 8], N),
                           rng.choice([-32768, 32767, 0, -1], (N, 3)), rng.choice([0, 3300, 65535, -65535], N),
                           rng.choice([-32768, 32767, 0, 2000], (N, 3))])
    bursts = []
    for start, n, lay in ((20, 40, 1), (65, 24, 0)):
        seg = ext[start:start + n]
        seg[:, 1] = min(int(seg[0, 1]), (1 << 26) - 1)
        seg[:, 5] = seg[0, 5]
        if lay == 0:
            seg[:, 0] = seg[0, 0]
            seg[:, 6:] = seg[0, 6:]
        else:
            seg[:, 0] = np.clip(seg[:, 0], -32768, 32767)
        bursts.append((start, n, lay))
    out.append(("extremes", m, ext, bursts))
    return out


DEVICE = r"""
import gc
from array import array
from tempcomp import augment
have = augment.use_native(None)  # the kernels and the buffers first, while the heap is empty
NMAX = 96
first = array('i', bytes(16 * NMAX))
ra = array('i', bytes(16 * NMAX))
rb = array('i', bytes(16 * NMAX))
gc.collect()
import binascii
rows = array('i', binascii.a2b_base64(ROWSB))  # int32 words, little-endian: array() takes bytes as memory
SC = [(NAME, MODEL, None, len(rows) // 9, BURSTS)]
k = augment._kernel() if have else None
KINDS = [('native', None, 1), ('pure', False, 1)]
if have:
    print('NATIVE', k.__name__, k._asm is not None and k._run is k._asm)
    if k._asm is not None:
        KINDS.append(('viper', None, 0))
else:
    print('NATIVE none')
raw = array('i', [0, 0, 0]); out = array('i', [0, 0, 0]); acc = array('i', [0, 0, 0])
outn = array('i', [0] * 120)

def digest(res, n):
    h = 0
    for j in range(4 * n):
        h = (h * 31 + res[j]) & 0x3FFFFFFF
    return h

def single(a, rows, i, res):
    r = 9 * i
    raw[0] = rows[r + 2]; raw[1] = rows[r + 3]; raw[2] = rows[r + 4]
    acc[0] = rows[r + 6]; acc[1] = rows[r + 7]; acc[2] = rows[r + 8]
    a.apply(rows[r], raw, out, rows[r + 1], rows[r + 5], acc)
    res[4 * i] = out[0]; res[4 * i + 1] = out[1]; res[4 * i + 2] = out[2]; res[4 * i + 3] = a.clamped()

def burst(a, rows, start, n, lay, res):
    st = 6 if lay == 0 else 14
    if lay:
        a.layout(14, raw=8, acc=0, temp=6)
    else:
        a.layout()
    buf = bytearray(n * st)
    for j in range(n):
        r = 9 * (start + j)
        p = j * st
        for k in ((2, 3, 4) if lay == 0 else (6, 7, 8, 0, 2, 3, 4)):
            w = rows[r + k]
            buf[p] = (w >> 8) & 0xFF
            buf[p + 1] = w & 0xFF
            p += 2
    r = 9 * start
    acc[0] = rows[r + 6]; acc[1] = rows[r + 7]; acc[2] = rows[r + 8]
    a.apply_be16_n(rows[r], buf, outn, n, rows[r + 1], rows[r + 5], None if lay else acc)
    for j in range(n):
        i = start + j
        res[4 * i] = outn[3 * j]; res[4 * i + 1] = outn[3 * j + 1]; res[4 * i + 2] = outn[3 * j + 2]
        res[4 * i + 3] = a.clamped() if j == n - 1 else -1

for name, m, path, nrows, bursts in SC:
    gc.collect()
    kn = 0
    for kind, mode, body in KINDS:
        augment.use_native(mode)
        if have and kind != 'pure':
            k.use_asm(body)
        a = augment.Augmented(m)
        b = augment.Augmented(m)
        for i in range(nrows):
            single(a, rows, i, ra)
        i = 0
        ends = {}
        for s, n, lay in bursts:
            ends[s] = (n, lay)
        while i < nrows:
            if i in ends:
                n, lay = ends[i]
                burst(b, rows, i, n, lay, rb)
                for j in range(i, i + n - 1):
                    ra_c = ra[4 * j + 3]
                    rb[4 * j + 3] = ra_c  # a burst's clamp count is read once, at its end
                i += n
            else:
                single(b, rows, i, rb)
                i += 1
        bad = [j for j in range(4 * nrows) if ra[j] != rb[j]]
        print('BURST', name, kind, 'same' if not bad else 'DIFF %d at %d: %r %r' % (len(bad), bad[0] // 4, ra[bad[0]], rb[bad[0]]))
        if kn == 0:
            for j in range(4 * nrows):
                first[j] = ra[j]
        else:
            bad = [j for j in range(4 * nrows) if ra[j] != first[j]]
            print('KERNEL', name, kind, 'same' if not bad else 'DIFF %d at %d' % (len(bad), bad[0] // 4))
        if kind == 'pure':
            print('DIGEST', name, digest(ra, nrows))
        a = b = None
        kn += 1
    if have:
        k.use_asm(1)
augment.use_native(None)
"""


def device_run(run, scs):
    """DEVICE once per scenario, its rows a bytes literal (a list that long would not fit the
    firmware's heap while it compiles); the outputs joined."""
    outs = []
    for n, m, r, b in scs:
        rb = base64.b64encode(r.astype("<i4").tobytes())
        head = "NAME = %r\nMODEL = %r\nBURSTS = %r\nROWSB = %r\n" % (n, m, b, rb)
        outs.append(run(head + DEVICE))
    return "\n".join(outs)


def cpython_digests(scs):
    # the same digest of the pure path's single samples, here
    out = {}
    raw, o, acc = array("i", [0, 0, 0]), array("i", [0, 0, 0]), array("i", [0, 0, 0])
    for name, m, rows, _ in scs:
        a = augment.Augmented(m)
        h = 0
        for r in rows.tolist():
            raw[0], raw[1], raw[2] = r[2:5]
            acc[0], acc[1], acc[2] = r[6:9]
            a.apply(r[0], raw, o, r[1], r[5], acc)
            for v in (o[0], o[1], o[2], a.clamped()):
                h = (h * 31 + v) & 0x3FFFFFFF
        out[name] = h
    return out


def check(out, scs, expect_native, same_as_cpython):
    lines = out.splitlines()
    native = [ln for ln in lines if ln.startswith("NATIVE ")][0]
    if expect_native:
        assert native.endswith(" True"), native  # the asm_thumb kernel runs (not just viper)
    names = [n for n, _, _, _ in scs]
    for tag in ("BURST", "KERNEL"):
        got = [ln for ln in lines if ln.startswith(tag + " ")]
        assert got and all(ln.endswith(" same") for ln in got), "\n".join(ln for ln in got if not ln.endswith(" same"))
    assert len([ln for ln in lines if ln.startswith("KERNEL ")]) == len(names) * (2 if expect_native else 1)
    if same_as_cpython:
        got = {ln[7:].rsplit(" ", 1)[0]: int(ln.rsplit(" ", 1)[1]) for ln in lines if ln.startswith("DIGEST ")}
        assert got == cpython_digests(scs)


@pytest.fixture(scope="module")
def scs():
    return scenarios()


def test_native_asm_viper_and_pure_agree_on(interp, scs):
    if interp.name == "an500":
        # the M7 runs the M3's .mpy: the base model, every term and the corners suffice there
        scs = [sc for sc in scs if sc[0] in ("base", "every term", "every kind, every axis", "extremes")]
    out = device_run(lambda code: interp.run(code, timeout=900), scs)
    native = interp.name in ("an385", "an500")
    # doubles at set-up (wasm, CircuitPython's unix port) give CPython's integers; the M3/M7
    # firmware's single-precision floats may move a coefficient's last bit
    check(out, scs, native, interp.name in ("wasm", "circuitpython"))


def test_native_and_pure_agree_on_the_virtual_pico(scs):
    why = picoctl.missing()
    if why:
        skip_unless_ci("virtual Pico cannot run: " + why)
    with picoctl.PicoInterp() as p:
        out = device_run(lambda code: p.run(code, timeout=1800), scs[-2:])
    assert "NATIVE tempcomp.augment_native_m0 True" in out  # the armv6m build, with its asm_thumb
    check(out, scs[-2:], True, False)


BAD = r"""
from array import array
from tempcomp import augment
a = augment.Augmented(%(model)s)
raw = array('i', [1, 2, 3]); out = array('i', [7, 7, 7]); acc = array('i', [0, 0, 0])
def tryit(tag, f):
    try:
        f()
        print(tag, 'ok')
    except Exception as e:
        print(tag, type(e).__name__, e)
o1 = array('i', [7, 7, 7]); o2 = array('i', [7, 7, 7])
tryit('LIST_RAW', lambda: a.apply(2500, [1, 2, 3], o1, 10, 3300, acc))
tryit('LIST_OUT', lambda: a.apply(2500, raw, [0, 0, 0], 10, 3300, acc))
tryit('SHORT_OUT', lambda: a.apply(2500, raw, array('i', [0, 0]), 10, 3300, acc))
tryit('H_OUT', lambda: a.apply(2500, raw, array('h', [0, 0, 0]), 10, 3300, acc))
tryit('NO_ACC', lambda: a.apply(2500, raw, o2, 10, 3300, None))
print('OUT1', list(o1))
print('OUT2', list(o2))
buf = bytearray(6 * 4); outn = array('i', [5] * 12)
tryit('N', lambda: a.apply_be16_n(2500, buf, outn, -1, 10, 3300, acc))
tryit('DT', lambda: a.apply_be16_n(2500, buf, outn, 2, -5, 3300, acc))
tryit('BUF', lambda: a.apply_be16_n(2500, buf, outn, 5, 10, 3300, acc))
tryit('OUTN', lambda: a.apply_be16_n(2500, buf, array('i', [5] * 9), 4, 10, 3300, acc))
tryit('LISTBUF', lambda: a.apply_be16_n(2500, [0] * 24, array('i', [5] * 12), 4, 10, 3300, acc))
print('OUTNV', list(outn))
tryit('GOOD', lambda: a.apply_be16_n(2500, buf, outn, 4, 10, 3300, acc))
tryit('GOOD1', lambda: a.apply(2500, raw, out, 10, 3300, acc))
"""


def test_bad_calls_are_refused_by_name_before_writing(interp):
    out = interp.run(BAD % {"model": json.dumps(model(["g_sensitivity"]))})
    got = {ln.split(" ", 1)[0]: ln.split(" ", 1)[1] for ln in out.splitlines() if " " in ln}
    native = interp.name in ("an385", "an500")
    if native:  # the native kernel reads and writes 32-bit words: anything else is refused
        for tag, what in (("LIST_RAW", "raw must be an array('i')"), ("LIST_OUT", "out must be an array('i')"),
                          ("SHORT_OUT", "out must be an array('i') of at least 3"),
                          ("H_OUT", "out must be an array('i')"), ("NO_ACC", "acc must be an array('i')"),
                          ("LISTBUF", "buf must be bytes")):
            assert got[tag].startswith("ValueError") and what in got[tag], (tag, got[tag])
        assert got["OUT1"] == "[7, 7, 7]"
    assert got["NO_ACC"].startswith("ValueError acc must be an array('i')") and got["OUT2"] == "[7, 7, 7]"
    assert "need 0 <= n < 32768" in got["N"] and "dt_ms=-5" in got["DT"]
    assert "5 samples at stride 6 need 30 bytes, buf has 24" in got["BUF"]
    assert "4 samples need 12 outputs, out has 9" in got["OUTN"]
    assert got["OUTNV"] == "[5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5]"
    assert got["GOOD"] == "ok" and got["GOOD1"] == "ok"


def test_layout_refuses_words_outside_the_stride():
    a = augment.Augmented(model([]))
    with pytest.raises(ValueError, match="stride 10 must cover the words"):
        a.layout(10, raw=8)
    with pytest.raises(ValueError, match="acc offset"):
        a.layout(14, acc=-2)
    a.layout(14, raw=8, acc=0, temp=6)
