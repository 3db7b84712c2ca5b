"""Power cut at every byte of a write and inside every open/rename/remove of a save: the store
then loads the previous or the new calibration, never garbage, never nothing; and the next
save works."""

import os

import pytest
from storecut import FakeNvm, Medium, PowerCut, ram_dir

from tempcomp import store as st
from tempcomp.store_encode import encode

pytestmark = pytest.mark.filterwarnings("ignore::tempcomp.store.StoreWarning")


@pytest.fixture
def tmp_path(tmp_path):
    yield from ram_dir(tmp_path)


OLDER = tuple(range(-600, -588))
OLD = (123456, -7, 0, 2**31 - 1, -(2**31), 1, 2, 3, 4, 5, 6, 7)
NEW = (-1, -2, -3, 99, 100000, 1 << 30, -(1 << 30), 8, 9, 10, 11, 12)
NEW2 = (42,) * 12
H = (5, 6)


def _image(tmp, recs_by_gen):
    """Bytes of valid images, made by the device code itself in a scratch directory."""
    p = str(tmp / "scratch.bin")
    s = st.Store(p)
    out = []
    for recs in recs_by_gen:
        for name, vals in recs:
            s.save_record(name, vals, part="MPU6050", when=1)
        out.append(open(p, "rb").read())
    for f in (p, p + ".old"):
        if os.path.exists(f):
            os.remove(f)
    return out


def _flip(b, bit):
    b = bytearray(b)
    b[bit // 8] ^= 1 << (bit % 8)
    return bytes(b)


def _scenarios(tmp):
    """name -> ({suffix: bytes}, value of "g" before the save or None, extra names kept)."""
    g1, g2 = _image(tmp, [[("g", OLDER)], [("g", OLD)]])
    c1, c2 = _image(tmp, [[("g", OLDER), ("h", H)], [("g", OLD)]])
    return {
        "first_save": ({}, None, {}),
        "one_generation": ({"": g1}, OLDER, {}),
        "two_generations": ({"": c2, ".old": c1}, OLD, {"h": H}),
        "interrupted_commit": ({"": g1, ".new": g2}, OLD, {}),
        "after_fat_cut": ({".old": g1, ".new": g2}, OLD, {}),
        "current_damaged": ({"": _flip(g2, 200), ".old": g1}, OLDER, {}),
        "stale_new_copy": ({"": g2, ".old": g1, ".new": g2}, OLD, {}),
    }


def _setup(d, files):
    d.mkdir()
    p = str(d / "cal.bin")
    for suffix, data in files.items():
        with Medium.real_open(p + suffix, "wb") as f:
            f.write(data)
    return p


def _check_after_cut(p, before, extra, why):
    s = st.Store(p)
    if before is None:
        try:
            got = s.load("g")
        except KeyError:
            got = None
    else:
        got = s.load("g")  # never nothing: must not raise
    assert got in (before, NEW), "%s: loaded %r" % (why, got)
    for name, vals in extra.items():
        assert s.load(name) == vals, why
    return s


def _follow_up(p, why):
    s = st.Store(p)
    s.save("g", NEW2)
    s2 = st.Store(p)
    assert s2.load("g") == NEW2, why
    assert s2.warnings == [], why  # everything healed by one good save
    assert not os.path.exists(p + ".new"), why


SCENARIOS = ["first_save", "one_generation", "two_generations", "interrupted_commit",
             "after_fat_cut", "current_damaged", "stale_new_copy"]


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_torn_write_at_every_byte(tmp_path, monkeypatch, scenario):
    files, before, extra = _scenarios(tmp_path)[scenario]
    n_image = len(_image(tmp_path, [[("g", NEW)] + list(extra.items())])[0])
    clean = scenario != "current_damaged"
    checked = 0
    for tail in ("truncate", "old", "ff"):
        for k in range(n_image + 1):
            d = tmp_path / ("%s_%d" % (tail, k))
            p = _setup(d, files)
            m = Medium(monkeypatch, d)
            m.tear = (k, tail)
            s = st.Store(p)
            with pytest.raises(PowerCut):
                s.save("g", NEW)
            why = "%s: torn at byte %d of %d, tail %s" % (scenario, k, n_image, tail)
            after = _check_after_cut(p, before, extra, why)
            if clean:
                assert after.warnings == [], why  # a torn scratch file is not a damaged copy
            _follow_up(p, why)
            monkeypatch.undo()
            checked += 1
    assert checked == 3 * (n_image + 1)


@pytest.mark.parametrize("fat", [False, True], ids=["atomic_rename", "fat_rename"])
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_cut_inside_open_rename_remove(tmp_path, monkeypatch, scenario, fat):
    files, before, extra = _scenarios(tmp_path)[scenario]
    # count the operations of an uninterrupted save first
    p = _setup(tmp_path / "count", files)
    m = Medium(monkeypatch, tmp_path / "count", fat=fat)
    st.Store(p).save("g", NEW)
    total = m.count
    kinds = {op[0] for op in m.log}
    monkeypatch.undo()
    assert total >= 3 and {"open", "rename"} <= kinds
    assert st.Store(p).load("g") == NEW
    for n in range(total):
        for when in ("before", "after"):
            d = tmp_path / ("%s_%d" % (when, n))
            p = _setup(d, files)
            m = Medium(monkeypatch, d, fat=fat)
            m.cut = (n, when)
            with pytest.raises(PowerCut):
                st.Store(p).save("g", NEW)
            why = "%s (fat=%s): cut %s operation %d %r" % (scenario, fat, when, n, m.log[-1])
            _check_after_cut(p, before, extra, why)
            _follow_up(p, why)
            monkeypatch.undo()


def test_save_is_durable_before_it_returns(tmp_path, monkeypatch):
    """The data is fsync'ed before the rename that makes it current (CPython path)."""
    calls = []
    real_fsync = os.fsync
    real_rename = os.rename
    monkeypatch.setattr(os, "fsync", lambda fd: (calls.append("fsync"), real_fsync(fd))[1])
    monkeypatch.setattr(os, "rename", lambda a, b: (calls.append("rename " + os.path.basename(b)), real_rename(a, b))[1])
    p = str(tmp_path / "cal.bin")
    st.Store(p).save("g", OLD)
    assert calls[0] == "fsync" and "rename cal.bin" in calls
    assert calls.index("fsync") < calls.index("rename cal.bin")
    assert calls[-1] == "fsync"  # the directory, so the rename itself is on disk


NVM_SCENARIOS = ["blank", "zeroed", "one_generation", "two_generations_a_newer",
                 "two_generations_b_newer", "slot_a_damaged"]


def _nvm_state(name):
    nvm = FakeNvm(1024, fill=0 if name == "zeroed" else 0xFF)
    s = st.Store(nvm=nvm)
    before = None
    if name == "one_generation":
        s.save("g", OLD)
        before = OLD
    elif name == "two_generations_b_newer":
        s.save("g", OLDER)  # gen 1 in slot A
        s.save("g", OLD)  # gen 2 in slot B
        before = OLD
    elif name == "two_generations_a_newer":
        s.save("g", OLDER)  # A
        s.save("g", OLDER)  # B
        s.save("g", OLD)  # gen 3 in A
        before = OLD
    elif name == "slot_a_damaged":
        s.save("g", OLDER)
        s.save("g", OLD)
        nvm.b[30] ^= 0x10  # slot A (gen 1) damaged; slot B (gen 2) good
        before = OLD
    return nvm, before


@pytest.mark.parametrize("scenario", NVM_SCENARIOS)
def test_nvm_torn_write_at_every_byte(scenario):
    nvm0, before = _nvm_state(scenario)
    n_image = len(encode(1, [st.Record("g", NEW, [0] * 12)]))
    for tail in ("old", "ff"):
        for k in range(n_image + 1):
            nvm = FakeNvm(1024)
            nvm.b[:] = nvm0.b
            nvm.tear = (k, tail)
            with pytest.raises(PowerCut):
                st.Store(nvm=nvm).save("g", NEW)
            why = "%s: nvm torn at byte %d, tail %s" % (scenario, k, tail)
            s = st.Store(nvm=nvm)
            if before is None:
                try:
                    got = s.load("g")
                except KeyError:
                    got = None
            else:
                got = s.load("g")
            assert got in (before, NEW), why
            s.save("g", NEW2)
            assert st.Store(nvm=nvm).load("g") == NEW2, why


def test_nvm_alternates_slots_and_keeps_previous():
    nvm = FakeNvm(512)
    s = st.Store(nvm=nvm)
    s.save("g", OLDER)
    a = bytes(nvm.b[:256])
    s.save("g", OLD)
    assert bytes(nvm.b[:256]) == a  # gen 2 went to slot B; slot A untouched
    s.save("g", NEW)
    assert bytes(nvm.b[:256]) != a and st.Store(nvm=nvm).load("g") == NEW
    assert nvm.writes == 3  # one assignment (one erase/program cycle) per save
