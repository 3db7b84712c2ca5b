"""The 3-axis int16 burst kernels: apply_be16_n against n calls of apply_be16, the native
(viper / asm_thumb) kernels against the pure-Python path on every interpreter, zero allocation
under heap_lock, and the bound for int16 words outside a narrower signed raw range."""

import random
import re

import pytest
import seeds
from bounded import BInt, bind

from tempcomp import fixedpoint as fp

OFFS = [[-35.0, 0.009, -2e-7], [12.0, -0.003, 1e-7], [3.0, 0.0, 1e-7, -1e-11]]
SCS = [[131.0, 4e-4, -3e-8], [130.0, 2e-4], [132.5, -2e-4]]
# the largest gain and offsets the set-up accepts: S at its floor, |c| near 2**29
EXT_OFFS = [[16000.0, 0.1], [-16000.0, -0.1], [0.0]]
EXT_SCS = [[1.0 / 250.0], [1.0 / 250.0, 1e-9], [1.0 / 200.0]]


def _words(rng, n):
    buf = bytearray(rng.getrandbits(8) for _ in range(n))
    # the corner words in the first samples
    buf[0:6] = b"\x80\x00\x7f\xff\xff\xff"
    buf[6:12] = b"\x7f\xff\x80\x00\x00\x00"
    return buf


def _s16(b, i):
    v = b[i] << 8 | b[i + 1]
    return v - 0x10000 if v & 0x8000 else v


@pytest.mark.parametrize("stride", [6, 14])
def test_batch_equals_single_calls_and_apply(stride):
    import array

    rng = random.Random(seeds.seed("kernels_sets"))
    for offs, scs, t_cal in ((OFFS, SCS, (-4000, 9000)), (EXT_OFFS, EXT_SCS, (-30000, 30000))):
        comp = fp.Compensator(offs, scs, t_cal, out_scale=1000.0 if offs is OFFS else 1.0)
        n = 40
        buf = _words(rng, n * stride)
        for t in (t_cal[0], 0, t_cal[1]):
            comp.update(t)
            out = [0] * (3 * n)
            arr = array.array("i", out)
            comp.apply_be16_n(buf, out, n, stride)
            comp.apply_be16_n(buf, arr, n, stride)
            one = [0, 0, 0]
            for i in range(n):
                comp.apply_be16(buf[i * stride : i * stride + 6], one)
                assert out[3 * i : 3 * i + 3] == one
                assert one == [comp.apply(_s16(buf, i * stride + 2 * k), k) for k in range(3)]
            assert list(arr) == out


def test_batch_generic_axes_equals_apply():
    comp = fp.Compensator([[5.0, 0.01], [-7.0]], [[16.4], [16.3, 1e-4]], (-100, 100), out_scale=1000.0)
    rng = random.Random(seeds.seed("kernels_bursts"))
    buf = _words(rng, 10 * 8)
    out = [0] * 20
    comp.update(37)
    comp.apply_be16_n(buf, out, 10, 8)
    assert out == [comp.apply(_s16(buf, 8 * i + 2 * k), k) for i in range(10) for k in range(2)]


@pytest.mark.parametrize(
    "n, stride, nbuf, nout, match",
    [
        (-1, 6, 60, 30, "n >= 0"),
        (2, 4, 60, 30, "stride >= 6"),
        (10, 6, 59, 30, "need 60 bytes, buf has 59"),
        (10, 6, 60, 29, "need 30 outputs, out has 29"),
    ],
)
def test_batch_rejects_a_bad_call_before_writing(n, stride, nbuf, nout, match):
    comp = fp.Compensator(OFFS, SCS, (-4000, 9000), out_scale=1000.0)
    out = [7] * nout
    with pytest.raises(ValueError, match=match):
        comp.apply_be16_n(bytearray(nbuf), out, n, stride)
    assert out == [7] * nout
    comp.apply_be16_n(bytearray(0), out, 0)  # an empty burst is fine


def test_be16_refused_for_a_range_not_centred_on_zero():
    comp = fp.Compensator([[1000.0]] * 3, [[12.8]] * 3, (0, 100), raw_range=(0, 2047))
    with pytest.raises(ValueError, match="not centred on 0: use apply"):
        comp.apply_be16(bytearray(6), [0, 0, 0])
    with pytest.raises(ValueError, match="not centred on 0"):
        comp.apply_be16_n(bytearray(6), [0, 0, 0], 1)


@pytest.mark.parametrize("axes", [1, 3])
def test_narrow_signed_range_keeps_full_int16_words_in_bound(axes):
    # +-8192 (a 14-bit part) at the largest gain it accepts: before, K = 13 and a word of
    # -32768 reached 2**30.08 in v * gh; every int16 word must stay inside +-2**30
    offs = [[8000.0, 0.05]] * axes
    scs = [[1.0 / 250.0]] * axes
    comp = fp.Compensator(offs, scs, (-1000, 1000), raw_range=(-8192, 8191))
    bind(comp, ["_gh", "_gl", "_b", "_s", "_half", "_mid", "_k"])
    if comp.burst3 is not None:
        bind(comp, ["burst3"])
    if comp._q0 is not None:
        bind(comp, ["_q0", "_q1", "_q2"])  # the pure 3-axis path's numbers per axis
    words = (-32768, 32767, -8193, 8192, 0)
    buf = bytearray()
    for w in words[:3]:
        buf += (w & 0xFFFF).to_bytes(2, "big")
    for t in (-1000, 1000):
        comp.update(BInt(t))
        for w in words:
            y = comp.apply(BInt(w))
            off = 8000.0 + 0.05 * t
            assert abs(y - (w - off) * 250.0) <= 0.5 + 2.0 ** (1 - comp._s)
        out = [0] * axes
        comp.apply_be16(buf[: 2 * axes], out)
        comp.apply_be16_n(buf[: 2 * axes], out, 1, 2 * axes)


def test_use_native_true_refuses_where_there_is_no_emitter():
    # CPython has no micropython module: the pure path, and a clear refusal to force native
    assert fp.use_native(None) is False
    with pytest.raises(ValueError, match="no @micropython.viper emitter"):
        fp.use_native(True)
    assert fp.use_native(False) is False
    fp.use_native(None)


# --- every interpreter: native against pure, against the host's exact arithmetic, heap-locked --

DEVICE = r"""
import array, allocprobe
from tempcomp import fixedpoint as fp
have = fp.use_native(None)
print("NATIVE %d" % have)
if have:
    fp.Compensator(OFFS_, SCS_, (-4000, 9000))
    print("ASM %d" % bool(fp._kernels()._t))
cfgs = [(OFFS_, SCS_, (-4000, 9000), 1000.0), (EOFFS_, ESCS_, (-30000, 30000), 1.0)]
N = 24
STRIDE = 14
seed = [12345]
def rnd():
    seed[0] = (seed[0] * 1103515245 + 12345) & 0x7FFFFFFF
    return seed[0] >> 16
buf = bytearray(N * STRIDE)
for i in range(len(buf)):
    buf[i] = rnd() & 0xFF
buf[0:6] = b"\x80\x00\x7f\xff\xff\xff"
buf[STRIDE:STRIDE + 6] = b"\x7f\xff\x80\x00\x00\x00"
print("BUF " + "".join("%02x" % b for b in buf))
modes = [False, True] if have else [False]
class Seq(list):
    pass
for ci in range(len(cfgs)):
    offs, scs, tc, osc = cfgs[ci]
    for mode in modes:
        fp.use_native(mode)
        c = fp.Compensator(offs, scs, tc, out_scale=osc)
        for t in (tc[0], 1234, tc[1]):
            c.update(t)
            out = [0] * (3 * N)
            arr = array.array("i", out)
            one = [0, 0, 0]
            c.apply_be16_n(buf, out, N, STRIDE)
            first = list(out)
            for i in range(3 * N):
                out[i] = 0
            c.apply_be16_n(buf, out, N, STRIDE)  # the same objects again: the asm kernel's quick call
            c.apply_be16_n(buf, arr, N, STRIDE)
            c.apply_be16_n(buf, arr, N, STRIDE)
            # every kind of burst the asm kernel takes, and an out it leaves to the viper one
            views = [0] * (3 * N)
            c.apply_be16_n(memoryview(b"xy" + buf)[2:], views, N, STRIDE)
            fixed = [0] * (3 * N)
            c.apply_be16_n(bytes(buf), fixed, N, STRIDE)
            other = Seq([0] * (3 * N))
            c.apply_be16_n(buf, other, N, STRIDE)
            ones = []
            for i in range(N):
                c.apply_be16(memoryview(buf)[i * STRIDE:], one)
                ones.extend(one)
            same = ones == out and list(arr) == out and first == out and views == out and fixed == out and list(other) == out
            print("RES %d %d %d %d %s %s" % (ci, mode, t, same, ",".join(str(v) for v in c.burst3), ",".join(str(v) for v in out)))
        allocprobe.report("one_%d_%d" % (ci, mode), c.apply_be16, (buf, one))
        allocprobe.report("list_%d_%d" % (ci, mode), c.apply_be16_n, (buf, out, N))
        allocprobe.report("arr_%d_%d" % (ci, mode), c.apply_be16_n, (buf, arr, N))
fp.use_native(None)
# update() itself, heap-locked: constant scales (Horner only) and scales varying with t
cc = fp.Compensator([[1.0, 0.01, 1e-6]] * 3, [[131.0]] * 3, (-4000, 9000), out_scale=1000.0)
cv = fp.Compensator(OFFS_, SCS_, (-4000, 9000), out_scale=1000.0)
st = [0]
def upd_const():
    st[0] = (st[0] + 37) & 0x1FFF
    cc.update(st[0] - 4000)
def upd_vary():
    st[0] = (st[0] + 37) & 0x1FFF
    cv.update(st[0] - 4000)
allocprobe.report("update_const", upd_const)
allocprobe.report("update_vary", upd_vary)
"""


def test_native_and_pure_agree_exactly_on_every_interpreter(interp):
    code = DEVICE
    for name, val in (("EOFFS_", EXT_OFFS), ("ESCS_", EXT_SCS), ("OFFS_", OFFS), ("SCS_", SCS)):
        code = code.replace(name, repr(val))
    out = interp.run(code, timeout=600)
    native = int(re.search(r"^NATIVE (\d)", out, re.M).group(1))
    if interp.name in ("an385", "an500"):
        assert re.search(r"^ASM 1", out, re.M), "the asm_thumb batch kernel should load on ARM firmware"
    buf = bytes.fromhex(re.search(r"^BUF (\w+)", out, re.M).group(1))
    rows = [line.split() for line in out.splitlines() if line.startswith("RES ")]
    assert len(rows) == 2 * 3 * (1 + native)
    by = {}
    for _, ci, mode, t, same, params, res in rows:
        assert same == "1", (interp.name, ci, mode, t)
        g0, l0, b0, g1, l1, b1, g2, l2, b2, k, s = [int(v) for v in params.split(",")][:11]
        ys = [int(v) for v in res.split(",")]
        # the host's own exact evaluation of the documented formula with the device's numbers
        for i in range(24):
            for a, (g, lo, b) in enumerate(((g0, l0, b0), (g1, l1, b1), (g2, l2, b2))):
                v = _s16(buf, 14 * i + 2 * a)
                assert ys[3 * i + a] == (v * g + ((v * lo) >> k) - b) >> s
        by.setdefault((ci, t), {})[mode] = res
    if native:
        for key, modes in by.items():
            assert modes["0"] == modes["1"], (interp.name, key)
    for name, (b, ok) in _alloc(out).items():
        assert b == 0.0 and ok, (interp.name, name, b, ok)
    if not native:
        assert interp.name == "wasm", "%s should have the viper emitter" % interp.name
        pytest.skip("native kernels not compared on %s: it has no @micropython.viper emitter" % interp.name)


def _alloc(out):
    res = {}
    for line in out.splitlines():
        if line.startswith("ALLOC "):
            _, name, b, ok = line.split()
            res[name] = (float(b), ok == "ok")
    return res
