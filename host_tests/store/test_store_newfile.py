"""path.new, the one name a save writes into, cannot be used to make the store write anywhere
else: a symlink, a hard link, a directory, a FIFO or someone's file put there is refused and left
alone (issue 17, item 5), on CPython with real links and in the MicroPython VM, whose port has
neither lstat nor O_EXCL. What a power cut leaves there (empty, torn, whole) is still ours and
is replaced by the next save."""

import builtins
import os

import pytest

from tempcomp import store as st

pytestmark = pytest.mark.filterwarnings("ignore::tempcomp.store.StoreWarning")

VICTIM = b"precious data, not a store\n"


def listing(d):
    out = {}
    for name in sorted(os.listdir(d)):
        p = os.path.join(d, name)
        if os.path.islink(p):
            out[name] = ("link", os.readlink(p))
        elif os.path.isfile(p):
            with open(p, "rb") as f:
                out[name] = f.read()
        else:
            out[name] = "other"
    return out


@pytest.fixture
def env(tmp_path):
    """A store with one generation saved, and a victim file elsewhere."""
    d = tmp_path / "cal"
    d.mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_bytes(VICTIM)
    p = str(d / "cal.bin")
    st.Store(p).save("g", (1, 2, 3))
    return p, victim


def _refused(p, match):
    before = listing(os.path.dirname(p))
    with pytest.raises(st.StoreError, match=match):
        st.Store(p).save("g", (7, 8, 9))
    assert listing(os.path.dirname(p)) == before  # nothing created, renamed or removed
    assert st.Store(p).load("g") == (1, 2, 3)  # the calibration is still there


def test_symlink_to_a_victim_is_refused_and_the_victim_never_written(env):
    p, victim = env
    os.symlink(str(victim), p + ".new")
    _refused(p, r"cal.bin.new is a symbolic link to '.*victim.txt'.*refusing to write it")
    assert victim.read_bytes() == VICTIM
    s = st.Store(p)
    assert s.load("g") == (1, 2, 3)
    assert any("symbolic link" in w for w in s.warnings)  # reading says so too


def test_symlink_to_a_store_image_is_never_read(env, tmp_path):
    # a link to a valid store of a higher generation would otherwise be taken as current
    p, _ = env
    other = str(tmp_path / "other.bin")
    s = st.Store(other)
    for v in range(5):
        s.save("g", (666, v))
    os.symlink(other, p + ".new")
    assert st.Store(p).load("g") == (1, 2, 3)
    _refused(p, "symbolic link")


def test_dangling_symlink_creates_nothing(env, tmp_path):
    p, _ = env
    target = tmp_path / "created_by_the_store"
    os.symlink(str(target), p + ".new")
    _refused(p, "symbolic link")
    assert not target.exists()


def test_hard_link_is_refused(env):
    p, victim = env
    os.link(str(victim), p + ".new")
    _refused(p, "2 hard links")
    assert victim.read_bytes() == VICTIM


def test_directory_and_fifo_are_refused_without_reading(env):
    p, _ = env
    os.mkdir(p + ".new")
    _refused(p, "is a directory")
    os.rmdir(p + ".new")
    os.mkfifo(p + ".new")  # reading it would block forever
    _refused(p, "not a regular file")


def test_foreign_file_is_refused_then_force_removes_only_that_name(env):
    p, victim = env
    with open(p + ".new", "wb") as f:
        f.write(b"my notes: nothing to do with calibration\n")
    _refused(p, r"cal.bin.new is not a tempcomp store.*refusing to write it.*force=True")
    st.Store(p).save_record("g", (7, 8, 9), force=True)
    assert st.Store(p).load("g") == (7, 8, 9)
    assert not os.path.exists(p + ".new")


def test_force_removes_the_link_never_its_target(env):
    p, victim = env
    os.symlink(str(victim), p + ".new")
    st.Store(p).save_record("g", (7, 8, 9), force=True)
    assert victim.read_bytes() == VICTIM
    assert st.Store(p).load("g") == (7, 8, 9)
    assert sorted(os.listdir(os.path.dirname(p))) == ["cal.bin", "cal.bin.old"]


@pytest.mark.parametrize("content", [b"", b"T", b"TCA", b"\xff" * 64, b"\0" * 10, b"TCAL" + b"\x17" * 40])
def test_what_a_cut_leaves_is_ours_and_replaced(env, content):
    p, _ = env
    with open(p + ".new", "wb") as f:
        f.write(content)
    st.Store(p).save("g", (7, 8, 9))
    s = st.Store(p)
    assert s.load("g") == (7, 8, 9) and s.warnings == []
    assert not os.path.exists(p + ".new")


def test_a_link_planted_between_check_and_create_is_not_followed(env, monkeypatch):
    """The race a check alone cannot close: O_EXCL makes the create itself refuse."""
    p, victim = env
    real_open = builtins.open

    def planting_open(path, mode="r", *a, **kw):
        if str(path) == p + ".new" and "x" in mode:
            os.symlink(str(victim), path)
        return real_open(path, mode, *a, **kw)

    monkeypatch.setattr(builtins, "open", planting_open)
    with pytest.raises(st.StoreError, match="appeared during the save"):
        st.Store(p).save("g", (7, 8, 9))
    monkeypatch.undo()
    assert victim.read_bytes() == VICTIM
    assert st.Store(p).load("g") == (1, 2, 3)


def test_symlinks_refused_in_the_micropython_vm(mpvm):
    """The VM's port (VfsPosix on Emscripten's filesystem) has symlinks but no lstat and no
    "x" mode: os.ilistdir's entry type is what shows the link."""
    out = mpvm("import store_link_check", symlinks=(("/d/cal.bin.new", "/d/victim.txt"),
                                                    ("/d/dangle.bin.new", "/d/nothere")))
    assert "DONE" in out, out
    assert not [ln for ln in out.splitlines() if ln.startswith("FAIL")], out
    oks = {ln.split()[1] for ln in out.splitlines() if ln.startswith("OK ")}
    assert oks == {"reads_with_warning", "symlink_refused", "victim_intact", "link_kept", "dangling_refused",
                   "force_removes_link", "foreign_refused", "own_torn_new_replaced"}, out
