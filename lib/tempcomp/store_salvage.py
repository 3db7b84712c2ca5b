"""What a damaged store copy still says: read by ``tempcomp.store_check`` only when a copy fails its
checks, to name the records a corrupt newest copy took with it (never trusted as data). Kept out
of ``tempcomp.store`` so a boot whose store is intact never loads it (docs/ram.md).
"""

import struct

from tempcomp.store_format import CRC_SIZE, ENTRY, HEADER, StoreError, entry_size, read_text


def salvage(buf):
    # What a damaged copy's header and entries still say: (generation, record names, all names
    # read?). Only to tell the user what a corrupt newest copy took with it; never trusted as data.
    n = len(buf)
    if n < HEADER:
        return 0, [], False
    count = struct.unpack_from("<H", buf, 6)[0]
    length = struct.unpack_from("<I", buf, 8)[0]
    gen = struct.unpack_from("<I", buf, 12)[0]
    names = []
    off = HEADER
    for _ in range(count):
        if off + ENTRY > n:
            return gen, names, False
        e = struct.unpack_from("<HBBBBBBH", buf, off)
        if not e[3] or e[0] != entry_size(e[3], e[4], e[5], e[7]) or off + e[0] > n:
            return gen, names, False
        try:
            names.append(read_text(buf, off + ENTRY, e[3], 0x20))
        except ValueError:
            return gen, names, False
        # a save's record carries its generation too: one flipped bit cannot lower both
        c = struct.unpack_from("<I", buf, off + 20)[0]
        if c > gen:
            gen = c
        off += e[0]
    return gen, names, off + CRC_SIZE in (length, n)  # else the count is wrong: names may be missing


def lost_names(lost):
    """The records only the corrupt newest copy held, in words (``lost`` as for lost_error)."""
    names = ", ".join(repr(x) for x in lost[3]) or "none"
    return "records only it held (lost): %s%s" % (
        names, "" if lost[4] else " (and maybe more: its entries are unreadable past that)")


def lost_error(lost, name, generation):
    """The StoreError for a record missing from the copy in use (of that generation) while a newer
    copy is corrupt (``lost``: what ``tempcomp.store_check.state`` found it took with it)."""
    return StoreError("%r is not in the copy in use (generation %d): the newest copy of the store (%s, "
                      "generation %d) %s; %s" % (name, generation, lost[0], lost[2], lost[1],
                                                 lost_names(lost)))
