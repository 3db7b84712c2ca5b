"""Bad input gives a clear error naming the problem, and nothing is overwritten unless the
caller asks (force=True)."""

import builtins
import os
import time

import pytest
from storecut import FakeNvm

from tempcomp import store as st
from tools.board import storetool

pytestmark = pytest.mark.filterwarnings("ignore::tempcomp.store.StoreWarning")


def _listing(d):
    out = {}
    for name in sorted(os.listdir(d)):
        with open(os.path.join(d, name), "rb") as f:
            out[name] = f.read()
    return out


@pytest.fixture
def saved(tmp_path):
    p = str(tmp_path / "cal.bin")
    s = st.Store(p)
    s.save_record("gyro", (1, 2, 3), part="MPU6050", kind=st.KIND_MPU_POLY, when=5)
    s.save("other", (4,))
    return p


def test_never_saved_is_keyerror(tmp_path, saved):
    with pytest.raises(KeyError, match="'nope' was never saved"):
        st.Store(saved).load("nope")
    with pytest.raises(KeyError):
        st.Store(str(tmp_path / "absent.bin")).load("gyro")
    assert st.Store(str(tmp_path / "absent.bin")).names() == []
    before = _listing(tmp_path)
    with pytest.raises(KeyError):
        st.Store(saved).delete("nope")
    assert _listing(tmp_path) == before


@pytest.mark.parametrize("content, problem", [
    (b"", "is empty"),
    (b"print('my program')\n" * 4, "is not a tempcomp store"),
])
def test_empty_or_foreign_file_is_refused(tmp_path, content, problem):
    p = str(tmp_path / "cal.bin")
    with open(p, "wb") as f:
        f.write(content)
    with pytest.raises(st.StoreError, match=problem):
        st.Store(p).load("gyro")
    with pytest.raises(st.StoreError, match=problem + ".*refusing to overwrite"):
        st.Store(p).save("gyro", (1,))
    assert _listing(tmp_path) == {"cal.bin": content}  # nothing written, not even .new
    st.Store(p).save_record("gyro", (1,), force=True)
    assert st.Store(p).load("gyro") == (1,)


def test_newer_format_version_is_refused(tmp_path, saved):
    doc = storetool.decode_image(open(saved, "rb").read())
    doc["format"] = 2
    doc["generation"] += 5
    newer = storetool.encode_image(doc)
    with open(saved, "wb") as f:
        f.write(newer)
    before = _listing(tmp_path)
    with pytest.raises(st.StoreError, match="format version 2; this tempcomp reads version 1"):
        st.Store(saved).load("gyro")
    with pytest.raises(st.StoreError, match="version 2"):
        st.Store(saved).save("gyro", (9,))
    assert _listing(tmp_path) == before
    st.Store(saved).save_record("gyro", (9,), force=True)
    assert st.Store(saved).load("gyro") == (9,)


@pytest.mark.parametrize("change", ["append", "truncate"])
def test_wrong_length(tmp_path, saved, change):
    data = open(saved, "rb").read()
    os.remove(saved + ".old")
    with open(saved, "wb") as f:
        f.write(data + b"\0\0\0\0" if change == "append" else data[:-1])
    with pytest.raises(st.StoreError, match="wrong length: header says %d bytes, file has %d" % (
            len(data), len(data) + (4 if change == "append" else -1))):
        st.Store(saved).load("gyro")
    before = _listing(tmp_path)
    with pytest.raises(st.StoreError, match="no usable copy"):
        st.Store(saved).save("gyro", (1,))
    assert _listing(tmp_path) == before


def test_record_for_another_part_or_kind(saved):
    s = st.Store(saved)
    with pytest.raises(ValueError, match="'gyro' is for part 'MPU6050', not 'MLX90609'"):
        s.load("gyro", part="MLX90609")
    with pytest.raises(ValueError, match="holds kind 2, not 3"):
        s.record("gyro", kind=st.KIND_ADI_3POINT)
    assert s.load("gyro", part="MPU6050") == (1, 2, 3)


@pytest.mark.parametrize("name, values, kw, problem", [
    ("", (1,), {}, "name '' is 0 bytes"),
    ("x" * 33, (1,), {}, "is 33 bytes; it must be 1..32"),
    ("x" * 1000, (1,), {}, "is 1000 bytes"),
    ("gyr\u00f3", (1,), {}, "must be printable ASCII"),
    ("\u00b5", (1,), {}, "must be printable ASCII"),
    ("nul\0", (1,), {}, "must be printable ASCII"),
    ("tab\t", (1,), {}, "must be printable ASCII"),
    (b"gyro", (1,), {}, "name must be a str"),
    ("g", (2**31,), {}, r"values\[0\] = 2147483648 is outside int32"),
    ("g", (0, -(2**31) - 1), {}, r"values\[1\] = -2147483649 is outside int32"),
    ("g", (1.5,), {}, r"values\[0\] = 1.5 is not an int"),
    ("g", ("3",), {}, "is not an int"),
    ("g", (1, 2), {"frac": [3]}, "frac has 1 entries for 2 values"),
    ("g", (1,), {"frac": 40}, "outside -31..31"),
    ("g", (1,), {"t_span": (5, 1)}, "t_lo > t_hi"),
    ("g", (1,), {"t_span": (0, 2**31)}, "outside int32"),
    ("g", (1,), {"part": "MPU6050-REVISION-C"}, "part 'MPU6050-REVISION-C' is 18 bytes"),
    ("g", (1,), {"serial": "\u00e9"}, "serial"),
    ("g", (1,), {"when": -1}, "when -1"),
    ("g", (1,), {"kind": 300}, "kind 300"),
])
def test_bad_arguments_name_the_problem_and_write_nothing(tmp_path, saved, name, values, kw, problem):
    before = _listing(tmp_path)
    with pytest.raises(ValueError, match=problem):
        st.Store(saved).save_record(name, values, **kw)
    assert _listing(tmp_path) == before


def test_get_into_checks_length_and_copies(saved):
    from array import array

    s = st.Store(saved)
    out = array("i", [0, 0])
    with pytest.raises(ValueError, match="'gyro' has 3 values; out has 2"):
        s.get_into("gyro", out)
    out = array("i", [0, 0, 0])
    assert s.get_into("gyro", out) == 3 and list(out) == [1, 2, 3]
    assert s.get("gyro", 2) == 3


def test_read_only_filesystem_gives_the_boot_py_fix(tmp_path, saved, monkeypatch):
    real_open = builtins.open

    def ro_open(path, mode="r", *a, **kw):
        if "w" in mode or "x" in mode:
            raise OSError(30, "Read-only filesystem")
        return real_open(path, mode, *a, **kw)

    before = _listing(tmp_path)
    monkeypatch.setattr(builtins, "open", ro_open)
    with pytest.raises(st.ReadOnlyStoreError) as e:
        st.Store(saved).save("gyro", (7,))
    monkeypatch.undo()
    msg = str(e.value)
    assert isinstance(e.value, OSError) and e.value.args[0] == 30
    assert 'storage.remount("/", readonly=False)' in msg and "boot.py" in msg
    assert "USB host can no longer write" in msg and "Store(nvm=microcontroller.nvm)" in msg
    assert _listing(tmp_path) == before


def test_two_store_objects_see_each_others_saves(saved):
    a, b = st.Store(saved), st.Store(saved)
    assert b.load("other") == (4,)
    a.save("other", (5,))
    assert b.load("other") == (5,)  # load always reads the medium
    assert b.get("other", 0) == 5
    a.save("other", (6,))
    assert b.get("other", 0) == 5  # lookups use what was loaded: allocation-free, no I/O
    b.refresh()
    assert b.get("other", 0) == 6


def test_names_values_accepted(saved):
    s = st.Store(saved)
    s.save("mpu6050 accel offsets: x/y/z", iter([1, 2, 3]))  # 28 chars, spaces, an iterable
    s.save("e", ())
    s2 = st.Store(saved)
    assert s2.load("mpu6050 accel offsets: x/y/z") == (1, 2, 3) and s2.load("e") == ()


def test_delete(saved):
    s = st.Store(saved)
    s.delete("other")
    assert st.Store(saved).names() == ["gyro"]


def test_time_stamp_from_the_rtc_only_when_set(saved, monkeypatch):
    # the clock is injected: 2026-01-01T00:00:00.75Z, truncated to whole seconds in the record
    monkeypatch.setattr(time, "time", lambda: 1767225600.75)
    s = st.Store(saved)
    s.save("t", (1,))
    assert s.record("t").time == 1767225600
    monkeypatch.setattr(time, "time", lambda: 86400.0 * 365)  # 1971: the clock was never set
    s.save("t", (1,))
    assert s.record("t").time == 0 and s.record("t").counter == s.generation


def test_fixed():
    assert st.fixed(1.5, 4) == 24 and st.fixed(-0.25, 2) == -1 and st.fixed(1024.0, -10) == 1
    with pytest.raises(ValueError, match="outside int32"):
        st.fixed(1.0, 31)


def test_constructor_errors():
    with pytest.raises(ValueError, match="either a path or nvm"):
        st.Store()
    with pytest.raises(ValueError, match="either a path or nvm"):
        st.Store("x", nvm=bytearray(64))
    with pytest.raises(ValueError, match="does not fit nvm"):
        st.Store(nvm=bytearray(30))


def test_nvm_foreign_data_is_not_overwritten():
    nvm = FakeNvm(256)
    nvm.b[0:16] = b"user settings:42"
    nvm.b[128:144] = b"more user data!!"
    before = bytes(nvm.b)
    with pytest.raises(st.StoreError, match="not a tempcomp store"):
        st.Store(nvm=nvm).load("g")
    with pytest.raises(st.StoreError, match="refusing to overwrite"):
        st.Store(nvm=nvm).save("g", (1,))
    assert bytes(nvm.b) == before and nvm.writes == 0
    # a region after the user's data is the answer; force=True the other
    s = st.Store(nvm=nvm, offset=16, size=96)
    # 16 header + 28 entry + 4 ("g" and 3 frac bytes) + 12 values + 4 CRC = 64
    with pytest.raises(ValueError, match="store of 64 bytes does not fit the 48-byte nvm slot"):
        s.save("g", (1, 2, 3))
    s = st.Store(nvm=FakeNvm(1024), offset=512)
    s.save("g", (1, 2, 3))
    assert s.load("g") == (1, 2, 3)


def test_nvm_foreign_one_slot_needs_force_and_is_kept_while_possible():
    nvm = FakeNvm(256)
    nvm.b[0:16] = b"user settings:42"
    with pytest.raises(st.StoreError, match="slot A is not a tempcomp store"):
        st.Store(nvm=nvm).load("g")
    with pytest.raises(st.StoreError, match="refusing to overwrite"):
        st.Store(nvm=nvm).save("g", (1,))
    st.Store(nvm=nvm).save_record("g", (1,), force=True)  # goes to the free slot B
    assert bytes(nvm.b[0:16]) == b"user settings:42"
    s = st.Store(nvm=nvm)
    assert s.load("g") == (1,) and len(s.warnings) == 1 and "slot A" in s.warnings[0]
    with pytest.raises(st.StoreError, match="slot A is not a tempcomp store"):
        s.save("g", (2,))  # the next save would need slot A: asked again
    assert s.load("g") == (1,) and bytes(nvm.b[0:16]) == b"user settings:42"
