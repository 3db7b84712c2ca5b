"""The binary layout of docs/store.md, read from the page's own tables, against the device code
(lib/tempcomp/store.py: files Store writes and reads) and the independent host codec
(tools/board/storetool.py): bytes built from the documented table equal the files both write,
and both read them back field by field; plus round trips between the device code and the host
codec."""

import importlib.util
import json
import os
import random
import re
import struct
import zlib

import pytest
import seeds
from paths import REPO

from tempcomp import store as st
from tempcomp.store_check import parse
from tempcomp.store_crc import crc32 as crc_bitwise
from tools.board import storetool

DOC = os.path.join(REPO, "docs", "store.md")


# -- the layout as docs/store.md states it ------------------------------------------------------

_FMT = {"u8": "B", "u16": "H", "u32": "I", "i8": "b", "i32": "i"}


def _tables(text, after):
    """The markdown tables (rows of cell lists) following the heading line `after`."""
    lines = text[text.index(after):].splitlines()
    tables, cur = [], []
    for ln in lines[1:]:
        if ln.startswith("#"):
            break
        if ln.startswith("|"):
            cur.append([c.strip() for c in ln.strip().strip("|").split("|")])
        elif cur:
            tables.append(cur[2:])  # the header row and |---| go
            cur = []
    return tables


def _expr(s):
    # "28 + nl + pl", "length − 4", "elen − 4m": a Python expression over the field values
    s = s.replace("\u2212", "-").replace("\u2026", "").strip()
    return re.sub(r"(\d)([a-z])", r"\1*\2", s)


class Layout:
    """The header and entry tables of the "Binary format (version 1)" section, as an encoder and a
    decoder: nothing about the layout is written in this test, every offset, size and type is
    the page's."""

    def __init__(self, text):
        self.text = text
        header, entry = _tables(text, "## Binary format (version 1)")[:2]
        self.little = "Little-endian throughout" in text
        self.header = [self._row(r) for r in header]
        self.entry = [self._row(r) for r in entry]
        elen = [r for r in self.entry if r["field"] == "elen"][0]
        self.elen = _expr(elen["meaning"].split("=", 1)[1])  # "28 + pad4(nl + pl + sl + m) + 4m"
        self.magic = re.search(r"`(\w+)`", [r for r in self.header if r["field"] == "magic"][0]["meaning"]).group(1)

    @staticmethod
    def _row(r):
        off, size, field, meaning = r
        t = re.match(r"(u8|u16|u32|i8|i32)\b", meaning)
        t = t.group(1) if t else None
        if field == "reserved":  # "0": zero bytes of the row's size
            assert meaning == "0", meaning
            t = {"1": "u8", "2": "u16", "4": "u32"}[size]
        return {"off": _expr(off), "size": _expr(size), "field": field, "meaning": meaning, "type": t}

    def _pack(self, t, v):
        return struct.pack(("<" if self.little else ">") + _FMT[t], v)

    def encode_entry(self, r):
        ns = {"nl": len(r["name"]), "pl": len(r["part"]), "sl": len(r["serial"]), "m": len(r["values"]),
              "pad4": lambda x: (x + 3) // 4 * 4}
        ns["elen"] = eval(self.elen, {}, ns)  # noqa: S307 (the page's formula)
        out = bytearray(ns["elen"])
        fields = dict(r, elen=ns["elen"], nl=ns["nl"], pl=ns["pl"], sl=ns["sl"], m=ns["m"], reserved=0)
        at = 0
        for row in self.entry:
            off = eval(row["off"], {}, ns) if row["off"] else at  # noqa: S307  ("…": after the previous)
            if row["field"] == "padding":
                at = off  # zeros up to the values
                continue
            if row["type"] and row["size"] in ("1", "2", "4"):
                b = self._pack(row["type"], fields[row["field"]])
            elif row["type"]:  # "i8 per value", "i32 per value"
                b = b"".join(self._pack(row["type"], v) for v in fields[row["field"]])
            else:  # printable ASCII
                b = fields[row["field"]].encode("ascii")
            assert len(b) == eval(row["size"], {}, ns), row  # noqa: S307
            out[off:off + len(b)] = b
            at = off + len(b)
        return bytes(out)

    def _put(self, out, ns, row, value):
        off = eval(row["off"], {}, ns)  # noqa: S307
        b = self._pack(row["type"], value)
        assert len(b) == int(row["size"]), row
        out[off:off + len(b)] = b

    def encode(self, generation, records, version=1):
        entries = b"".join(self.encode_entry(r) for r in records)
        start = int([r for r in self.header if r["field"] == "entries"][0]["off"])
        crc = [r for r in self.header if r["field"] == "crc32"][0]
        ns = {"count": len(records), "version": version, "generation": generation}
        ns["length"] = start + len(entries) + int(crc["size"])
        out = bytearray(ns["length"])
        for row in self.header:
            if row["field"] == "magic":
                out[int(row["off"]):int(row["off"]) + int(row["size"])] = self.magic.encode("ascii")
            elif row["field"] == "entries":
                out[start:start + len(entries)] = entries
            elif row["field"] != "crc32":
                self._put(out, ns, row, ns[row["field"]])
        # "binascii.crc32 (the zlib CRC-32) of bytes 0 … length − 5"
        self._put(out, ns, crc, zlib.crc32(bytes(out[:ns["length"] - int(crc["size"])])))
        return bytes(out)

    def _get(self, data, base, ns, row):
        off = base + eval(row["off"], {}, ns)  # noqa: S307
        return struct.unpack_from(("<" if self.little else ">") + _FMT[row["type"]], data, off)[0]

    def decode(self, data):
        """(header fields, records) of an image, every field where the tables put it."""
        ns = {}
        for row in self.header:
            if row["type"] and row["off"].isdigit():
                ns[row["field"]] = self._get(data, 0, ns, row)
        m0 = [r for r in self.header if r["field"] == "magic"][0]
        ns["magic"] = data[:int(m0["size"])].decode("ascii")
        crc = [r for r in self.header if r["field"] == "crc32"][0]
        ns["crc_ok"] = self._get(data, 0, ns, crc) == zlib.crc32(data[:ns["length"] - 4])
        at = int([r for r in self.header if r["field"] == "entries"][0]["off"])
        records = []
        for _ in range(ns["count"]):
            f = {}
            fixed = [r for r in self.entry if r["off"].isdigit() and r["type"]]
            for row in fixed:
                v = self._get(data, at, f, row)
                if row["field"] == "reserved":
                    assert v == 0, "reserved field at %s is %d" % (row["off"], v)
                else:
                    f[row["field"]] = v
            for row in self.entry:
                if row in fixed or not row["off"]:
                    continue
                off = at + eval(row["off"], {}, f)  # noqa: S307
                n = eval(row["size"], {}, f)  # noqa: S307
                if row["type"]:
                    f[row["field"]] = list(struct.unpack_from("<%d%s" % (f["m"], _FMT[row["type"]]), data, off))
                else:
                    f[row["field"]] = data[off:off + n].decode("ascii")
            tail = at + 28 + f["nl"] + f["pl"] + f["sl"] + f["m"]
            assert data[tail:at + f["elen"] - 4 * f["m"]].count(0) == at + f["elen"] - 4 * f["m"] - tail, "padding"
            records.append(f)
            at += f["elen"]
        assert at == ns["length"] - 4, "the entries end at the CRC"
        return ns, records


LAYOUT = Layout(open(DOC, encoding="utf-8").read())


def _rec(name, part="", serial="", kind=0, t_unit=0, t_lo=0, t_hi=0, counter=1, time=0, frac=(), values=()):
    return {"name": name, "part": part, "serial": serial, "kind": kind, "t_unit": t_unit, "t_lo": t_lo,
            "t_hi": t_hi, "counter": counter, "time": time, "frac": list(frac), "values": list(values)}


def _image(generation, recs):
    return LAYOUT.encode(generation, [_rec(**r) for r in recs])




def _random_records(rng, n):
    """n records that use every field: names 1..32 characters (every padding), empty and full
    part and serial, 0..12 values at the int32 ends, frac -31..31, any kind and t_unit."""
    text = "".join(chr(c) for c in range(0x20, 0x7F))
    recs = []
    for k in range(n):
        name = "%d" % k + "".join(rng.choice(text) for _ in range(rng.randint(0, 30)))
        m = rng.choice([0, 1, 2, 3, 5, 12])
        lo = rng.randint(-2**31, 2**31 - 1)
        recs.append(_rec(name=name, part="".join(rng.choice(text) for _ in range(rng.choice([0, 7, 16]))),
                         serial="".join(rng.choice(text) for _ in range(rng.choice([0, 1, 32]))),
                         kind=rng.randint(0, 255), t_unit=rng.randint(0, 3), t_lo=lo,
                         t_hi=rng.randint(lo, 2**31 - 1), counter=k + 1, time=rng.randint(0, 2**32 - 1),
                         frac=[rng.randint(-31, 31) for _ in range(m)],
                         values=[rng.choice([-2**31, 2**31 - 1, 0, rng.randint(-2**31, 2**31 - 1)]) for _ in range(m)]))
    return recs


def _save(store, r):
    store.save_record(r["name"], r["values"], part=r["part"], serial=r["serial"], kind=r["kind"],
                      frac=r["frac"], t_span=(r["t_lo"], r["t_hi"]), t_unit=r["t_unit"], when=r["time"])


FIELDS = ("name", "part", "serial", "kind", "t_unit", "t_lo", "t_hi", "counter", "time", "frac", "values")


@pytest.mark.parametrize("seed", seeds.seeds("store_format", 3))
def test_the_documented_layout_is_what_the_store_writes_and_reads(tmp_path, seed):
    # Store.save_record, one save per record: the file decoded by the page's tables holds exactly
    # what was saved (each entry's counter the generation that wrote it), the page's encoding of
    # those records is the file byte for byte (padding, reserved bytes, CRC), and a file built
    # from the tables loads through Store field by field
    recs = _random_records(random.Random(seed), 6)
    p = str(tmp_path / "cal.bin")
    store = st.Store(p)
    for r in recs:
        _save(store, r)
    data = open(p, "rb").read()
    head, got = LAYOUT.decode(data)
    assert (head["magic"], head["version"], head["count"], head["length"], head["generation"], head["crc_ok"]) == (
        "TCAL", 1, len(recs), len(data), len(recs), True)
    assert [{k: g[k] for k in FIELDS} for g in got] == recs
    assert LAYOUT.encode(len(recs), recs) == data
    q = tmp_path / "from_the_page.bin"
    q.write_bytes(LAYOUT.encode(len(recs), recs))
    back = st.Store(str(q))
    assert back.names() == [r["name"] for r in recs] and back.generation == len(recs)
    for r in recs:
        rec = back.record(r["name"])
        assert (rec.part, rec.serial, rec.kind, rec.t_unit, rec.t_lo, rec.t_hi, rec.counter, rec.time) == (
            r["part"], r["serial"], r["kind"], r["t_unit"], r["t_lo"], r["t_hi"], r["counter"], r["time"])
        assert list(rec.values) == r["values"] and list(rec.frac) == r["frac"]


@pytest.mark.parametrize("seed", seeds.seeds("store_format_host", 3))
def test_the_host_codec_writes_and_reads_the_documented_layout(seed):
    recs = _random_records(random.Random(seed), 6)
    data = LAYOUT.encode(9, recs)
    doc = storetool.decode_image(data)
    assert doc["generation"] == 9 and len(doc["records"]) == len(recs)
    for h, r in zip(doc["records"], recs):
        kind = storetool.KINDS.index(h["kind"]) if isinstance(h["kind"], str) else h["kind"]
        unit = storetool.T_UNITS.index(h["t_unit"]) if isinstance(h["t_unit"], str) else h["t_unit"]
        assert (h["name"], h["part"], h["serial"], kind, unit, h["t_span"], h["counter"], h["time"],
                h["frac"], h["values"]) == (r["name"], r["part"], r["serial"], r["kind"], r["t_unit"],
                                            [r["t_lo"], r["t_hi"]], r["counter"], r["time"], r["frac"], r["values"])
    assert storetool.encode_image(doc) == data
    assert storetool.encode_image(json.loads(storetool.to_json(doc))) == data


@pytest.mark.parametrize("seed", seeds.seeds("store_format_codec", 3))
def test_the_device_codec_writes_and_reads_the_documented_layout(seed):
    # tempcomp.store_encode.encode and tempcomp.store_format.decode, what Store stands on
    from array import array

    from tempcomp.store_encode import encode
    from tempcomp.store_format import Record, decode

    recs = _random_records(random.Random(seed), 6)
    data = LAYOUT.encode(7, [dict(r, counter=min(r["counter"], 7)) for r in recs])
    objs = [Record(r["name"], array("i", r["values"]), array("b", r["frac"]), r["part"], r["serial"], r["kind"],
                   r["t_lo"], r["t_hi"], r["t_unit"], min(r["counter"], 7), r["time"]) for r in recs]
    assert bytes(encode(7, objs)) == data
    gen, back = decode(data)
    assert gen == 7
    assert [{k: (list(getattr(b, k)) if k in ("values", "frac") else getattr(b, k)) for k in FIELDS} for b in back] == [
        dict(r, counter=min(r["counter"], 7)) for r in recs]


def test_the_layout_comes_from_the_page():
    # the codec above reads the page: a page with two fields swapped, or without the padding,
    # describes other bytes than the store writes (so an edit of the table fails these tests)
    text = LAYOUT.text
    swapped = text.replace("| 12 | 4 | t_lo |", "| 16 | 4 | T_LO |").replace("| 16 | 4 | t_hi |", "| 12 | 4 | t_hi |")
    swapped = swapped.replace("| T_LO |", "| t_lo |")
    unpadded = text.replace("28 + pad4(nl + pl + sl + m) + 4m", "28 + nl + pl + sl + m + 4m")
    for other in (swapped, unpadded):
        assert other != text
        assert Layout(other).encode(2, [_rec(**E1), _rec(**E2)]) != GEN2
    assert LAYOUT.encode(2, [_rec(**E1), _rec(**E2)]) == GEN2


def _section(text, heading):
    start = text.index(heading)
    nxt = re.search(r"^#", text[start + len(heading):], re.M)
    return text[start:start + len(heading) + (nxt.start() if nxt else len(text))]


def test_readme_shows_the_same_tables():
    readme = open(os.path.join(REPO, "README.md"), encoding="utf-8").read()
    assert _tables(readme, "### Binary format (version 1)") == _tables(LAYOUT.text, "## Binary format (version 1)")


def test_kinds_and_temperature_units_are_the_pages():
    # the page's kinds table and t_unit list are the store's constants (store.KIND_*, store.T_*:
    # module attributes, some loaded on first use) and the host codec's names, in order
    kinds = [t for t in _tables(LAYOUT.text, "Kinds (") if t and t[0][1].startswith("`KIND_")][0]
    assert [int(n) for n, _, _ in kinds] == list(range(len(kinds)))
    for n, c, _ in kinds:
        assert getattr(st, c.strip("`")) == int(n), c
    assert len(kinds) == len(storetool.KINDS)
    units = [(c, int(n)) for c, n in re.findall(r"`(T_[A-Z_]+)` (\d+)", LAYOUT.text)]
    units = list(dict(units).items())
    assert [n for _, n in units] == list(range(len(units)))
    for c, n in units:
        assert getattr(st, c) == n, c
    assert [c for c, _ in units] == ["T_" + n.upper().replace("CENTI_DEGC", "CENTI_C") for n in storetool.T_UNITS]


E1 = dict(kind=2, t_unit=1, name="gyro0", part="MPU6050", serial="S1", t_lo=-100, t_hi=2500,
          counter=1, time=1700000000, frac=[0, 14], values=[1, -2])
E2 = dict(kind=0, t_unit=0, name="x", part="", serial="", t_lo=0, t_hi=0, counter=2, time=0,
          frac=[0, 0], values=[2147483647, -2147483648])
GEN1 = _image(1, [E1])
GEN2 = _image(2, [E1, E2])


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


@pytest.mark.parametrize("change, words", [
    (dict(serial="S\x01"),  # header 16 + fixed entry 28 + "gyro0" + "MPU6050" + "S"
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
        f.write(_image(1, [bad]))
    s = st.Store(p)
    with pytest.warns(st.StoreWarning):
        assert s.load("gyro0") == (1, -2)
    assert len(s.warnings) == 1
    assert s.warnings[0].startswith(p + " " + words + "; using %s.old (generation 1)" % p), s.warnings
    assert parse(_image(1, [bad]), False)[1] == words
    # two entries of one name
    assert parse(_image(2, [E1, E1]), False)[1] == "is malformed: entry 1: name 'gyro0' appears twice"
