"""Every single-bit flip in a stored copy is detected; with one copy damaged the other is used,
with a warning naming the damaged one; with no good copy left the error names the problem."""

import os

import pytest
from storecut import FakeNvm, ram_dir

from tempcomp import store as st
from tempcomp import store_format
from tempcomp.store_check import parse
from tempcomp.store_encode import encode

OLD = (10, -20, 30, 2**31 - 1)
NEW = (11, -21, 31, -(2**31))
pytestmark = pytest.mark.filterwarnings("ignore::tempcomp.store.StoreWarning")


@pytest.fixture
def tmp_path(tmp_path):
    yield from ram_dir(tmp_path)


def _two_generations(p):
    s = st.Store(p)
    s.save_record("g", OLD, part="MLX90609", serial="A1", kind=st.KIND_MLX_REZERO, frac=3,
                  t_span=(2300, 2900), t_unit=st.T_MV, when=1735689600)
    s.save_record("g", NEW, part="MLX90609", serial="A1", kind=st.KIND_MLX_REZERO, frac=3,
                  t_span=(2300, 2900), t_unit=st.T_MV, when=1735689700)
    s.save("h", (1, 2, 3))
    return open(p, "rb").read(), open(p + ".old", "rb").read()


def _flip(b, bit):
    b = bytearray(b)
    b[bit // 8] ^= 1 << (bit % 8)
    return bytes(b)


def _put(p, data):
    with open(p, "wb") as f:
        f.write(data)


def test_every_bit_flip_detected_by_the_parser(tmp_path):
    cur, _ = _two_generations(str(tmp_path / "cal.bin"))
    assert parse(cur, False)[0] == store_format.OK
    for bit in range(8 * len(cur)):
        state, why, _, _ = parse(_flip(cur, bit), False)
        assert state in (store_format.DAMAGED, store_format.FOREIGN), (bit, state)
        assert why


def test_flip_in_current_uses_previous_with_warning(tmp_path):
    p = str(tmp_path / "cal.bin")
    cur, old = _two_generations(p)
    g_old = st.Store(p + ".old")  # the previous generation's content, read as a store
    assert g_old.load("g") == NEW  # .old holds generation 2 (g=NEW), current adds h
    named = 0
    for bit in range(8 * len(cur)):
        _put(p, _flip(cur, bit))
        s = st.Store(p)
        assert s.load("g") == NEW, bit
        with pytest.raises(st.StoreError, match="newest copy .*lost") as e:
            s.load("h")  # h came with the damaged generation: not invented, and said lost
        lost = str(e.value).split("(lost): ")[1]
        named += "'h'" in lost or "maybe more" in lost
        assert len(s.warnings) == 1 and s.warnings[0].startswith(p + " "), (bit, s.warnings)
        assert "using %s.old" % p in s.warnings[0]
    assert named >= 8 * len(cur) - 8, named  # all but a flip inside the name 'h' itself


def test_flip_in_previous_keeps_current_with_warning(tmp_path):
    p = str(tmp_path / "cal.bin")
    cur, old = _two_generations(p)
    for bit in range(0, 8 * len(old), 3):
        _put(p + ".old", _flip(old, bit))
        s = st.Store(p)
        assert s.load("h") == (1, 2, 3) and s.load("g") == NEW
        assert len(s.warnings) == 1 and s.warnings[0].startswith(p + ".old "), bit


def test_flip_in_only_copy_is_an_error_not_garbage(tmp_path):
    p = str(tmp_path / "cal.bin")
    cur, _ = _two_generations(p)
    os.remove(p + ".old")
    reasons = set()
    for bit in range(8 * len(cur)):
        _put(p, _flip(cur, bit))
        with pytest.raises(st.StoreError, match="no usable copy") as e:
            st.Store(p).load("g")
        reasons.add(str(e.value).split(p, 1)[1].split("(")[0].strip())
    assert any("CRC32" in r for r in reasons) and any("wrong length" in r for r in reasons)
    assert any("corrupted magic" in r for r in reasons)  # one bit off TCAL: ours, damaged


def test_save_repairs_damaged_copy_and_keeps_the_good_one(tmp_path):
    p = str(tmp_path / "cal.bin")
    cur, old = _two_generations(p)
    _put(p, _flip(cur, 77))
    s = st.Store(p)
    s.save("g", (5,))
    s2 = st.Store(p)
    assert s2.load("g") == (5,) and s2.warnings == []
    assert open(p + ".old", "rb").read() == old  # the good previous copy became the backup
    with pytest.raises(KeyError):
        s2.load("h")  # it was only in the damaged generation


def test_nvm_flip_in_either_slot():
    nvm = FakeNvm(512)
    s = st.Store(nvm=nvm)
    s.save("g", OLD)  # slot A, generation 1
    s.save("g", NEW)  # slot B, generation 2
    good = bytes(nvm.b)
    n = len(encode(2, [st.Record("g", NEW, [0] * 4)]))
    for slot, expect in ((256, OLD), (0, NEW)):
        for bit in range(8 * n):
            nvm.b[:] = _flip(good, 8 * slot + bit)
            s = st.Store(nvm=nvm)
            assert s.load("g") == expect, (slot, bit)
            assert len(s.warnings) == 1, (slot, bit)
            assert s.warnings[0].startswith("nvm slot %s" % ("B" if slot else "A"))
    # the next save rewrites the damaged slot, never the good one
    nvm.b[:] = _flip(good, 8 * 256 + 40)
    st.Store(nvm=nvm).save("g", (7,))
    assert bytes(nvm.b[:256]) == good[:256]
    s = st.Store(nvm=nvm)
    assert s.load("g") == (7,) and s.warnings == []
