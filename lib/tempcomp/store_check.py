"""Diagnosing a tempcomp store whose copies are not all intact: loaded by ``tempcomp.store`` only
when a copy fails a check (damaged, foreign, newer, blank or torn nvm slot) or when something is
at ``path.new`` (what a cut during a save leaves), and by the first save. A boot whose store is
intact reads it without this module (docs/ram.md). The checks, their one-line messages and the
choice of the copy to use are the ones docs/store.md describes.

It stands on ``tempcomp.store_format`` alone: handed the medium (a path, or an nvm byte array and
its slots), it reads the copies itself and returns its verdict; the ``Store`` keeps it.
"""

import os
import struct

from tempcomp.store_format import (
    ALIEN,
    BLANK,
    CRC_SIZE,
    DAMAGED,
    FOREIGN,
    MAGIC,
    MIN_IMAGE,
    MISSING,
    NEWER,
    OK,
    S_IFDIR,
    S_IFLNK,
    S_IFREG,
    VERSION,
    StoreError,
    crc,
    decode_entries,
    entry,
    read_file,
)

# MicroPython has no Warning class (warnings are printed there): the base is looked up
try:
    import builtins

    _WARNING = getattr(builtins, "Warning", Exception)
except ImportError:
    _WARNING = Exception


class StoreWarning(_WARNING):  # pyright: ignore[reportGeneralTypeIssues]
    """One copy of the store is damaged and another copy was used."""

    __module__ = "tempcomp.store"


# what tempcomp.store_format's decoder found wrong with an entry: ValueError(code, *numbers)
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
        return FOREIGN, "is empty (0 bytes)", 0, None
    head = bytes(buf[0:4])
    if head != MAGIC and n >= MIN_IMAGE and _one_bit_off(head):
        return DAMAGED, "has a corrupted magic %r (one bit off %r: a flipped bit)" % (head, MAGIC), 0, None
    if head != MAGIC:
        if slot:
            erased = True
            torn = True
            for i in range(min(4, n)):
                b = head[i]
                erased = erased and b in (0, 0xFF)
                torn = torn and (b in (0, 0xFF) or b == MAGIC[i])
            if erased:
                return BLANK, "is blank", 0, None
            if torn:
                return DAMAGED, "holds a torn write (magic %r)" % (head,), 0, None
        return FOREIGN, "is not a tempcomp store (starts %r, expected %r)" % (head, MAGIC), 0, None
    if n < MIN_IMAGE:
        return DAMAGED, "is truncated: %d bytes, a store has at least %d" % (n, MIN_IMAGE), 0, None
    # Every format version keeps magic, version and length at offsets 0, 4, 8 and the CRC32
    # last, so a newer store is recognised only when whole: a torn one is just damaged.
    _, ver, count, length, gen = struct.unpack_from("<4sHHII", buf, 0)
    if slot:
        if not MIN_IMAGE <= length <= n:
            return DAMAGED, "has a wrong length: header says %d bytes, slot holds %d" % (length, n), 0, None
    elif length != n:
        return DAMAGED, "has a wrong length: header says %d bytes, file has %d" % (length, n), 0, None
    stored = struct.unpack_from("<I", buf, length - CRC_SIZE)[0]
    calc = crc(memoryview(buf)[0:length - CRC_SIZE])
    if stored != calc:
        return DAMAGED, "fails its CRC32 check (stored 0x%08x, computed 0x%08x)" % (stored, calc), 0, None
    if ver > VERSION:
        return (NEWER, "was written in store format version %d; this tempcomp reads version %d "
                "(update tempcomp)" % (ver, VERSION), 0, None)
    if ver != VERSION:
        return DAMAGED, "has an invalid format version %d" % ver, 0, None
    if gen == 0:
        return DAMAGED, "has generation 0", 0, None
    try:
        recs = decode_entries(buf, count, length - CRC_SIZE, gen)
    except ValueError as e:
        a = e.args
        return DAMAGED, "is malformed: " + _MALFORMED[a[0]] % tuple(a[1:]), 0, None
    return OK, "", gen, recs


def labels(path):
    """The names of the copies in words: path, path.old, path.new; or the two nvm slots (path None)."""
    if path is None:
        return ["nvm slot A", "nvm slot B"]
    return [path, path + ".old", path + ".new"]


def alien(p):
    """None when p is absent or a plain file with one link; else what it is, in words."""
    e = entry(p)
    if e is None:
        return None
    t, links = e
    if t == S_IFREG:
        if links > 1:
            return "a file with %d hard links (a store never makes one)" % links
        return None
    if t == S_IFLNK:
        target = ""
        readlink = getattr(os, "readlink", None)
        if readlink is not None:
            try:
                target = " to %r" % (readlink(p),)
            except OSError:
                pass
        return "a symbolic link%s (a store never makes one)" % target
    if t == S_IFDIR:
        return "a directory"
    return "not a regular file (file type 0o%o)" % t


def _read_copies(path, nvm, slots):
    if nvm is None:
        names = labels(path)
        out = [read_file(names[0]), read_file(names[1]), None]
        # path.new is the only name a save writes into: read it only when it is a plain
        # file of its own (a symlink there could point anywhere, a FIFO would hang the read)
        if alien(names[2]) is None:
            out[2] = read_file(names[2])
        return out
    return [bytes(nvm[a:a + n]) for a, n in slots]


def _scan(path, nvm, slots):
    """Read every copy; return (best index or -1, states, records, generation, problems, newer,
    damaged copies with what their salvage found)."""
    names = labels(path)
    slot = nvm is not None
    copies = _read_copies(path, nvm, slots)
    states = []
    whys = []
    best = -1
    best_gen = 0
    best_recs = []  # type: list
    problems = []
    newer = None
    damaged = []
    for i in range(len(names)):
        buf = copies[i]
        if buf is None:
            what = None if slot or i != 2 else alien(names[i])
            if what is not None:
                states.append(ALIEN)
                whys.append("is %s: never read or written through" % what)
                problems.append("%s %s" % (names[i], whys[-1]))
                continue
            states.append(MISSING)
            whys.append("does not exist")
            continue
        s, why, gen, recs = parse(buf, slot)
        states.append(s)
        whys.append(why)
        scratch = not slot and i == 2  # path.new: a torn one is the normal trace of a cut
        if s == OK and recs is not None:
            if gen > best_gen:
                best, best_gen, best_recs = i, gen, recs
        elif s == NEWER:
            newer = "%s %s" % (names[i], why)
        elif s != BLANK and not scratch:
            problems.append("%s %s" % (names[i], why))
            if s == DAMAGED:
                from tempcomp.store_salvage import salvage

                damaged.append((len(problems) - 1, names[i], why) + salvage(buf))
    return best, (states, whys), best_recs, best_gen, problems, newer, damaged


def state(path, nvm, slots, force=False, writing=False):
    """The copies of a store diagnosed in full: (best copy or -1, (states, problems in words),
    records, generation, warnings, lost). The medium is a file ``path`` (nvm None) or an nvm byte
    array and its two (offset, size) slots. lost: what a corrupt copy newer than the one used took
    with it, (label, problem, its generation, record names only it held, all names read?), or None.
    Raises StoreError when no copy can be used (or one is in a newer format) unless force."""
    best, states, recs, gen, problems, newer, damaged = _scan(path, nvm, slots)
    if newer is not None and not force:
        raise StoreError(newer)
    torn_only = nvm is not None and FOREIGN not in states[0]
    fatal = problems
    if nvm is None and states[0][2] == ALIEN:
        fatal = problems[:-1]  # only a warning for reading; a save refuses it (store_write)
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
    lost = None
    lost_at = -1
    if best >= 0:
        for k, label, why, hgen, names, whole in damaged:
            if hgen > gen:
                have = [r.name for r in recs]
                lost = (label, why, hgen, [x for x in names if x not in have], whole)
                lost_at = k
    warnings = []
    for i in range(len(problems)):
        p = problems[i]
        if best >= 0:
            msg = "%s; using %s (generation %d)" % (p, labels(path)[best], gen)
            if i == lost_at:
                from tempcomp.store_salvage import lost_names

                msg += "; " + lost_names(lost)
        else:
            msg = "%s; no calibration stored" % p
        warnings.append(msg)
        warn(msg)
    return best, states, recs, gen, warnings, lost
