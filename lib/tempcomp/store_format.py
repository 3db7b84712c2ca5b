"""The bottom of the store: its binary format and what every layer above shares.

The layout's facts (docs/store.md "Binary format"): constants, limits, the copy states, the
errors, ``Record``; the decoder of an intact copy (``decode``, ``decode_entries``); the CRC; and
the file primitives the reader, the checker and the writer all use (``read_file``, ``exists``,
``entry``). It imports no other part of tempcomp (but ``tempcomp.store_crc`` on a port without
``binascii.crc32``). Above it, each importing only what lies
below: ``tempcomp.store_check`` (what is wrong with a copy, in words) and ``tempcomp.store_encode``
(records to bytes); ``tempcomp.store_write`` (the crash-safe commit); ``tempcomp.store`` (the
``Store`` facade users call). A boot that reads an intact store loads this module and the facade
only (docs/ram.md).

The decoder checks every field but says what is wrong only as ``ValueError(code, *numbers)``:
the words are ``tempcomp.store_check``'s, built when a copy is diagnosed.
"""

import os
import struct
from array import array

try:
    from binascii import crc32 as _crc32
except ImportError:  # a port built without binascii.crc32: same polynomial, bit by bit
    from tempcomp.store_crc import crc32 as _crc32

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
HEADER = const(16)
ENTRY = const(28)  # fixed part of an entry, "<HBBBBBBHHiiII"
CRC_SIZE = const(4)
MIN_IMAGE = const(20)

# what a copy (a file or an nvm slot) is: the reader, the checker and the writer decide by these
OK = const(0)
MISSING = const(1)
BLANK = const(2)  # erased nvm (0xFF or 0x00): free to write
DAMAGED = const(3)  # our magic, but torn or corrupted: free to overwrite, with a warning
FOREIGN = const(4)  # not a store (or empty): never overwritten without force=True
NEWER = const(5)  # a store in a newer format: never read, never overwritten without force
ALIEN = const(6)  # path.new that is not a plain file (a symlink, a directory, a hard link): never
#                   read, never opened for writing, removed only with force=True

# st_mode file types (POSIX values, the ones MicroPython's os.ilistdir reports too)
S_IFMT = const(0o170000)
S_IFREG = const(0o100000)
S_IFDIR = const(0o040000)
S_IFLNK = const(0o120000)


# The error every layer raises; its public home is tempcomp.store (what users catch, and what
# CPython's tracebacks name). The checker's StoreWarning and the writer's ReadOnlyStoreError are theirs.
class StoreError(ValueError):
    """The stored data cannot be used (empty, not a store, newer version, bad length/CRC)."""

    __module__ = "tempcomp.store"


def crc(data):
    """CRC-32 (the zlib polynomial) of data, as the store keeps it."""
    return _crc32(data) & 0xFFFFFFFF


class Record:
    """One sensor's calibration as loaded: ``values`` array('i'), ``frac`` array('b'), metadata."""

    __module__ = "tempcomp.store"

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
        f = self.frac[i]
        return self.values[i] / float(1 << f) if f >= 0 else self.values[i] * float(1 << -f)

    def __repr__(self):
        return "Record(%r, part=%r, serial=%r, kind=%d, values=%r, frac=%r, t=%d..%d unit %d, counter=%d, time=%d)" % (
            self.name, self.part, self.serial, self.kind, tuple(self.values), tuple(self.frac),
            self.t_lo, self.t_hi, self.t_unit, self.counter, self.time)


def entry_size(nb, pb, sb, m):
    """Bytes of an entry with name, part, serial of nb, pb, sb bytes and m values."""
    return ENTRY + ((nb + pb + sb + m + 3) & ~3) + 4 * m


def read_text(buf, p, n, first):
    """buf[p:p + n] as a str of ASCII bytes first..0x7E; ValueError(0, byte, offset) otherwise."""
    for i in range(p, p + n):
        if not first <= buf[i] <= 0x7E:
            raise ValueError(0, buf[i], i)
    return bytes(buf[p:p + n]).decode()


def decode_entries(buf, count, end, gen):
    """The ``count`` Records of an image's entries, which end at ``end``; every field checked.
    ValueError(code, *numbers) on the first fault (tempcomp.store_check has the words)."""
    recs = []
    seen = {}
    off = HEADER
    for k in range(count):
        if off + ENTRY > end:
            raise ValueError(1, k, off, end)
        (elen, kind, t_unit, nl, pl, sl, res1, m, res2, t_lo, t_hi, counter,
         tm) = struct.unpack_from("<HBBBBBBHHiiII", buf, off)
        if res1 or res2:
            raise ValueError(2, k)
        if not 1 <= nl <= MAX_NAME or pl > MAX_PART or sl > MAX_SERIAL or m > MAX_VALUES:
            raise ValueError(3, k, nl, pl, sl, m)
        if elen != entry_size(nl, pl, sl, m) or off + elen > end:
            raise ValueError(4, k, elen)
        if counter > gen:
            raise ValueError(5, k, counter, gen)
        p = off + ENTRY
        name = read_text(buf, p, nl, 0x20)
        part = read_text(buf, p + nl, pl, 0x20)
        serial = read_text(buf, p + nl + pl, sl, 0x20)
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


def decode(buf, slot=False):
    """(generation, records) of an intact copy (every check of docs/store.md passes), else None.
    slot: an nvm slot, where the image may be shorter than the bytes read."""
    n = len(buf)
    if n >= MIN_IMAGE and bytes(buf[0:4]) == MAGIC:
        _, ver, count, length, gen = struct.unpack_from("<4sHHII", buf, 0)
        if ((length == n or slot and MIN_IMAGE <= length <= n) and ver == VERSION and gen
                and struct.unpack_from("<I", buf, length - CRC_SIZE)[0] == crc(memoryview(buf)[0:length - CRC_SIZE])):
            try:
                return gen, decode_entries(buf, count, length - CRC_SIZE, gen)
            except ValueError:
                pass
    return None


# -- the medium: a file's bytes and what is at a name ---------------------------------------

def exists(p):
    try:
        os.stat(p)
        return True
    except OSError:
        return False


def read_file(path):
    """The bytes of the file at path, or None when there is none."""
    try:
        f = open(path, "rb")
    except OSError:
        # errno numbers differ between ports (ENOENT is 44 under Emscripten): ask stat
        if not exists(path):
            return None
        raise
    try:
        return f.read()
    finally:
        f.close()


def entry(p):
    """(file type bits, hard links) of the name p itself, never following a symlink; None
    when nothing is there. MicroPython has no lstat: its os.ilistdir reports the entry's
    own type (VfsPosix from d_type, so a symlink shows as one; LittleFS and FAT have none)."""
    lstat = getattr(os, "lstat", None)
    if lstat is not None:
        try:
            st = lstat(p)
        except OSError:
            return None
        return st[0] & S_IFMT, st[3]
    i = p.rfind("/")
    d, name = (p[:i] or "/", p[i + 1:]) if i >= 0 else (None, p)
    try:
        entries = os.ilistdir(d) if d is not None else os.ilistdir()
        for e in entries:
            if e[0] == name:
                t = e[1] & S_IFMT
                if t == 0:  # a filesystem that does not say: ask stat
                    t = os.stat(p)[0] & S_IFMT
                return t, 1
    except (OSError, AttributeError):
        if exists(p):
            return os.stat(p)[0] & S_IFMT, 1
    return None
