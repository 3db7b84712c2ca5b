"""The crash-safe commit of a store's next generation to a file or to nvm slots.

Loaded by the first ``Store.save()``, ``save_record()``, ``delete()`` or ``export_module()``, never
by a board that only reads its calibration at boot (docs/ram.md has the heap figures). Handed what
the ``Store`` read (the state of every copy, the records, the generation) and the medium (a path,
or an nvm byte array and its slots), it writes and returns what is now stored; docs/store.md has
the power-cut argument. Stands on ``tempcomp.store_format``, ``tempcomp.store_encode`` (the
bytes) and ``tempcomp.store_check`` (what is at ``path.new``, in words).
"""

import os

from tempcomp.store_check import alien, labels
from tempcomp.store_encode import UINT32_MAX, encode
from tempcomp.store_format import (
    BLANK,
    DAMAGED,
    FOREIGN,
    MAGIC,
    MISSING,
    NEWER,
    OK,
    StoreError,
    entry,
    exists,
    read_file,
)

try:
    import errno

    _EROFS = getattr(errno, "EROFS", 30)
except ImportError:
    _EROFS = 30

class ReadOnlyStoreError(OSError):
    """The filesystem refused a write (on CircuitPython: CIRCUITPY is read-only to code)."""

    __module__ = "tempcomp.store"


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


def write(path, nvm, slots, state, rec, drop, force, where):
    """Commit the next generation: ``rec`` (a Record) replaces the record of its name or is added,
    or the record named ``drop`` is removed (KeyError naming the store ``where`` when there is
    none). state: (best copy, (states, problems), records, generation) as ``Store`` read it for
    writing. Returns (records, generation) as now stored."""
    best, states, recs, gen = state
    if gen >= UINT32_MAX:
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
            raise KeyError("%r was never saved in %s" % (drop, where))
        recs.pop(i)
    image = encode(gen, recs)
    if nvm is None:
        _commit_file(path, image, best, states, force)
    else:
        _commit_nvm(nvm, slots, image, best, states, force)
    return recs, gen


def _refuse(names, states, i, force):
    state = states[0][i]
    if force or state in (MISSING, BLANK, DAMAGED, OK):
        return
    raise StoreError("%s %s; refusing to overwrite it (pass force=True to replace it, "
                     "losing its content)" % (names[i], states[1][i]))


# File backend. Only rename is trusted to be atomic: LittleFS commits a rename in one
# metadata block; POSIX rename(2) replaces atomically; FAT (and Windows) refuse to rename
# over an existing file, so there the old target is removed first, and the window between
# is covered by the reader taking the newest valid copy of path, path.old, path.new.


def _wrap(e, what):
    if _errno(e) == _EROFS:
        raise ReadOnlyStoreError(_EROFS, "cannot %s: read-only filesystem%s" % (what, _READ_ONLY_HELP))
    raise e


def _remove(p):
    try:
        os.remove(p)
    except OSError as e:
        _wrap(e, "remove " + p)


def _replace(src, dst):
    try:
        os.rename(src, dst)
        return
    except OSError as e:
        if _errno(e) == _EROFS or not exists(dst) or not exists(src):
            _wrap(e, "rename %s to %s" % (src, dst))
    # FAT/Windows: rename does not replace. dst is never the newest copy here.
    _remove(dst)
    try:
        os.rename(src, dst)
    except OSError as e:
        _wrap(e, "rename %s to %s" % (src, dst))


def _check_new(path, states, force):
    # path.new before anything changes: what a cut left there (empty, torn or whole, our
    # magic or erased bytes at the start) is ours to remove; anything else is refused.
    state, why = states[0][2], states[1][2]
    if force or state in (MISSING, DAMAGED, OK):
        return
    new = path + ".new"
    if state == FOREIGN:
        head = read_file(new) or b""
        torn = True
        for i in range(min(4, len(head))):
            torn = torn and head[i] in (MAGIC[i], 0, 0xFF)
        if torn:  # empty, or a torn start of our own write
            return
    raise StoreError("%s %s; refusing to write it (remove it, or pass force=True to remove "
                     "that name: nothing is ever written through it)" % (new, why))


def _open_new(p, force):
    # Exclusive creation: a save never opens an existing file for writing, so a symlink or
    # a foreign file put at path.new cannot make it write anywhere else. Whatever is there
    # now was vetted by _check_new (or force): only the name is removed.
    if entry(p) is not None:
        what = alien(p)
        if what is not None and not force:
            raise StoreError("%s became %s during the save; refusing to write it" % (p, what))
        _remove(p)
    try:
        return open(p, "xb")  # O_CREAT|O_EXCL: CPython (never follows a symlink), LittleFS, FAT
    except (OSError, ValueError) as e:
        if isinstance(e, OSError) and _errno(e) == _EROFS:
            _wrap(e, "create " + p)
        if entry(p) is not None:
            raise StoreError("%s appeared during the save (another program?); refusing to "
                             "write it; the store is unchanged" % p)
    # A port whose open() has no "x" (MicroPython's VfsPosix reads "xb" as "rb" and fails
    # on the missing file): nothing is at p, checked just now without following links.
    try:
        return open(p, "wb")
    except OSError as e:
        _wrap(e, "write " + p)
        raise


def _write_verified(p, image, force=False):
    f = _open_new(p, force)
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
    back = read_file(p)
    if back != image:
        raise OSError(5, "%s did not read back as written (flash fault?); store unchanged" % p)


def _sync_dir(p):
    # CPython/POSIX: make the renames themselves durable. MicroPython's VFS commits a
    # rename before returning, and os.open does not exist there.
    rdonly = getattr(os, "O_RDONLY", None)
    if rdonly is None or not hasattr(os, "fsync"):
        return
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


def _commit_file(path, image, best, states, force):
    names = labels(path)
    cur, old, new = names
    _refuse(names, states, 0, force)
    _refuse(names, states, 1, force)
    _check_new(path, states, force)
    states = states[0]
    # 1. make `cur` hold the newest valid copy (normally it already does)
    if best == 1:
        if states[0] != MISSING:
            _remove(cur)
        _replace(old, cur)
    elif best == 2:
        if states[0] != MISSING:
            _replace(cur, old)
        _replace(new, cur)
    elif best < 0:
        for i in (0, 1):
            if states[i] != MISSING:
                _remove((cur, old)[i])
    # 2. the new image goes to a scratch name, created exclusively, read back
    _write_verified(new, image, force)
    # 3. commit: the newest copy becomes .old, the new image becomes current
    if exists(cur):
        _replace(cur, old)
    _replace(new, cur)
    _sync_dir(path)


# nvm backend: the slot not holding the newest copy is rewritten in one assignment
# (CircuitPython erases and programs per assignment) and read back.


def _commit_nvm(nvm, slots, image, best, states, force):
    state = states[0]
    if best >= 0:
        target = 1 - best
    elif state[0] in (FOREIGN, NEWER) and state[1] not in (FOREIGN, NEWER):
        target = 1
    else:
        target = 0
    names = labels(None)
    _refuse(names, states, target, force)
    a, n = slots[target]
    if len(image) > n:
        raise ValueError("store of %d bytes does not fit the %d-byte nvm slot" % (len(image), n))
    nvm[a:a + len(image)] = image
    if bytes(nvm[a:a + len(image)]) != bytes(image):
        raise OSError(5, "%s did not read back as written; the other slot is unchanged" % names[target])


def export(dst, text):
    """Write ``text`` (``store_encode.module_text``) to dst, a path or a stream."""
    if isinstance(dst, str):
        f = open(dst, "w")
        try:
            f.write(text)
        finally:
            f.close()
    else:
        dst.write(text)
