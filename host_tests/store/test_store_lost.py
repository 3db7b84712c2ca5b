"""Say what was lost: when the newest copy of a store is corrupt (a flipped bit, not a power cut)
and an older copy is used, a record only the newest held reads as a StoreError naming the corrupt
copy and the lost records, never as "KeyError: never saved"; the warning names them too."""

import pytest
from storecut import FakeNvm, ram_dir

from tempcomp import store as st
from tempcomp.store_check import parse

pytestmark = pytest.mark.filterwarnings("ignore::tempcomp.store.StoreWarning")


@pytest.fixture
def tmp_path(tmp_path):
    yield from ram_dir(tmp_path)


def _flip(b, bit):
    b = bytearray(b)
    b[bit // 8] ^= 1 << (bit % 8)
    return bytes(b)


def _two_saves(s):
    s.save("gyro", (1, 2, 3))      # generation 1
    s.save("acc", (4, 5, 6))       # generation 2: only the newest copy holds acc


def test_a_record_only_the_corrupt_newest_copy_held_is_named_as_lost(tmp_path):
    p = str(tmp_path / "cal.bin")
    _two_saves(st.Store(p))
    cur = open(p, "rb").read()
    with open(p, "wb") as f:
        f.write(_flip(cur, 8 * (len(cur) - 8)))  # a bit of acc's last value
    s = st.Store(p)
    assert s.load("gyro") == (1, 2, 3)  # from cal.bin.old
    assert any("'acc'" in w and "lost" in w for w in s.warnings), s.warnings
    with pytest.raises(st.StoreError) as e:
        s.load("acc")
    assert not isinstance(e.value, KeyError)
    msg = str(e.value)
    assert "newest copy" in msg and p in msg and "generation 2" in msg and "CRC32" in msg
    assert "'acc'" in msg.split("lost")[1]


def test_an_intact_store_still_says_never_saved(tmp_path):
    p = str(tmp_path / "cal.bin")
    s = st.Store(p)
    _two_saves(s)
    with pytest.raises(KeyError, match="never saved"):
        st.Store(p).load("mag")


def test_every_bit_flip_of_the_newest_copy(tmp_path):
    p = str(tmp_path / "cal.bin")
    _two_saves(st.Store(p))
    cur = open(p, "rb").read()
    for bit in range(8 * len(cur)):
        with open(p, "wb") as f:
            f.write(_flip(cur, bit))
        s = st.Store(p)
        with pytest.raises(st.StoreError):
            s.load("acc")
        try:
            assert s.load("gyro") == (1, 2, 3)
        except st.StoreError as e:  # the flip made it a newer format version: refused whole
            assert "format version" in str(e), (bit, e)


def test_nvm_slots_too():
    nvm = FakeNvm(1024)
    _two_saves(st.Store(nvm=nvm))
    a = bytes(nvm[0:512])
    b = bytes(nvm[512:1024])
    newest = 512 if parse(b, True)[2] > parse(a, True)[2] else 0
    nvm[newest + 40] ^= 0x10
    s = st.Store(nvm=nvm)
    assert s.load("gyro") == (1, 2, 3)
    with pytest.raises(st.StoreError, match="nvm slot .*'acc'"):
        s.load("acc")
