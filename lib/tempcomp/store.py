"""Calibration coefficients kept in flash: crash-safe, CRC-checked, several sensors per store.

Minimal interface (stable; what every sensor module may rely on)::

    from tempcomp.store import Store
    st = Store("/tempcomp.cal")              # a file: LittleFS/FAT on a board, any file on CPython
    st.save("gyro0", (12, -340, 7))          # ints within int32; durable when it returns
    st.load("gyro0")                         # -> (12, -340, 7); KeyError if never saved

Rich interface (one record per sensor; same store, same file)::

    from tempcomp import store
    st.save_record("gyro0", values, part="MPU6050", serial="B4:E6:2D", kind=store.KIND_MPU_POLY,
                   frac=14, t_span=(1800, 3100), t_unit=store.T_RAW)
    rec = st.record("gyro0", part="MPU6050", kind=store.KIND_MPU_POLY)  # checks part and kind
    rec.values        # array('i') of the stored ints (allocated once, at load)
    rec.frac          # array('b'): value i means values[i] / 2**frac[i]
    rec.real(i)       # that as a float (set-up time only: floats allocate)
    rec.part, rec.serial, rec.kind, rec.t_lo, rec.t_hi, rec.t_unit, rec.counter, rec.time
    st.get_into("gyro0", out)   # copy into a caller's array('i'): allocates nothing
    st.get("gyro0", 2)          # one value: allocates nothing (values within +-2**30)
    st.names(); st.delete("gyro0"); st.export_module("/calib_const.py")

``fixed(x, frac)`` turns a float into the stored int (round(x * 2**frac), int32-checked).
``values`` keep whatever layout the sensor module documents; ``kind`` says which layout:

==================== = ==================================================================
KIND_RAW             0 plain ints from ``save()``
KIND_MLX_REZERO      1 MLX90609 re-zero (null offset vs temperature)
KIND_MPU_POLY        2 MPU-6050/6500 offset registers and offset(T) polynomials
KIND_ADI_3POINT      3 ADI three-point (cold/room/hot) calibration
KIND_AN12760         4 NXP AN12760 per-axis offset and sensitivity vs temperature
KIND_ELLIPSOID       5 ellipsoid fit: offsets and 3x3 matrix
KIND_AUGMENT         6 augmented model from the gap diagnosis (tempcomp.augment.pack)
==================== = ==================================================================

``t_unit`` says what ``t_lo``/``t_hi`` (the calibrated temperature span) count: ``T_NONE`` (no
span), ``T_RAW`` (the sensor's own temperature reading, the ``t`` the Compensator takes),
``T_CENTI_C`` (0.01 degC) or ``T_MV`` (millivolts). ``counter`` is the store generation that
wrote the record; ``time`` is UTC seconds since 1970 from the RTC, 0 when the board's clock was
not set (year before 2024), so the counter is the reliable order.

Backends:

* ``Store(path)``: a file. Writes go to ``path + ".new"``, created exclusively (never through
  a symlink or into an existing file), read back and checked, then renamed over ``path``; the
  previous generation is kept as ``path + ".old"``. Reading picks the newest of the three whose
  CRC holds. See docs/store.md for why this is power-cut safe.
* ``Store(nvm=microcontroller.nvm, offset=0, size=None)``: CircuitPython's non-volatile byte
  array, split in two slots written alternately.

On CircuitPython the CIRCUITPY drive is read-only to code while USB may write it: a save then
raises ``ReadOnlyStoreError`` (an OSError) whose message gives the one-line boot.py fix.

Errors: ``KeyError`` for a name never saved; ``StoreError`` instead when the newest copy is
corrupt and an older one is in use (the message names that copy and the records only it held,
which are lost); ``ValueError`` for bad arguments (name not
printable ASCII or longer than 32, a value outside int32, wrong array length, a record for
another part or kind); ``StoreError`` (a ValueError) for a store whose content cannot be used
(empty, not a store, newer format version, bad length or CRC with no good copy left). A save
never overwrites a file or nvm slot it does not recognise as its own unless ``force=True``, and
refuses a ``path.new`` that is a symlink, a directory or someone else's file (``force=True``
removes that name; it never writes through it).
Warnings (one damaged copy, the other used) are printed and kept in ``Store.warnings``.

Heap: this module is the reader of an intact store, what a boot needs; encoding, the crash-safe
commit and the const() export are in ``tempcomp.store_write``, loaded by the first write; the
diagnosis of a copy that fails a check (its words, the warnings and errors above, what is at
``path.new``) in ``tempcomp.store_check``, loaded only then (docs/ram.md).
"""

import os
import struct
from array import array

try:
    from binascii import crc32 as _crc32
except ImportError:  # a port built without binascii.crc32: same polynomial, bitwise
    _crc32 = None

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


KIND_RAW = const(0)
KIND_MLX_REZERO = const(1)
KIND_MPU_POLY = const(2)
KIND_ADI_3POINT = const(3)
KIND_AN12760 = const(4)
KIND_ELLIPSOID = const(5)
KIND_AUGMENT = const(6)

T_NONE = const(0)
T_RAW = const(1)
T_CENTI_C = const(2)
T_MV = const(3)

MAGIC = b"TCAL"
VERSION = const(1)
MAX_NAME = const(32)
MAX_PART = const(16)
MAX_SERIAL = const(32)
MAX_VALUES = const(4096)
FRAC_MIN = const(-31)
FRAC_MAX = const(31)

# Layout (docs/store.md has the table): header "<4sHHII" magic, version, count, length,
# generation; entries; CRC32 of everything before it in the last 4 bytes.
_HDR = const(16)
_ENTRY = const(28)  # fixed part of an entry, "<HBBBBBBHHiiII"
_CRC = const(4)
_MIN_IMAGE = const(20)

# slot states
_OK = const(0)
_MISSING = const(1)
_BLANK = const(2)  # erased nvm (0xFF or 0x00): free to write
_DAMAGED = const(3)  # our magic, but torn or corrupted: free to overwrite, with a warning
_FOREIGN = const(4)  # not a store (or empty): never overwritten without force=True
_NEWER = const(5)  # a store in a newer format: never read, never overwritten without force
_ALIEN = const(6)  # path.new that is not a plain file (a symlink, a directory, a hard link): never
#                    read, never opened for writing, removed only with force=True

# st_mode file types (POSIX values, the ones MicroPython's os.ilistdir reports too)
_S_IFMT = const(0o170000)
_S_IFREG = const(0o100000)
_S_IFDIR = const(0o040000)
_S_IFLNK = const(0o120000)


class StoreError(ValueError):
    """The stored data cannot be used (empty, not a store, newer version, bad length/CRC)."""


class ReadOnlyStoreError(OSError):
    """The filesystem refused a write (on CircuitPython: CIRCUITPY is read-only to code)."""


# MicroPython has no Warning class (warnings are printed there): the base is looked up
try:
    import builtins

    _WARNING = getattr(builtins, "Warning", Exception)
except ImportError:
    _WARNING = Exception


class StoreWarning(_WARNING):  # pyright: ignore[reportGeneralTypeIssues]
    """One copy of the store is damaged and another copy was used."""


def _crc(data):
    if _crc32 is None:
        from tempcomp.store_check import crc_bitwise

        return crc_bitwise(data)
    return _crc32(data) & 0xFFFFFFFF


def _pow2(f):
    return float(1 << f) if f >= 0 else 1.0 / (1 << -f)


def fixed(x, frac):
    """round(x * 2**frac) as an int, checked to fit int32 (ValueError otherwise)."""
    from tempcomp import store_write  # set-up only: the boot's reader does without it

    return store_write.fixed(x, frac)


class Record:
    """One sensor's calibration as loaded: ``values`` array('i'), ``frac`` array('b'), metadata."""

    def __init__(self, name, values, frac, part="", serial="", kind=KIND_RAW,
                 t_lo=0, t_hi=0, t_unit=T_NONE, counter=0, time=0):
        self.name = name
        self.values = values
        self.frac = frac
        self.part = part
        self.serial = serial
        self.kind = kind
        self.t_lo = t_lo
        self.t_hi = t_hi
        self.t_unit = t_unit
        self.counter = counter
        self.time = time

    def real(self, i):
        """Value i as a float: values[i] / 2**frac[i] (allocates: set-up time only)."""
        return self.values[i] * _pow2(-self.frac[i])

    def __repr__(self):
        from tempcomp.store_check import record_repr

        return record_repr(self)


def _pad4(n):
    return (n + 3) & ~3


def _entry_size(nb, pb, sb, m):
    return _ENTRY + _pad4(nb + pb + sb + m) + 4 * m


# A malformed entry raises ValueError(code, *numbers): the words are tempcomp.store_check's
# _MALFORMED[code], built only when a copy is diagnosed (a boot whose store is intact never
# loads them).


def _text(buf, p, n, first):
    for i in range(p, p + n):
        if not first <= buf[i] <= 0x7E:
            raise ValueError(0, buf[i], i)
    return bytes(buf[p:p + n]).decode()


def _decode_entries(buf, count, end, gen):
    recs = []
    seen = {}
    off = _HDR
    for k in range(count):
        if off + _ENTRY > end:
            raise ValueError(1, k, off, end)
        (elen, kind, t_unit, nl, pl, sl, res1, m, res2, t_lo, t_hi, counter,
         tm) = struct.unpack_from("<HBBBBBBHHiiII", buf, off)
        if res1 or res2:
            raise ValueError(2, k)
        if not 1 <= nl <= MAX_NAME or pl > MAX_PART or sl > MAX_SERIAL or m > MAX_VALUES:
            raise ValueError(3, k, nl, pl, sl, m)
        if elen != _entry_size(nl, pl, sl, m) or off + elen > end:
            raise ValueError(4, k, elen)
        if counter > gen:
            raise ValueError(5, k, counter, gen)
        p = off + _ENTRY
        name = _text(buf, p, nl, 0x20)
        part = _text(buf, p + nl, pl, 0x20)
        serial = _text(buf, p + nl + pl, sl, 0x20)
        if name in seen:
            raise ValueError(6, k, name)
        seen[name] = True
        p += nl + pl + sl
        frac = array("b", [0] * m)
        for i in range(m):
            f = buf[p + i]
            f = f - 256 if f & 0x80 else f
            if not FRAC_MIN <= f <= FRAC_MAX:
                raise ValueError(7, k, i, f)
            frac[i] = f
        for i in range(p + m, off + elen - 4 * m):
            if buf[i]:
                raise ValueError(8, k)
        values = array("i", [0] * m)
        p = off + elen - 4 * m
        for i in range(m):
            values[i] = struct.unpack_from("<i", buf, p + 4 * i)[0]
        recs.append(Record(name, values, frac, part, serial, kind, t_lo, t_hi, t_unit, counter, tm))
        off += elen
    if off != end:
        raise ValueError(9, end - off)
    return recs


def _parse(buf, slot):
    """Classify one copy: (state, problem, generation, records). slot: an nvm slot, not a file.
    An intact copy is read here; any other is diagnosed by tempcomp.store_check."""
    n = len(buf)
    if n >= _MIN_IMAGE and bytes(buf[0:4]) == MAGIC:
        _, ver, count, length, gen = struct.unpack_from("<4sHHII", buf, 0)
        if ((length == n or slot and _MIN_IMAGE <= length <= n) and ver == VERSION and gen
                and struct.unpack_from("<I", buf, length - _CRC)[0] == _crc(memoryview(buf)[0:length - _CRC])):
            try:
                return _OK, "", gen, _decode_entries(buf, count, length - _CRC, gen)
            except ValueError:
                pass
    from tempcomp.store_check import parse

    return parse(buf, slot)


class Store:
    """A crash-safe calibration store on a file (``path``) or a CircuitPython nvm byte array."""

    def __init__(self, path=None, nvm=None, offset=0, size=None):
        if (path is None) == (nvm is None):
            raise ValueError("Store needs either a path or nvm=, not both or neither")
        self.path = path
        self._nvm = nvm
        if nvm is not None:
            total = len(nvm) - offset if size is None else size
            if offset < 0 or total < 2 * _MIN_IMAGE or offset + total > len(nvm):
                raise ValueError("nvm region %d+%d does not fit nvm of %d bytes (needs two slots)"
                                 % (offset, total, len(nvm)))
            half = total // 2
            self._slots = ((offset, half), (offset + half, half))
        self.generation = 0
        self.warnings = []
        self._damaged = []
        self._lost = None
        self._recs = None
        self._index = None

    def __repr__(self):
        if self._nvm is None:
            return "Store(%r)" % (self.path,)
        return "Store(nvm, slots=%r)" % (self._slots,)

    # -- reading --------------------------------------------------------------------------

    def _file_names(self):
        p = self.path or ""
        return [p, p + ".old", p + ".new"]

    def _labels(self):
        if self._nvm is None:
            return self._file_names()
        return ["nvm slot A", "nvm slot B"]

    def _exists(self, p):
        try:
            os.stat(p)
            return True
        except OSError:
            return False

    def _read_file(self, path):
        try:
            f = open(path, "rb")
        except OSError:
            # errno numbers differ between ports (ENOENT is 44 under Emscripten): ask stat
            if not self._exists(path):
                return None
            raise
        try:
            return f.read()
        finally:
            f.close()

    def _entry(self, p):
        """(file type bits, hard links) of the name p itself, never following a symlink; None
        when nothing is there. MicroPython has no lstat: its os.ilistdir reports the entry's
        own type (VfsPosix from d_type, so a symlink shows as one; LittleFS and FAT have none)."""
        lstat = getattr(os, "lstat", None)
        if lstat is not None:
            try:
                st = lstat(p)
            except OSError:
                return None
            return st[0] & _S_IFMT, st[3]
        i = p.rfind("/")
        d, name = (p[:i] or "/", p[i + 1:]) if i >= 0 else (None, p)
        try:
            entries = os.ilistdir(d) if d is not None else os.ilistdir()
            for e in entries:
                if e[0] == name:
                    t = e[1] & _S_IFMT
                    if t == 0:  # a filesystem that does not say: ask stat
                        t = os.stat(p)[0] & _S_IFMT
                    return t, 1
        except (OSError, AttributeError):
            if self._exists(p):
                return os.stat(p)[0] & _S_IFMT, 1
        return None

    def _state(self, force=False, writing=False):
        """(best copy or -1, (states, problems), records, generation). Here only when every
        copy there is intact and nothing is at path.new; else tempcomp.store_check decides."""
        nvm = self._nvm
        slot = nvm is not None
        whole = True
        if nvm is not None:
            copies = [bytes(nvm[a:a + n]) for a, n in self._slots]
        else:
            p = self.path or ""
            copies = [self._read_file(p), self._read_file(p + ".old"), None]
            whole = self._entry(p + ".new") is None  # else what a cut (or someone) left there
        best, gen, recs, states = -1, 0, [], []
        for i in range(len(copies)):
            if not whole:
                break
            buf = copies[i]
            s = _MISSING
            if buf is not None:
                if slot and bytes(buf[0:4]) in (b"\xff\xff\xff\xff", b"\0\0\0\0"):
                    s = _BLANK  # an erased slot: free to write
                else:
                    s, _, g, r = _parse(buf, slot)
                    whole = s == _OK
                    if g > gen:
                        best, gen, recs = i, g, r
            states.append(s)
        if not whole:
            from tempcomp.store_check import state

            return state(self, force, writing)
        self.warnings = []
        self._damaged = []
        self._lost = None
        whys = ["is blank" if s == _BLANK else "" if s == _OK else "does not exist" for s in states]
        return best, (states, whys), recs, gen

    def _set_cache(self, recs, gen):
        index = {}
        for r in recs:
            index[r.name] = r
        self._recs = recs
        self._index = index
        self.generation = gen
        return index

    def refresh(self):
        """Re-read the medium (after another Store object or a host tool changed it)."""
        self._recs = None
        self._index = None
        _, _, recs, gen = self._state()
        return self._set_cache(recs, gen)

    def _ensure(self):
        index = self._index
        if index is None:
            index = self.refresh()
        return index

    def load(self, name, part=None):
        """Return the values saved under name as a tuple (KeyError if never saved).

        Reads the medium on every call. With ``part``, a record made for another part
        raises ValueError.
        """
        self.refresh()
        return tuple(self.record(name, part).values)

    def record(self, name, part=None, kind=None):
        """The loaded Record for name; ValueError if it is for another part or kind."""
        index = self._ensure()
        if name not in index:
            if self._lost is not None:
                from tempcomp.store_salvage import lost_error

                raise lost_error(self, name)
            raise KeyError("%r was never saved in %r" % (name, self))
        r = index[name]
        if part is not None and r.part != part:
            raise ValueError("record %r is for part %r, not %r" % (name, r.part, part))
        if kind is not None and r.kind != kind:
            raise ValueError("record %r holds kind %d, not %d" % (name, r.kind, kind))
        return r

    def get(self, name, i):
        """Value i of a loaded record (no allocation for values within +-2**30)."""
        index = self._index
        if index is None:
            index = self._ensure()
        return index[name].values[i]

    def get_into(self, name, out):
        """Copy a record's values into out (array('i') of the same length); returns the count."""
        index = self._index
        if index is None:
            index = self._ensure()
        v = index[name].values
        n = len(v)
        if len(out) != n:
            raise ValueError("record %r has %d values; out has %d" % (name, n, len(out)))
        i = 0
        while i < n:  # no slice object, no range object: nothing allocated
            out[i] = v[i]
            i += 1
        return n

    def names(self):
        """Names of the stored records, in store order."""
        self._ensure()
        return [r.name for r in self._recs or ()]

    # -- writing: tempcomp.store_write, loaded by the first write (a boot that only reads never
    # has it on its heap) ---------------------------------------------------------------------

    def save(self, name, values):
        """Store ints (each within int32) under a short ASCII name; durable when it returns."""
        self.save_record(name, values)

    def save_record(self, name, values, part="", serial="", kind=KIND_RAW, frac=0,
                    t_span=None, t_unit=None, when=None, force=False):
        """Store one sensor's record (see the module docstring); replaces one of the same name.

        values: ints within int32; frac: fraction bits, one int for all or one per value
        (-31..31); t_span: (t_lo, t_hi) calibrated temperature span in t_unit (default T_RAW
        when a span is given); when: UTC seconds since 1970, default the RTC (0 if not set).
        force=True overwrites a copy that is not a store of this version (its data is lost).
        """
        from tempcomp import store_write

        store_write.save_record(self, name, values, part, serial, kind, frac, t_span, t_unit, when, force)

    def delete(self, name, force=False):
        """Remove a record (a crash-safe write like save); KeyError if it is not there."""
        from tempcomp import store_write

        store_write.delete(self, name, force)

    def export_module(self, dst):
        """Write the records as a Python module of const() values (path or stream)."""
        from tempcomp import store_write

        store_write.export_module(self, dst)
