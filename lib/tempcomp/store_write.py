"""Writing a tempcomp store: encode, crash-safe commit to a file or nvm slots, const() export.

Loaded by the first ``Store.save()``, ``save_record()``, ``delete()`` or ``export_module()``, never
by a board that only reads its calibration at boot (``tempcomp.store`` holds the reader; docs/ram.md
has the heap figures). Call the ``Store`` methods; these functions are their bodies. The format and
the power-cut argument are in ``tempcomp.store`` and docs/store.md.
"""

import os
import struct
from array import array

from tempcomp.store import (
    FRAC_MAX,
    FRAC_MIN,
    KIND_RAW,
    MAGIC,
    MAX_NAME,
    MAX_PART,
    MAX_SERIAL,
    MAX_VALUES,
    T_NONE,
    T_RAW,
    VERSION,
    ReadOnlyStoreError,
    Record,
    StoreError,
    _crc,
    _entry_size,
    _pow2,
)

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


# (private const() names are not module attributes on MicroPython: the ones shared with
# tempcomp.store are repeated here, with the same values)
_HDR = const(16)
_ENTRY = const(28)  # fixed part of an entry, "<HBBBBBBHHiiII"
_CRC = const(4)
_MAX_IMAGE = const(65536)
_INT32_MIN = -2147483648  # not const(): beyond the 32-bit small-int range
_INT32_MAX = 2147483647
_UINT32_MAX = 4294967295
_UNIX_2000 = 946684800  # 2000-01-01 in UTC seconds since 1970
_RTC_SET_YEAR = const(2024)  # an RTC reading before this year is taken as "clock not set"
try:
    import errno

    _EROFS = getattr(errno, "EROFS", 30)
except ImportError:
    _EROFS = 30

# copy states (tempcomp.store)
_OK = const(0)
_MISSING = const(1)
_BLANK = const(2)
_DAMAGED = const(3)
_FOREIGN = const(4)
_NEWER = const(5)

_READ_ONLY_HELP = (
    "; on CircuitPython the CIRCUITPY drive is read-only to code while USB can write it: "
    'add `import storage; storage.remount("/", readonly=False)` to boot.py (then the USB host '
    "can no longer write CIRCUITPY until that line is removed; use the REPL or safe mode to undo "
    "it), or use Store(nvm=microcontroller.nvm)"
)


def _errno(e):
    return e.args[0] if e.args else None


def _find(recs, name):
    for i in range(len(recs)):
        if recs[i].name == name:
            return i
    return -1


def _check_int32(what, v):
    if not isinstance(v, int) and not isinstance(v, float):
        index = getattr(v, "__index__", None)  # e.g. numpy integers on the host
        if index is not None:
            v = index()
    if not isinstance(v, int):
        raise ValueError("%s = %r is not an int" % (what, v))
    if not _INT32_MIN <= v <= _INT32_MAX:
        raise ValueError("%s = %d is outside int32 (-2147483648..2147483647)" % (what, v))
    return v


def fixed(x, frac):
    """round(x * 2**frac) as an int, checked to fit int32 (ValueError otherwise)."""
    if not FRAC_MIN <= frac <= FRAC_MAX:
        raise ValueError("frac %r outside %d..%d" % (frac, FRAC_MIN, FRAC_MAX))
    return _check_int32("fixed(%r, %d)" % (x, frac), round(x * _pow2(frac)))


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
    # UTC seconds since 1970 when the board's clock looks set, else 0 (see module docstring)
    try:
        import time

        t = int(time.time())
        conv = getattr(time, "gmtime", None) or time.localtime
        if conv(t)[0] < _RTC_SET_YEAR:
            return 0
        if conv(0)[0] == 2000:  # MicroPython ports with the 2000 epoch
            t += _UNIX_2000
        return t if 0 <= t <= _UINT32_MAX else 0
    except Exception:
        return 0


def _encode(gen, recs):
    parts = []
    size = _HDR + _CRC
    for r in recs:
        nb, pb, sb = r.name.encode(), r.part.encode(), r.serial.encode()
        m = len(r.values)
        parts.append((r, nb, pb, sb, m))
        size += _entry_size(len(nb), len(pb), len(sb), m)
    if size > _MAX_IMAGE:
        raise ValueError("store would be %d bytes; at most %d" % (size, _MAX_IMAGE))
    buf = bytearray(size)
    struct.pack_into("<4sHHII", buf, 0, MAGIC, VERSION, len(recs), size, gen)
    off = _HDR
    for r, nb, pb, sb, m in parts:
        elen = _entry_size(len(nb), len(pb), len(sb), m)
        struct.pack_into("<HBBBBBBHHiiII", buf, off, elen, r.kind, r.t_unit, len(nb), len(pb),
                         len(sb), 0, m, 0, r.t_lo, r.t_hi, r.counter, r.time)
        p = off + _ENTRY
        for b in (nb, pb, sb):
            buf[p:p + len(b)] = b
            p += len(b)
        for i in range(m):
            buf[p + i] = r.frac[i] & 0xFF
        p = off + elen - 4 * m
        for i in range(m):
            struct.pack_into("<i", buf, p + 4 * i, r.values[i])
        off += elen
    struct.pack_into("<I", buf, size - _CRC, _crc(memoryview(buf)[0:size - _CRC]))
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


def save_record(st, name, values, part="", serial="", kind=KIND_RAW, frac=0,
                t_span=None, t_unit=None, when=None, force=False):
    """Store one sensor's record (see the module docstring); replaces one of the same name.

    values: ints within int32; frac: fraction bits, one int for all or one per value
    (-31..31); t_span: (t_lo, t_hi) calibrated temperature span in t_unit (default T_RAW
    when a span is given); when: UTC seconds since 1970, default the RTC (0 if not set).
    force=True overwrites a copy that is not a store of this version (its data is lost).
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
    if not isinstance(when, int) or not 0 <= when <= _UINT32_MAX:
        raise ValueError("when %r must be UTC seconds since 1970 within uint32" % (when,))
    rec = Record(name, vals, fr, part, serial, kind, t_lo, t_hi, t_unit, 0, when)
    _write(st, rec, None, force)


def delete(st, name, force=False):
    """Remove a record (a crash-safe write like save); KeyError if it is not there."""
    _write(st, None, name, force)


def _write(st, rec, drop, force):
    ok = False
    try:
        best, states, recs, gen = st._state(force, True)
        if gen >= _UINT32_MAX:
            raise StoreError("generation counter exhausted")
        recs = list(recs)
        gen += 1
        if rec is not None:
            rec.counter = gen
            i = _find(recs, rec.name)
            if i < 0:
                recs.append(rec)
            else:
                recs[i] = rec
        else:
            i = _find(recs, drop)
            if i < 0:
                raise KeyError("%r was never saved in %r" % (drop, st))
            recs.pop(i)
        image = _encode(gen, recs)
        if st._nvm is None:
            _commit_file(st, image, best, states, force)
        else:
            _commit_nvm(st, image, best, states, force)
        st._set_cache(recs, gen)
        ok = True
    finally:
        if not ok:  # an error or a power cut in a test: re-read before trusting the cache
            st._recs = None
            st._index = None


def _refuse(st, states, i, force):
    state = states[0][i]
    if force or state in (_MISSING, _BLANK, _DAMAGED, _OK):
        return
    raise StoreError("%s %s; refusing to overwrite it (pass force=True to replace it, "
                     "losing its content)" % (st._labels()[i], states[1][i]))


# File backend. Only rename is trusted to be atomic: LittleFS commits a rename in one
# metadata block; POSIX rename(2) replaces atomically; FAT (and Windows) refuse to rename
# over an existing file, so there the old target is removed first, and the window between
# is covered by the reader taking the newest valid copy of path, path.old, path.new.


def _wrap(st, e, what):
    if _errno(e) == _EROFS:
        raise ReadOnlyStoreError(_EROFS, "cannot %s: read-only filesystem%s" % (what, _READ_ONLY_HELP))
    raise e


def _remove(st, p):
    try:
        os.remove(p)
    except OSError as e:
        _wrap(st, e, "remove " + p)


def _replace(st, src, dst):
    try:
        os.rename(src, dst)
        return
    except OSError as e:
        if _errno(e) == _EROFS or not st._exists(dst) or not st._exists(src):
            _wrap(st, e, "rename %s to %s" % (src, dst))
    # FAT/Windows: rename does not replace. dst is never the newest copy here.
    _remove(st, dst)
    try:
        os.rename(src, dst)
    except OSError as e:
        _wrap(st, e, "rename %s to %s" % (src, dst))


def _check_new(st, states, force):
    # path.new before anything changes: what a cut left there (empty, torn or whole, our
    # magic or erased bytes at the start) is ours to remove; anything else is refused.
    state, why = states[0][2], states[1][2]
    if force or state in (_MISSING, _DAMAGED, _OK):
        return
    new = st._file_names()[2]
    if state == _FOREIGN:
        head = st._read_file(new) or b""
        torn = True
        for i in range(min(4, len(head))):
            torn = torn and head[i] in (MAGIC[i], 0, 0xFF)
        if torn:  # empty, or a torn start of our own write
            return
    raise StoreError("%s %s; refusing to write it (remove it, or pass force=True to remove "
                     "that name: nothing is ever written through it)" % (new, why))


def _open_new(st, p, force):
    # Exclusive creation: a save never opens an existing file for writing, so a symlink or
    # a foreign file put at path.new cannot make it write anywhere else. Whatever is there
    # now was vetted by _check_new (or force): only the name is removed.
    if st._entry(p) is not None:
        from tempcomp.store_check import alien as what

        alien = what(st, p)
        if alien is not None and not force:
            raise StoreError("%s became %s during the save; refusing to write it" % (p, alien))
        _remove(st, p)
    try:
        return open(p, "xb")  # O_CREAT|O_EXCL: CPython (never follows a symlink), LittleFS, FAT
    except (OSError, ValueError) as e:
        if isinstance(e, OSError) and _errno(e) == _EROFS:
            _wrap(st, e, "create " + p)
        if st._entry(p) is not None:
            raise StoreError("%s appeared during the save (another program?); refusing to "
                             "write it; the store is unchanged" % p)
    # A port whose open() has no "x" (MicroPython's VfsPosix reads "xb" as "rb" and fails
    # on the missing file): nothing is at p, checked just now without following links.
    try:
        return open(p, "wb")
    except OSError as e:
        _wrap(st, e, "write " + p)
        raise


def _write_verified(st, p, image, force=False):
    f = _open_new(st, p, force)
    try:
        f.write(image)
        f.flush()
        fileno = getattr(f, "fileno", None)
        if fileno is not None and hasattr(os, "fsync"):
            os.fsync(fileno())  # CPython: data on disk before the rename makes it current
    finally:
        f.close()
    if hasattr(os, "sync"):
        if not hasattr(os, "fsync"):  # MicroPython: flush the block device cache
            os.sync()
    back = st._read_file(p)
    if back != image:
        raise OSError(5, "%s did not read back as written (flash fault?); store unchanged" % p)


def _sync_dir(st):
    # CPython/POSIX: make the renames themselves durable. MicroPython's VFS commits a
    # rename before returning, and os.open does not exist there.
    rdonly = getattr(os, "O_RDONLY", None)
    if rdonly is None or not hasattr(os, "fsync"):
        return
    p = st.path or ""
    d = p[: p.rfind("/")] if "/" in p else "."
    try:
        fd = os.open(d or "/", rdonly)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _commit_file(st, image, best, states, force):
    cur, old, new = st._file_names()
    _refuse(st, states, 0, force)
    _refuse(st, states, 1, force)
    _check_new(st, states, force)
    states = states[0]
    # 1. make `cur` hold the newest valid copy (normally it already does)
    if best == 1:
        if states[0] != _MISSING:
            _remove(st, cur)
        _replace(st, old, cur)
    elif best == 2:
        if states[0] != _MISSING:
            _replace(st, cur, old)
        _replace(st, new, cur)
    elif best < 0:
        for i in (0, 1):
            if states[i] != _MISSING:
                _remove(st, (cur, old)[i])
    # 2. the new image goes to a scratch name, created exclusively, read back
    _write_verified(st, new, image, force)
    # 3. commit: the newest copy becomes .old, the new image becomes current
    if st._exists(cur):
        _replace(st, cur, old)
    _replace(st, new, cur)
    _sync_dir(st)


# nvm backend: the slot not holding the newest copy is rewritten in one assignment
# (CircuitPython erases and programs per assignment) and read back.


def _commit_nvm(st, image, best, states, force):
    state = states[0]
    if best >= 0:
        target = 1 - best
    elif state[0] in (_FOREIGN, _NEWER) and state[1] not in (_FOREIGN, _NEWER):
        target = 1
    else:
        target = 0
    label = st._labels()[target]
    _refuse(st, states, target, force)
    a, n = st._slots[target]
    if len(image) > n:
        raise ValueError("store of %d bytes does not fit the %d-byte nvm slot" % (len(image), n))
    nvm = st._nvm
    if nvm is None:
        return
    nvm[a:a + len(image)] = image
    if bytes(nvm[a:a + len(image)]) != bytes(image):
        raise OSError(5, "%s did not read back as written; the other slot is unchanged" % label)


def export_module(st, dst):
    """Write the records as a Python module of const() values (path or stream)."""
    st._ensure()
    text = module_text(st._recs or (), st.generation)
    if isinstance(dst, str):
        f = open(dst, "w")
        try:
            f.write(text)
        finally:
            f.close()
    else:
        dst.write(text)
