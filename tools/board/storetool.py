"""Host tool for tempcomp calibration stores: inspect, convert to JSON and back, export.

    python -m tools.board.storetool dump tempcomp.cal            # every copy, its state, the records
    python -m tools.board.storetool bin2json tempcomp.cal -o cal.json
    python -m tools.board.storetool json2bin cal.json -o tempcomp.cal
    python -m tools.board.storetool export tempcomp.cal -o calib_const.py   # const() module to freeze
    python -m tools.board.storetool put tempcomp.cal model.json --name gyro_aug  # add --export's model
    ... --nvm            the file is a dump of CircuitPython's microcontroller.nvm (two slots)
    ... json2bin --nvm 4096   write a 4096-byte nvm image (slot A used, the rest erased 0xFF)

Copy a store from a board with ``mpremote cp :tempcomp.cal .`` and back the same way.

The codec here is written from the format table in docs/store.md, independently of
lib/tempcomp/store*.py (the device code), so that a round trip through both checks the format
rather than one implementation against itself. JSON fields: format, generation, records: a
list of {name, part, serial, kind, t_unit, t_span, counter, time, values, frac}; "real" (the
values scaled by 2**-frac) and "time_utc" are written for reading and ignored on input, except
that "real" is used when "values" is absent.
"""

import struct
import sys
import time
import zlib

from tools import LIB, hostio

MAGIC = b"TCAL"
FORMAT = 1
HEADER = struct.Struct("<4sHHII")  # magic, version, count, total length, generation
ENTRY = struct.Struct("<HBBBBBBHHiiII")  # see docs/store.md "Entry"
KINDS = ["raw", "mlx90609_rezero", "mpu_offset_poly", "adi_three_point", "an12760_axis", "ellipsoid",
         "augment"]
T_UNITS = ["none", "raw", "centi_degC", "mV"]


class FormatError(ValueError):
    pass


def _ascii(b, what, allow_space=True):
    lo = 0x20 if allow_space else 0x21
    if any(not lo <= c <= 0x7E for c in b):
        raise FormatError("%s %r is not printable ASCII" % (what, b))
    return b.decode("ascii")


def decode_image(data, slot=False):
    """bytes of one store image -> dict; FormatError naming the problem."""
    if len(data) < 20:
        raise FormatError("%d bytes: too short for a store (header 16 + CRC 4)" % len(data))
    magic, version, count, length, generation = HEADER.unpack_from(data, 0)
    if magic != MAGIC:
        raise FormatError("magic %r is not %r: not a tempcomp store" % (magic, MAGIC))
    if version != FORMAT:
        raise FormatError("format version %d; this tool reads version %d" % (version, FORMAT))
    if (length > len(data)) if slot else (length != len(data)):
        raise FormatError("header length %d but %d bytes present" % (length, len(data)))
    data = data[:length]
    (crc,) = struct.unpack_from("<I", data, length - 4)
    if zlib.crc32(data[: length - 4]) != crc:
        raise FormatError("CRC32 mismatch")
    records = []
    off = 16
    for k in range(count):
        (elen, kind, t_unit, nl, pl, sl, r1, m, r2, t_lo, t_hi, counter, when) = ENTRY.unpack_from(data, off)
        text_len = nl + pl + sl + m
        want = 28 + (text_len + 3) // 4 * 4 + 4 * m
        if r1 or r2 or elen != want or off + elen > length - 4 or not 1 <= nl <= 32:
            raise FormatError("entry %d at offset %d is malformed" % (k, off))
        p = off + 28
        name = _ascii(data[p : p + nl], "name", True)
        part = _ascii(data[p + nl : p + nl + pl], "part", True)
        serial = _ascii(data[p + nl + pl : p + nl + pl + sl], "serial", True)
        frac = list(struct.unpack_from("<%db" % m, data, p + nl + pl + sl))
        values = list(struct.unpack_from("<%di" % m, data, off + elen - 4 * m))
        records.append({
            "name": name,
            "part": part,
            "serial": serial,
            "kind": KINDS[kind] if kind < len(KINDS) else kind,
            "t_unit": T_UNITS[t_unit] if t_unit < len(T_UNITS) else t_unit,
            "t_span": [t_lo, t_hi],
            "counter": counter,
            "time": when,
            "time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(when)) if when else None,
            "values": values,
            "frac": frac,
            "real": [v * 2.0 ** -f for v, f in zip(values, frac)],
        })
        off += elen
    if off != length - 4:
        raise FormatError("%d stray bytes after the last entry" % (length - 4 - off))
    return {"format": version, "generation": generation, "records": records}


def _code(value, names, what):
    if isinstance(value, int):
        return value
    if value in names:
        return names.index(value)
    raise FormatError("unknown %s %r (one of %s or an int)" % (what, value, ", ".join(names)))


def encode_image(doc):
    """dict (as decode_image returns, or edited JSON) -> bytes of one store image."""
    body = b""
    recs = doc["records"]
    for r in recs:
        name = r["name"].encode("ascii")
        part = r.get("part", "").encode("ascii")
        serial = r.get("serial", "").encode("ascii")
        frac = list(r.get("frac") or [0] * len(r.get("values", r.get("real", []))))
        if "values" in r:
            values = list(r["values"])
        else:
            values = [round(x * 2.0 ** f) for x, f in zip(r["real"], frac)]
        if len(frac) != len(values):
            raise FormatError("record %r: %d frac for %d values" % (r["name"], len(frac), len(values)))
        for v in values:
            if not -(2**31) <= v < 2**31:
                raise FormatError("record %r: value %d outside int32" % (r["name"], v))
        if not 1 <= len(name) <= 32 or len(part) > 16 or len(serial) > 32:
            raise FormatError("record %r: name/part/serial too long" % (r["name"],))
        _ascii(name, "name", True)
        m = len(values)
        text = name + part + serial + struct.pack("<%db" % m, *frac)
        text += b"\0" * (-len(text) % 4)
        elen = 28 + len(text) + 4 * m
        t_lo, t_hi = r.get("t_span", [0, 0])
        body += ENTRY.pack(elen, _code(r.get("kind", 0), KINDS, "kind"),
                           _code(r.get("t_unit", 0), T_UNITS, "t_unit"), len(name), len(part),
                           len(serial), 0, m, 0, t_lo, t_hi, r.get("counter", 0), r.get("time") or 0)
        body += text + struct.pack("<%di" % m, *values)
    length = 16 + len(body) + 4
    data = HEADER.pack(MAGIC, doc.get("format", FORMAT), len(recs), length, doc["generation"]) + body
    return data + struct.pack("<I", zlib.crc32(data))


def read_copies(path, nvm=False):
    """[(label, bytes or None)] for every copy the device code would consider."""
    if nvm:
        with open(path, "rb") as f:
            data = f.read()
        half = len(data) // 2
        return [("slot A", data[:half]), ("slot B", data[half : 2 * half])]
    out = []
    for p in (path, path + ".old", path + ".new"):
        try:
            with open(p, "rb") as f:
                out.append((p, f.read()))
        except FileNotFoundError:
            out.append((p, None))
    return out


def newest(copies, nvm=False):
    """(label, doc, problems): the valid copy with the highest generation."""
    best = None
    problems = []
    for label, data in copies:
        if data is None:
            continue
        if nvm and data.count(0xFF) == len(data):
            continue  # an erased slot (json2bin --nvm writes one): empty, not damaged
        try:
            doc = decode_image(data, slot=nvm)
        except FormatError as e:
            problems.append("%s: %s" % (label, e))
            continue
        if best is None or doc["generation"] > best[1]["generation"]:
            best = (label, doc)
    if best is None:
        raise FormatError("no valid copy: " + "; ".join(problems or ["nothing found"]))
    return best[0], best[1], problems


def to_json(doc):
    return hostio.dumps(doc, indent=2)


def _ident(name):
    s = "".join(c if ("A" <= c <= "Z" or "0" <= c <= "9") else "_" for c in name.upper())
    return "R" + s if s[0].isdigit() else s


MAX_VALUES = 4096  # docs/store.md: values per record
MAX_IMAGE = 65536  # docs/store.md: bytes per store
INT32 = (-(2**31), 2**31 - 1)


def _int(v, lo, hi, what):
    if isinstance(v, bool) or not isinstance(v, int):
        raise FormatError("%s is %r, not an integer" % (what, v))
    if not lo <= v <= hi:
        raise FormatError("%s = %d is outside %d..%d" % (what, v, lo, hi))
    return v


def _text_field(r, key, lo, hi, what):
    v = r.get(key, "")
    if not isinstance(v, str):
        raise FormatError("%s %s is %r, not a string" % (what, key, v))
    if not lo <= len(v) <= hi or any(not 0x20 <= ord(c) <= 0x7E for c in v):
        raise FormatError("%s %s %r must be %d..%d printable ASCII characters" % (what, key, v, lo, hi))


def check_doc(doc):
    """FormatError naming the record and field of anything the device would refuse in a JSON doc
    (docs/store.md limits), before it is encoded; the encoded image is then parsed by the device's
    own reader as well (device_check)."""
    if not isinstance(doc, dict):
        raise FormatError("the JSON must be an object with generation and records, got %s" % type(doc).__name__)
    for key in ("generation", "records"):
        if key not in doc:
            raise FormatError("the JSON has no %r field" % key)
    gen = _int(doc["generation"], 1, 2**32 - 1, "generation")
    if doc.get("format", FORMAT) != FORMAT:
        raise FormatError("format %r: this tool writes format %d" % (doc.get("format"), FORMAT))
    recs = doc["records"]
    if not isinstance(recs, list):
        raise FormatError("records must be a list, got %s" % type(recs).__name__)
    names = {}
    idents = {}
    for k, r in enumerate(recs):
        if not isinstance(r, dict):
            raise FormatError("record %d is %r, not an object" % (k, r))
        if "name" not in r:
            raise FormatError("record %d has no name" % k)
        _text_field(r, "name", 1, 32, "record %d" % k)
        what = "record %d (%r)" % (k, r["name"])
        if r["name"] in names:
            raise FormatError("%s: the name is used by record %d too; names must be unique" % (what, names[r["name"]]))
        names[r["name"]] = k
        ident = _ident(r["name"])
        if ident in idents:
            raise FormatError("%s: names %r and %r give the same identifier %s in an exported module; rename one"
                              % (what, idents[ident], r["name"], ident))
        idents[ident] = r["name"]
        _text_field(r, "part", 0, 16, what)
        _text_field(r, "serial", 0, 32, what)
        if "values" in r:
            vals = r["values"]
            if not isinstance(vals, list):
                raise FormatError("%s: values must be a list of integers" % what)
            for i, v in enumerate(vals):
                _int(v, INT32[0], INT32[1], "%s values[%d]" % (what, i))
        elif "real" in r:
            vals = r["real"]
            if not isinstance(vals, list):
                raise FormatError("%s: real must be a list of numbers" % what)
            for i, v in enumerate(vals):
                if isinstance(v, bool) or not isinstance(v, (int, float)) or v != v or v in (float("inf"), float("-inf")):
                    raise FormatError("%s real[%d] is %r, not a finite number" % (what, i, v))
        else:
            raise FormatError("%s has neither values nor real" % what)
        if len(vals) > MAX_VALUES:
            raise FormatError("%s: %d values; a record holds at most %d" % (what, len(vals), MAX_VALUES))
        frac = r.get("frac")
        if frac is not None:
            if not isinstance(frac, list) or len(frac) != len(vals):
                raise FormatError("%s: frac must be a list of %d integers (one per value)" % (what, len(vals)))
            for i, f in enumerate(frac):
                _int(f, -31, 31, "%s frac[%d]" % (what, i))
        if "values" not in r:
            for i, (x, f) in enumerate(zip(vals, frac or [0] * len(vals))):
                _int(round(x * 2.0 ** f), INT32[0], INT32[1], "%s real[%d] * 2**frac" % (what, i))
        for key, table in (("kind", KINDS), ("t_unit", T_UNITS)):
            v = r.get(key, 0)
            if isinstance(v, str):
                _code(v, table, key)
            else:
                _int(v, 0, 255, "%s %s" % (what, key))
        span = r.get("t_span", [0, 0])
        if not isinstance(span, list) or len(span) != 2:
            raise FormatError("%s: t_span must be [t_lo, t_hi]" % what)
        lo = _int(span[0], INT32[0], INT32[1], "%s t_span[0]" % what)
        hi = _int(span[1], INT32[0], INT32[1], "%s t_span[1]" % what)
        if lo > hi:
            raise FormatError("%s: t_span %r has t_lo > t_hi" % (what, span))
        _int(r.get("counter", 0), 0, gen, "%s counter (at most the generation)" % what)
        _int(r.get("time") or 0, 0, 2**32 - 1, "%s time" % what)


def device_check(image, slot=False):
    """Parse image with the device's own checker (lib/tempcomp/store_check.py, on the decoder of
    store_format.py): FormatError if it refuses."""
    if LIB not in sys.path:
        sys.path.insert(0, LIB)
    from tempcomp.store_check import parse
    from tempcomp.store_format import OK

    if len(image) > MAX_IMAGE:
        raise FormatError("the store would be %d bytes; the device reads at most %d" % (len(image), MAX_IMAGE))
    state, why, _, _ = parse(bytes(image), slot)
    if state != OK:
        raise FormatError("the device would refuse this store: it %s" % why)


def export_text(doc):
    """A Python module of const() values (same layout as Store.export_module)."""
    lines = ["# tempcomp calibration, store generation %d. Generated: edit by re-exporting." % doc["generation"],
             "try:", "    from micropython import const", "except ImportError:", "",
             "    def const(x):", "        return x", "", "", "GENERATION = const(%d)" % doc["generation"]]
    table = []
    for r in doc["records"]:
        k = _ident(r["name"])
        kind = _code(r["kind"], KINDS, "kind")
        unit = _code(r["t_unit"], T_UNITS, "t_unit")
        lines.append("%s_VALUES = const(%r)" % (k, tuple(r["values"])))
        lines.append("%s_FRAC = const(%r)" % (k, tuple(r["frac"])))
        lines.append("%s_META = const(%r)" % (k, (r["part"], r["serial"], kind, r["t_span"][0],
                                                  r["t_span"][1], unit, r["counter"], r["time"] or 0)))
        table.append("    %r: (%s_VALUES, %s_FRAC, %s_META)," % (r["name"], k, k, k))
    lines.append("# name: (values, frac, (part, serial, kind, t_lo, t_hi, t_unit, counter, time))")
    lines += ["RECORDS = {"] + table + ["}"]
    return "\n".join(lines) + "\n"


def put(path, model_path, name, part="", base=False):
    """Add the exported model's store values as record `name` (kind augment) to the store at
    path, keeping every other record; a new generation, written only once it checks. base=True
    stores the sim alone (the model's "store_base") for before/after comparisons on the board."""
    import os

    model = hostio.load_json(model_path)
    st = model.get("store_base" if base else "store") if isinstance(model, dict) else None
    if not isinstance(st, dict) or "values" not in st or "frac" not in st:
        raise hostio.HostError("%s: no 'store' section; write the model with python -m tools gap ... --export"
                               % model_path)
    if os.path.exists(path):
        try:
            _, doc, _ = newest(read_copies(path), False)
        except FormatError as e:
            raise hostio.HostError("%s: %s" % (path, e)) from None
        recs = [r for r in doc["records"] if r["name"] != name]
        gen = doc["generation"] + 1
    else:
        recs, gen = [], 1
    for r in recs:
        for k in ("real", "time_utc"):
            r.pop(k, None)
    recs.append({"name": name, "part": part, "serial": "", "kind": "augment", "t_unit": "none",
                 "t_span": [0, 0], "counter": gen, "time": 0, "values": st["values"], "frac": st["frac"]})
    doc = {"format": FORMAT, "generation": gen, "records": recs}
    try:
        check_doc(doc)
        image = encode_image(doc)
        decode_image(image)
        device_check(image)
    except FormatError as e:
        raise hostio.HostError("%s: %s" % (model_path, e)) from None
    hostio.write_all([(path, image)])
    print("%s: record %r (augmented model, %d values), generation %d" % (path, name, len(st["values"]), gen))
    return 0


def main(argv=None):
    ap = hostio.Parser(prog="python -m tools.board.storetool", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for cmd in ("dump", "bin2json", "export"):
        p = sub.add_parser(cmd)
        p.add_argument("store")
        p.add_argument("--nvm", action="store_true", help="the file is a microcontroller.nvm dump")
        if cmd != "dump":
            p.add_argument("-o", "--out", default="-")
    p = sub.add_parser("json2bin")
    p.add_argument("json")
    p.add_argument("-o", "--out", required=True)
    p.add_argument("--nvm", type=int, metavar="SIZE", help="write a SIZE-byte nvm image")
    p = sub.add_parser("put", help="add (or replace) the model written by simgap --export as a record")
    p.add_argument("store", help="the store file (created if absent)")
    p.add_argument("model", help="MODEL.json from python -m tools gap ... --export")
    p.add_argument("--name", required=True, help="record name the board loads it by")
    p.add_argument("--part", default="", help="part name kept with the record")
    p.add_argument("--base", action="store_true", help="store the model's base (the sim alone) instead")
    a = ap.parse_args(argv)
    try:
        if a.cmd == "put":
            return put(a.store, a.model, a.name, a.part, a.base)
        if a.cmd != "dump":
            hostio.check_output(a.out)
        if a.cmd == "json2bin":
            doc = hostio.load_json(a.json)
            try:
                check_doc(doc)
                image = encode_image(doc)
                decode_image(image)  # refuse to write what the format cannot read back
                device_check(image)  # nor what the device would refuse
                if a.nvm is not None:
                    if a.nvm < 2 * 20:
                        raise FormatError("--nvm %d: an nvm image holds two slots of at least 20 bytes" % a.nvm)
                    if len(image) > a.nvm // 2:
                        raise FormatError("%d-byte store does not fit a %d-byte nvm slot" % (len(image), a.nvm // 2))
                    image = image + b"\xff" * (a.nvm - len(image))
            except FormatError as e:
                raise hostio.HostError("%s: %s" % (a.json, e)) from None
            hostio.write_all([(a.out, image)])
            return 0
        try:
            label, doc, problems = newest(read_copies(a.store, a.nvm), a.nvm)
        except OSError as e:
            raise hostio.HostError("%s: cannot read: %s" % (e.filename or a.store, e.strerror)) from None
        except FormatError as e:
            raise hostio.HostError("%s: %s" % (a.store, e)) from None
        for p in problems:
            print("warning: %s (using %s)" % (p, label), file=sys.stderr)
        if a.cmd == "bin2json":
            hostio.write_all([(a.out, to_json(doc))])
        elif a.cmd == "export":
            try:
                check_doc(doc)
            except FormatError as e:
                raise hostio.HostError("%s: cannot export: %s" % (label, e)) from None
            hostio.write_all([(a.out, export_text(doc))])
        else:
            print("%s: format %d, generation %d, %d record(s)" % (label, doc["format"], doc["generation"], len(doc["records"])))
            for r in doc["records"]:
                print("  %-16s part=%r serial=%r kind=%s t=%d..%d %s counter=%d time=%s" % (
                    r["name"], r["part"], r["serial"], r["kind"], r["t_span"][0], r["t_span"][1],
                    r["t_unit"], r["counter"], r["time_utc"] or "-"))
                for i, (v, f, x) in enumerate(zip(r["values"], r["frac"], r["real"])):
                    print("    [%d] %11d  Q%-3d %.9g" % (i, v, f, x))
    except hostio.HostError as e:
        return hostio.fail(e)
    return 0


if __name__ == "__main__":
    sys.exit(main())
