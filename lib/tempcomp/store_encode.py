"""Records to bytes: the store's encoder, the checks of what a save is given, the const() export.

Pure (no file or nvm access): ``new_record`` checks ``save_record``'s arguments and builds the
Record, ``encode`` lays records out as a store image (docs/store.md "Binary format"; the decoder
is ``tempcomp.store_format.decode``), ``module_text`` is the Python source of
``Store.export_module``. Loaded by the first save or export, never by a boot that only reads.
Stands on ``tempcomp.store_format``; ``tempcomp.store_write`` commits what this encodes.
"""

import struct
from array import array

from tempcomp.store_format import (
    CRC_SIZE,
    ENTRY,
    FRAC_MAX,
    FRAC_MIN,
    HEADER,
    KIND_RAW,
    MAGIC,
    MAX_NAME,
    MAX_PART,
    MAX_SERIAL,
    MAX_VALUES,
    T_NONE,
    T_RAW,
    VERSION,
    Record,
    crc,
    entry_size,
)

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


MAX_IMAGE = const(65536)  # bytes in one store image
INT32_MIN = -2147483648  # not const(): beyond the 32-bit small-int range
INT32_MAX = 2147483647
UINT32_MAX = 4294967295
_UNIX_2000 = 946684800  # 2000-01-01 in UTC seconds since 1970
_RTC_SET_YEAR = const(2024)  # an RTC reading before this year is taken as "clock not set"


def _check_int32(what, v):
    if not isinstance(v, int) and not isinstance(v, float):
        index = getattr(v, "__index__", None)  # e.g. numpy integers on the host
        if index is not None:
            v = index()
    if not isinstance(v, int):
        raise ValueError("%s = %r is not an int" % (what, v))
    if not INT32_MIN <= v <= INT32_MAX:
        raise ValueError("%s = %d is outside int32 (-2147483648..2147483647)" % (what, v))
    return v


def pow2(f):
    """2**f as a float, for f of either sign."""
    return float(1 << f) if f >= 0 else 1.0 / (1 << -f)


def fixed(x, frac):
    """round(x * 2**frac) as an int, checked to fit int32 (ValueError otherwise)."""
    if not FRAC_MIN <= frac <= FRAC_MAX:
        raise ValueError("frac %r outside %d..%d" % (frac, FRAC_MIN, FRAC_MAX))
    return _check_int32("fixed(%r, %d)" % (x, frac), round(x * pow2(frac)))


def _check_text(what, s, hi, lo, first):
    # printable ASCII only: MicroPython's str.encode/decode do not validate "ascii"
    if not isinstance(s, str):
        raise ValueError("%s must be a str, got %r" % (what, s))
    b = s.encode()
    if not lo <= len(b) <= hi:
        raise ValueError("%s %r is %d bytes; it must be %d..%d ASCII characters" % (what, s, len(b), lo, hi))
    for i in range(len(b)):
        if not first <= b[i] <= 0x7E:
            raise ValueError("%s %r must be printable ASCII (byte 0x%02x at %d)" % (what, s, b[i], i))
    return b


def _now():
    # UTC seconds since 1970 when the board's clock looks set, else 0 (docs/store.md: rec.time)
    try:
        import time

        t = int(time.time())
        conv = getattr(time, "gmtime", None) or time.localtime
        if conv(t)[0] < _RTC_SET_YEAR:
            return 0
        if conv(0)[0] == 2000:  # MicroPython ports with the 2000 epoch
            t += _UNIX_2000
        return t if 0 <= t <= UINT32_MAX else 0
    except Exception:
        return 0


def new_record(name, values, part="", serial="", kind=KIND_RAW, frac=0, t_span=None, t_unit=None, when=None):
    """The Record ``Store.save_record`` saves, every argument checked (ValueError naming it).

    values: ints within int32; frac: fraction bits, one int for all or one per value
    (-31..31); t_span: (t_lo, t_hi) calibrated temperature span in t_unit (default T_RAW
    when a span is given); when: UTC seconds since 1970, default the RTC (0 if not set).
    """
    _check_text("name", name, MAX_NAME, 1, 0x20)
    _check_text("part", part, MAX_PART, 0, 0x20)
    _check_text("serial", serial, MAX_SERIAL, 0, 0x20)
    try:
        m = len(values)
    except TypeError:  # any iterable of ints will do
        values = tuple(values)
        m = len(values)
    if m > MAX_VALUES:
        raise ValueError("%d values; at most %d" % (m, MAX_VALUES))
    vals = array("i", [0] * m)
    for i in range(m):
        vals[i] = _check_int32("values[%d]" % i, values[i])
    if isinstance(frac, int):
        frac = [frac] * m
    if len(frac) != m:
        raise ValueError("frac has %d entries for %d values (wrong length)" % (len(frac), m))
    fr = array("b", [0] * m)
    for i in range(m):
        f = frac[i]
        if not isinstance(f, int) or not FRAC_MIN <= f <= FRAC_MAX:
            raise ValueError("frac[%d] = %r outside %d..%d" % (i, f, FRAC_MIN, FRAC_MAX))
        fr[i] = f
    if not isinstance(kind, int) or not 0 <= kind <= 255:
        raise ValueError("kind %r must be 0..255 (a KIND_ constant)" % (kind,))
    if t_span is None:
        t_lo = t_hi = 0
        t_unit = T_NONE if t_unit is None else t_unit
    else:
        if len(t_span) != 2:
            raise ValueError("t_span must be (t_lo, t_hi), got %r" % (t_span,))
        t_lo = _check_int32("t_span[0]", t_span[0])
        t_hi = _check_int32("t_span[1]", t_span[1])
        if t_lo > t_hi:
            raise ValueError("t_span %r: t_lo > t_hi" % (t_span,))
        t_unit = T_RAW if t_unit is None else t_unit
    if not isinstance(t_unit, int) or not 0 <= t_unit <= 255:
        raise ValueError("t_unit %r must be 0..255 (a T_ constant)" % (t_unit,))
    if when is None:
        when = _now()
    if not isinstance(when, int) or not 0 <= when <= UINT32_MAX:
        raise ValueError("when %r must be UTC seconds since 1970 within uint32" % (when,))
    return Record(name, vals, fr, part, serial, kind, t_lo, t_hi, t_unit, 0, when)


def encode(gen, recs):
    """The store image of records ``recs`` at generation ``gen``: header, entries, CRC32
    (docs/store.md "Binary format"); ValueError when it would pass MAX_IMAGE bytes."""
    parts = []
    size = HEADER + CRC_SIZE
    for r in recs:
        nb, pb, sb = r.name.encode(), r.part.encode(), r.serial.encode()
        m = len(r.values)
        parts.append((r, nb, pb, sb, m))
        size += entry_size(len(nb), len(pb), len(sb), m)
    if size > MAX_IMAGE:
        raise ValueError("store would be %d bytes; at most %d" % (size, MAX_IMAGE))
    buf = bytearray(size)
    struct.pack_into("<4sHHII", buf, 0, MAGIC, VERSION, len(recs), size, gen)
    off = HEADER
    for r, nb, pb, sb, m in parts:
        elen = entry_size(len(nb), len(pb), len(sb), m)
        struct.pack_into("<HBBBBBBHHiiII", buf, off, elen, r.kind, r.t_unit, len(nb), len(pb),
                         len(sb), 0, m, 0, r.t_lo, r.t_hi, r.counter, r.time)
        p = off + ENTRY
        for b in (nb, pb, sb):
            buf[p:p + len(b)] = b
            p += len(b)
        for i in range(m):
            buf[p + i] = r.frac[i] & 0xFF
        p = off + elen - 4 * m
        for i in range(m):
            struct.pack_into("<i", buf, p + 4 * i, r.values[i])
        off += elen
    struct.pack_into("<I", buf, size - CRC_SIZE, crc(memoryview(buf)[0:size - CRC_SIZE]))
    return buf


def _ident(name):
    s = ""
    for c in name.upper():
        s += c if ("A" <= c <= "Z" or "0" <= c <= "9") else "_"
    if "0" <= s[0] <= "9":
        s = "R" + s
    return s


def module_text(recs, generation):
    """Python source of const() values for recs (for freezing calibration into firmware)."""
    lines = [
        "# tempcomp calibration, store generation %d. Generated: edit by re-exporting." % generation,
        "try:",
        "    from micropython import const",
        "except ImportError:",
        "",
        "    def const(x):",
        "        return x",
        "",
        "",
        "GENERATION = const(%d)" % generation,
    ]
    seen = {}
    table = []
    for r in recs:
        k = _ident(r.name)
        if k in seen:
            raise ValueError("names %r and %r give the same identifier %s" % (seen[k], r.name, k))
        seen[k] = r.name
        lines.append("%s_VALUES = const(%r)" % (k, tuple(r.values)))
        lines.append("%s_FRAC = const(%r)" % (k, tuple(r.frac)))
        lines.append("%s_META = const((%r, %r, %d, %d, %d, %d, %d, %d))" % (
            k, r.part, r.serial, r.kind, r.t_lo, r.t_hi, r.t_unit, r.counter, r.time))
        table.append("    %r: (%s_VALUES, %s_FRAC, %s_META)," % (r.name, k, k, k))
    lines.append("# name: (values, frac, (part, serial, kind, t_lo, t_hi, t_unit, counter, time))")
    lines.append("RECORDS = {")
    lines.extend(table)
    lines.append("}")
    return "\n".join(lines) + "\n"


