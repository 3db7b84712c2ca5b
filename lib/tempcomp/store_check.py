"""Diagnosing a tempcomp store whose copies are not all intact: loaded by ``tempcomp.store`` only
when a copy fails a check (damaged, foreign, newer, blank or torn nvm slot) or when something is
at ``path.new`` (what a cut during a save leaves), and by the first save. A boot whose store is
intact reads it without this module (docs/ram.md). The checks, their one-line messages and the
choice of the copy to use are the ones docs/store.md describes.
"""

import os
import struct

from tempcomp.store import MAGIC, VERSION, StoreError, StoreWarning, _crc, _decode_entries

try:
    from micropython import const
except ImportError:

    def const(x):
        return x


# as in tempcomp.store (private const() names are not module attributes on MicroPython)
_CRC = const(4)
_MIN_IMAGE = const(20)
_OK = const(0)
_MISSING = const(1)
_BLANK = const(2)
_DAMAGED = const(3)
_FOREIGN = const(4)
_NEWER = const(5)
_ALIEN = const(6)
_S_IFREG = const(0o100000)
_S_IFDIR = const(0o040000)
_S_IFLNK = const(0o120000)


# what tempcomp.store's decoder found wrong with an entry: ValueError(code, *numbers)
_MALFORMED = (
    "byte 0x%02x at offset %d is not printable ASCII",
    "entry %d at offset %d runs past the end (%d)",
    "entry %d: reserved bytes are not zero",
    "entry %d: field lengths %d/%d/%d/%d out of range",
    "entry %d: length %d does not match its fields or the store",
    "entry %d: counter %d is after the store generation %d",
    "entry %d: name %r appears twice",
    "entry %d: frac[%d] = %d out of range",
    "entry %d: padding is not zero",
    "%d bytes after the last entry",
)


def warn(msg):
    try:
        import warnings  # pyright: ignore[reportMissingImports]  (CPython only)

        warnings.warn(msg, StoreWarning, stacklevel=5)
    except ImportError:
        print("tempcomp.store warning:", msg)


def crc_bitwise(data):
    """CRC-32 (the zlib polynomial) bit by bit, for a port built without binascii.crc32."""
    c = 0xFFFFFFFF
    for b in data:
        c ^= b
        for _ in range(8):
            c = (c >> 1) ^ 0xEDB88320 if c & 1 else c >> 1
    return c ^ 0xFFFFFFFF


def record_repr(r):
    return "Record(%r, part=%r, serial=%r, kind=%d, values=%r, frac=%r, t=%d..%d unit %d, counter=%d, time=%d)" % (
        r.name, r.part, r.serial, r.kind, tuple(r.values), tuple(r.frac),
        r.t_lo, r.t_hi, r.t_unit, r.counter, r.time)


def _one_bit_off(head):
    d = 0
    for i in range(4):
        x = head[i] ^ MAGIC[i]
        while x:
            d += x & 1
            x >>= 1
    return d == 1


def parse(buf, slot):
    """Classify one copy: (state, problem, generation, records). slot: an nvm slot, not a file."""
    n = len(buf)
    if n == 0:
        return _FOREIGN, "is empty (0 bytes)", 0, None
    head = bytes(buf[0:4])
    if head != MAGIC and n >= _MIN_IMAGE and _one_bit_off(head):
        return _DAMAGED, "has a corrupted magic %r (one bit off %r: a flipped bit)" % (head, MAGIC), 0, None
    if head != MAGIC:
        if slot:
            erased = True
            torn = True
            for i in range(min(4, n)):
                b = head[i]
                erased = erased and b in (0, 0xFF)
                torn = torn and (b in (0, 0xFF) or b == MAGIC[i])
            if erased:
                return _BLANK, "is blank", 0, None
            if torn:
                return _DAMAGED, "holds a torn write (magic %r)" % (head,), 0, None
        return _FOREIGN, "is not a tempcomp store (starts %r, expected %r)" % (head, MAGIC), 0, None
    if n < _MIN_IMAGE:
        return _DAMAGED, "is truncated: %d bytes, a store has at least %d" % (n, _MIN_IMAGE), 0, None
    # Every format version keeps magic, version and length at offsets 0, 4, 8 and the CRC32
    # last, so a newer store is recognised only when whole: a torn one is just damaged.
    _, ver, count, length, gen = struct.unpack_from("<4sHHII", buf, 0)
    if slot:
        if not _MIN_IMAGE <= length <= n:
            return _DAMAGED, "has a wrong length: header says %d bytes, slot holds %d" % (length, n), 0, None
    elif length != n:
        return _DAMAGED, "has a wrong length: header says %d bytes, file has %d" % (length, n), 0, None
    stored = struct.unpack_from("<I", buf, length - _CRC)[0]
    calc = _crc(memoryview(buf)[0:length - _CRC])
    if stored != calc:
        return _DAMAGED, "fails its CRC32 check (stored 0x%08x, computed 0x%08x)" % (stored, calc), 0, None
    if ver > VERSION:
        return (_NEWER, "was written in store format version %d; this tempcomp reads version %d "
                "(update tempcomp)" % (ver, VERSION), 0, None)
    if ver != VERSION:
        return _DAMAGED, "has an invalid format version %d" % ver, 0, None
    if gen == 0:
        return _DAMAGED, "has generation 0", 0, None
    try:
        recs = _decode_entries(buf, count, length - _CRC, gen)
    except ValueError as e:
        a = e.args
        return _DAMAGED, "is malformed: " + _MALFORMED[a[0]] % tuple(a[1:]), 0, None
    return _OK, "", gen, recs


def alien(st, p):
    """None when p is absent or a plain file with one link; else what it is, in words."""
    e = st._entry(p)
    if e is None:
        return None
    t, links = e
    if t == _S_IFREG:
        if links > 1:
            return "a file with %d hard links (a store never makes one)" % links
        return None
    if t == _S_IFLNK:
        target = ""
        readlink = getattr(os, "readlink", None)
        if readlink is not None:
            try:
                target = " to %r" % (readlink(p),)
            except OSError:
                pass
        return "a symbolic link%s (a store never makes one)" % target
    if t == _S_IFDIR:
        return "a directory"
    return "not a regular file (file type 0o%o)" % t


def _read_copies(st):
    if st._nvm is None:
        names = st._labels()
        out = [st._read_file(names[0]), st._read_file(names[1]), None]
        # path.new is the only name a save writes into: read it only when it is a plain
        # file of its own (a symlink there could point anywhere, a FIFO would hang the read)
        if alien(st, names[2]) is None:
            out[2] = st._read_file(names[2])
        return out
    return [bytes(st._nvm[a:a + n]) for a, n in st._slots]


def _scan(st):
    """Read every copy; return (best index or -1, states, records, problems)."""
    labels = st._labels()
    slot = st._nvm is not None
    copies = _read_copies(st)
    states = []
    whys = []
    best = -1
    best_gen = 0
    best_recs = []  # type: list
    problems = []
    newer = None
    damaged = []
    for i in range(len(labels)):
        buf = copies[i]
        if buf is None:
            what = None if slot or i != 2 else alien(st, labels[i])
            if what is not None:
                states.append(_ALIEN)
                whys.append("is %s: never read or written through" % what)
                problems.append("%s %s" % (labels[i], whys[-1]))
                continue
            states.append(_MISSING)
            whys.append("does not exist")
            continue
        s, why, gen, recs = parse(buf, slot)
        states.append(s)
        whys.append(why)
        scratch = not slot and i == 2  # path.new: a torn one is the normal trace of a cut
        if s == _OK and recs is not None:
            if gen > best_gen:
                best, best_gen, best_recs = i, gen, recs
        elif s == _NEWER:
            newer = "%s %s" % (labels[i], why)
        elif s != _BLANK and not scratch:
            problems.append("%s %s" % (labels[i], why))
            if s == _DAMAGED:
                from tempcomp.store_salvage import salvage

                damaged.append((len(problems) - 1, labels[i], why) + salvage(buf))
    st._damaged = damaged
    return best, (states, whys), best_recs, best_gen, problems, newer


def state(st, force=False, writing=False):
    """``Store._state`` in full: every copy diagnosed, warnings and errors in words."""
    best, states, recs, gen, problems, newer = _scan(st)
    if newer is not None and not force:
        raise StoreError(newer)
    torn_only = st._nvm is not None and _FOREIGN not in states[0]
    fatal = problems
    if st._nvm is None and states[0][2] == _ALIEN:
        fatal = problems[:-1]  # only a warning for reading; a save refuses it (_check_new)
    if best < 0 and fatal and not force and not torn_only:
        raise StoreError("no usable copy of the store: " + "; ".join(problems) + (
            "; refusing to overwrite it (pass force=True to start a new store, losing "
            "what is there)" if writing else ""))
    # nvm slots are rewritten in place, so a slot of ours that fails its checks beside a
    # blank one is what a cut during the first save leaves: nothing was stored yet.
    # Files are different: path and path.old only ever appear whole (by rename), so a
    # damaged one with no good copy is an error above.
    # A damaged copy newer than the one used (a flipped bit in the newest file, not a cut):
    # the records only it held are lost; record() says so instead of "never saved".
    st._lost = None
    lost_at = -1
    if best >= 0:
        for k, label, why, hgen, names, whole in st._damaged:
            if hgen > gen:
                have = [r.name for r in recs]
                st._lost = (label, why, hgen, [x for x in names if x not in have], whole)
                lost_at = k
    st.warnings = []
    for i in range(len(problems)):
        p = problems[i]
        if best >= 0:
            msg = "%s; using %s (generation %d)" % (p, st._labels()[best], gen)
            if i == lost_at:
                from tempcomp.store_salvage import lost_names

                msg += "; " + lost_names(st._lost)
        else:
            msg = "%s; no calibration stored" % p
        st.warnings.append(msg)
        warn(msg)
    return best, states, recs, gen
