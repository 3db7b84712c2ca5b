"""The binary layout against a byte string built by hand from the table in docs/store.md, and
round trips between the device code (lib/tempcomp/store.py) and the independent host codec
(tools/board/storetool.py)."""

import importlib.util
import json
import os
import struct
import zlib

import pytest

from tempcomp import store as st
from tempcomp.store_check import parse
from tempcomp.store_crc import crc32 as crc_bitwise
from tools.board import storetool


def _le(n, v):
    return v.to_bytes(n, "little", signed=v < 0)


def _entry(kind, t_unit, name, part, serial, t_lo, t_hi, counter, when, frac, values):
    # docs/store.md "Entry", field by field
    text = name + part + serial + bytes(f & 0xFF for f in frac)
    text += b"\0" * (-len(text) % 4)
    elen = 28 + len(text) + 4 * len(values)
    fixed = (_le(2, elen) + bytes([kind, t_unit, len(name), len(part), len(serial), 0])
             + _le(2, len(values)) + b"\0\0" + _le(4, t_lo) + _le(4, t_hi) + _le(4, counter)
             + _le(4, when))
    assert len(fixed) == 28
    return fixed + text + b"".join(_le(4, v) for v in values)


def _image(generation, entries):
    body = b"".join(entries)
    length = 16 + len(body) + 4
    head = b"TCAL" + _le(2, 1) + _le(2, len(entries)) + _le(4, length) + _le(4, generation)
    data = head + body
    return data + zlib.crc32(data).to_bytes(4, "little")


E1 = dict(kind=2, t_unit=1, name=b"gyro0", part=b"MPU6050", serial=b"S1", t_lo=-100, t_hi=2500,
          counter=1, when=1700000000, frac=[0, 14], values=[1, -2])
E2 = dict(kind=0, t_unit=0, name=b"x", part=b"", serial=b"", t_lo=0, t_hi=0, counter=2, when=0,
          frac=[0, 0], values=[2147483647, -2147483648])
GEN1 = _image(1, [_entry(**E1)])
GEN2 = _image(2, [_entry(**E1), _entry(**E2)])


def _save_two(path):
    s = st.Store(path)
    s.save_record("gyro0", [1, -2], part="MPU6050", serial="S1", kind=st.KIND_MPU_POLY,
                  frac=[0, 14], t_span=(-100, 2500), when=1700000000)
    s.save_record("x", [2147483647, -2147483648], when=0)
    return s


def test_hand_built_bytes_match_device_files(tmp_path):
    p = str(tmp_path / "cal.bin")
    _save_two(p)
    assert len(GEN2) == 112  # 16 header + 52 + 40 entries + 4 CRC, from the table by hand
    assert GEN2[:16] == bytes.fromhex("5443414c 0100 0200 70000000 02000000".replace(" ", ""))
    assert open(p, "rb").read() == GEN2
    assert open(p + ".old", "rb").read() == GEN1  # the previous generation is kept
    assert not os.path.exists(p + ".new")


def test_device_reads_hand_built_bytes(tmp_path):
    p = tmp_path / "cal.bin"
    p.write_bytes(GEN2)
    s = st.Store(str(p))
    assert s.load("x") == (2147483647, -2147483648)
    r = s.record("gyro0", part="MPU6050", kind=st.KIND_MPU_POLY)
    assert (r.part, r.serial, r.t_lo, r.t_hi, r.t_unit, r.counter, r.time) == (
        "MPU6050", "S1", -100, 2500, st.T_RAW, 1, 1700000000)
    assert list(r.frac) == [0, 14]
    assert r.real(1) == -2 / 16384.0
    assert s.names() == ["gyro0", "x"] and s.generation == 2


def test_host_codec_against_hand_built_bytes():
    doc = storetool.decode_image(GEN2)
    assert doc["generation"] == 2
    r0, r1 = doc["records"]
    assert (r0["name"], r0["part"], r0["kind"], r0["t_unit"], r0["t_span"], r0["values"], r0["frac"]) == (
        "gyro0", "MPU6050", "mpu_offset_poly", "raw", [-100, 2500], [1, -2], [0, 14])
    assert r1["values"] == [2147483647, -2147483648] and r1["time_utc"] is None
    assert storetool.encode_image(doc) == GEN2
    assert storetool.encode_image(json.loads(storetool.to_json(doc))) == GEN2


def test_round_trip_host_device_host(tmp_path):
    doc = {"generation": 41, "records": [
        {"name": "mlx", "part": "MLX90609", "serial": "E2-0417", "kind": "mlx90609_rezero",
         "t_unit": "mV", "t_span": [2300, 2900], "counter": 40, "time": 1735689600,
         "frac": [4, 4, -3], "values": [-12345, 0, 2**31 - 1]},
        {"name": "ell", "kind": "ellipsoid", "frac": [20] * 12, "t_unit": "none",
         "real": [1.0, 0.001, -0.002, 0.0, 0.998, 0.0005, 0.0, 0.0, 1.003, 12.5, -3.25, 0.125],
         "counter": 41, "time": 0},
    ]}
    p = str(tmp_path / "cal.bin")
    assert storetool.main(["json2bin", _dump(tmp_path, doc), "-o", p]) == 0
    s = st.Store(p)
    assert s.load("mlx", part="MLX90609") == (-12345, 0, 2**31 - 1)
    ell = s.record("ell", kind=st.KIND_ELLIPSOID)
    assert [ell.real(i) for i in range(12)] == pytest.approx(doc["records"][1]["real"], abs=2**-20)
    s.save_record("acc", [7, 8, 9], part="ADXL355", kind=st.KIND_ADI_3POINT, frac=2,
                  t_span=(-4000, 8500), t_unit=st.T_CENTI_C, when=1767225600)
    back = storetool.decode_image(open(p, "rb").read())
    assert back["generation"] == 42
    names = [r["name"] for r in back["records"]]
    assert names == ["mlx", "ell", "acc"]
    assert back["records"][0]["values"] == [-12345, 0, 2**31 - 1]
    assert back["records"][1]["values"] == [round(x * 2**20) for x in doc["records"][1]["real"]]
    acc = back["records"][2]
    assert (acc["kind"], acc["t_unit"], acc["t_span"], acc["counter"], acc["frac"], acc["time_utc"]) == (
        "adi_three_point", "centi_degC", [-4000, 8500], 42, [2, 2, 2], "2026-01-01T00:00:00Z")
    # the previous generation stays readable by the host tool too
    label, old, _ = storetool.newest([(p + ".old", open(p + ".old", "rb").read())])
    assert old["generation"] == 41


def _dump(tmp_path, doc):
    j = tmp_path / "in.json"
    j.write_text(json.dumps(doc))
    return str(j)


def test_export_modules_agree_and_import(tmp_path):
    p = str(tmp_path / "cal.bin")
    s = _save_two(p)
    dev = tmp_path / "calib_dev.py"
    s.export_module(str(dev))
    host = storetool.export_text(storetool.newest(storetool.read_copies(p))[1])
    assert dev.read_text() == host
    spec = importlib.util.spec_from_file_location("calib_dev", str(dev))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.GENERATION == 2
    assert mod.X_VALUES == (2147483647, -2147483648)
    assert mod.RECORDS["gyro0"] == ((1, -2), (0, 14), ("MPU6050", "S1", 2, -100, 2500, 1, 1, 1700000000))


def test_crc_fallback_matches_zlib():
    for data in (b"", b"123456789", bytes(range(256)) * 3, GEN2):
        assert crc_bitwise(data) == zlib.crc32(data)


def test_storetool_cli(tmp_path, capsys):
    p = str(tmp_path / "cal.bin")
    _save_two(p)
    assert storetool.main(["dump", p]) == 0
    out = capsys.readouterr().out
    assert "generation 2, 2 record(s)" in out and "Q14" in out
    j = str(tmp_path / "c.json")
    assert storetool.main(["bin2json", p, "-o", j]) == 0
    again = str(tmp_path / "again.bin")
    assert storetool.main(["json2bin", j, "-o", again]) == 0
    assert open(again, "rb").read() == GEN2
    nvm = str(tmp_path / "nvm.bin")
    assert storetool.main(["json2bin", j, "-o", nvm, "--nvm", "512"]) == 0
    raw = open(nvm, "rb").read()
    assert len(raw) == 512 and raw[:112] == GEN2 and raw[112:] == b"\xff" * 400
    assert storetool.main(["bin2json", nvm, "--nvm", "-o", str(tmp_path / "n.json")]) == 0
    bad = tmp_path / "bad.bin"
    bad.write_bytes(b"print('hello')\n" * 3)
    assert storetool.main(["dump", str(bad)]) == 2
    assert "not a tempcomp store" in capsys.readouterr().err


def test_entry_layout_is_what_struct_says():
    # the table's fixed entry part is 28 bytes and the header 16: checked against struct
    assert struct.calcsize("<HBBBBBBHHiiII") == 28 and struct.calcsize("<4sHHII") == 16


@pytest.mark.parametrize("change, words", [
    (dict(serial=b"S\x01"),  # header 16 + fixed entry 28 + "gyro0" + "MPU6050" + "S"
     "is malformed: byte 0x01 at offset 57 is not printable ASCII"),
    (dict(frac=[0, 40]), "is malformed: entry 0: frac[1] = 40 out of range"),
    (dict(counter=5), "is malformed: entry 0: counter 5 is after the store generation 1"),
])
def test_malformed_entry_is_named_in_words(tmp_path, change, words):
    # a whole copy (CRC right) whose entry breaks a rule of docs/store.md: the intact older copy
    # is used, and the warning says what is wrong with the newest, in words (tempcomp.store_check)
    p = str(tmp_path / "cal.bin")
    with open(p + ".old", "wb") as f:
        f.write(GEN1)
    bad = dict(E1, **change)
    with open(p, "wb") as f:
        f.write(_image(1, [_entry(**bad)]))
    s = st.Store(p)
    with pytest.warns(st.StoreWarning):
        assert s.load("gyro0") == (1, -2)
    assert len(s.warnings) == 1
    assert s.warnings[0].startswith(p + " " + words + "; using %s.old (generation 1)" % p), s.warnings
    assert parse(_image(1, [_entry(**bad)]), False)[1] == words
    # two entries of one name
    assert parse(_image(2, [_entry(**E1), _entry(**E1)]), False)[1] == "is malformed: entry 1: name 'gyro0' appears twice"
