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

Layers, each importing only those below it: ``tempcomp.store_format`` (the format's constants,
errors, ``Record``, the decoder, the file primitives); ``tempcomp.store_check`` (a copy that fails a
check, in words; what is at ``path.new``) and ``tempcomp.store_encode`` (records to bytes);
``tempcomp.store_write`` (the crash-safe commit); this module, the ``Store`` facade, on top. A
boot whose store is intact loads the format and this module only; the others come with a damaged
copy or the first save (docs/ram.md).
"""

from tempcomp.store_format import (
    BLANK,
    KIND_RAW,
    MIN_IMAGE,
    MISSING,
    OK,
    decode,
    entry,
    read_file,
)

# The public names of the layers below are this module's too, as before they were split out:
# store.KIND_MPU_POLY, store.StoreError, store.Record (tempcomp.store_format), store.fixed
# (tempcomp.store_encode), store.StoreWarning (tempcomp.store_check, which warns) and
# store.ReadOnlyStoreError (tempcomp.store_write, which raises it). Looked up when asked (PEP 562),
# so a boot keeps no second table of them and loads no module it does not use.
TYPE_CHECKING = False
if TYPE_CHECKING:  # the same names for the type checker
    from tempcomp.store_check import StoreWarning  # noqa: F401
    from tempcomp.store_encode import fixed  # noqa: F401
    from tempcomp.store_format import (  # noqa: F401
        FRAC_MAX,
        FRAC_MIN,
        KIND_ADI_3POINT,
        KIND_AN12760,
        KIND_AUGMENT,
        KIND_ELLIPSOID,
        KIND_MLX_REZERO,
        KIND_MPU_POLY,
        MAGIC,
        MAX_NAME,
        MAX_PART,
        MAX_SERIAL,
        MAX_VALUES,
        T_CENTI_C,
        T_MV,
        T_NONE,
        T_RAW,
        VERSION,
        Record,
        StoreError,
    )
    from tempcomp.store_write import ReadOnlyStoreError  # noqa: F401


def __getattr__(name):
    if name == "StoreWarning":
        from tempcomp.store_check import StoreWarning

        return StoreWarning
    if name == "ReadOnlyStoreError":
        from tempcomp.store_write import ReadOnlyStoreError

        return ReadOnlyStoreError
    if name == "fixed":
        from tempcomp.store_encode import fixed

        return fixed
    if name[0] != "_":
        from tempcomp import store_format

        v = getattr(store_format, name, store_format)
        if v is not store_format:
            return v
    raise AttributeError(name)


class Store:
    """A crash-safe calibration store on a file (``path``) or a CircuitPython nvm byte array."""

    def __init__(self, path=None, nvm=None, offset=0, size=None):
        if (path is None) == (nvm is None):
            raise ValueError("Store needs either a path or nvm=, not both or neither")
        self.path = path
        self._nvm = nvm
        self._slots = None
        if nvm is not None:
            total = len(nvm) - offset if size is None else size
            if offset < 0 or total < 2 * MIN_IMAGE or offset + total > len(nvm):
                raise ValueError("nvm region %d+%d does not fit nvm of %d bytes (needs two slots)"
                                 % (offset, total, len(nvm)))
            half = total // 2
            self._slots = ((offset, half), (offset + half, half))
        self.generation = 0
        self.warnings = []
        self._lost = None
        self._recs = None
        self._index = None

    def __repr__(self):
        if self._nvm is None:
            return "Store(%r)" % (self.path,)
        return "Store(nvm, slots=%r)" % (self._slots,)

    # -- reading --------------------------------------------------------------------------

    def _state(self, force=False, writing=False):
        """(best copy or -1, (states, problems), records, generation). Here only when every
        copy there is intact and nothing is at path.new; else tempcomp.store_check decides."""
        nvm = self._nvm
        slot = nvm is not None
        whole = True
        if nvm is not None:
            copies = [bytes(nvm[a:a + n]) for a, n in self._slots or ()]
        else:
            p = self.path or ""
            copies = [read_file(p), read_file(p + ".old"), None]
            whole = entry(p + ".new") is None  # else what a cut (or someone) left there
        best, gen, recs, states = -1, 0, [], []
        for i in range(len(copies) if whole else 0):
            buf = copies[i]
            s = MISSING
            if buf is not None:
                if slot and bytes(buf[0:4]) in (b"\xff\xff\xff\xff", b"\0\0\0\0"):
                    s = BLANK  # an erased slot: free to write
                else:
                    r = decode(buf, slot)
                    if r is None:
                        whole = False
                        break
                    s = OK
                    if r[0] > gen:
                        best, gen, recs = i, r[0], r[1]
            states.append(s)
        if not whole:
            from tempcomp.store_check import state

            best, states, recs, gen, self.warnings, self._lost = state(self.path, nvm, self._slots, force, writing)
            return best, states, recs, gen
        self.warnings = []
        self._lost = None
        whys = ["is blank" if s == BLANK else "" if s == OK else "does not exist" for s in states]
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

                raise lost_error(self._lost, name, self.generation)
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

    # -- writing: tempcomp.store_encode and tempcomp.store_write, loaded by the first write (a
    # boot that only reads never has them on its heap) ------------------------------------------

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
        from tempcomp.store_encode import new_record

        self._write(new_record(name, values, part, serial, kind, frac, t_span, t_unit, when), None, force)

    def delete(self, name, force=False):
        """Remove a record (a crash-safe write like save); KeyError if it is not there."""
        self._write(None, name, force)

    def _write(self, rec, drop, force):
        from tempcomp.store_write import write

        # until the write has succeeded (an error, or a power cut in a test): re-read the medium
        # before trusting a cache
        self._recs = None
        self._index = None
        recs, gen = write(self.path, self._nvm, self._slots, self._state(force, True), rec, drop, force, repr(self))
        self._set_cache(recs, gen)

    def export_module(self, dst):
        """Write the records as a Python module of const() values (path or stream)."""
        from tempcomp.store_encode import module_text
        from tempcomp.store_write import export

        self._ensure()
        export(dst, module_text(self._recs or (), self.generation))
