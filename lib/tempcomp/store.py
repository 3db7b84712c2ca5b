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
==================== = ==================================================================

``t_unit`` says what ``t_lo``/``t_hi`` (the calibrated temperature span) count: ``T_NONE`` (no
span), ``T_RAW`` (the sensor's own temperature reading, the ``t`` the Compensator takes),
``T_CENTI_C`` (0.01 degC) or ``T_MV`` (millivolts). ``counter`` is the store generation that
wrote the record; ``time`` is UTC seconds since 1970 from the RTC, 0 when the board's clock was
not set (year before 2024), so the counter is the reliable order.

Backends:

* ``Store(path)``: a file. Writes go to ``path + ".new"``, are read back and checked, then
  renamed over ``path``; the previous generation is kept as ``path + ".old"``. Reading picks
  the newest of the three whose CRC holds. See docs/store.md for why this is power-cut safe.
* ``Store(nvm=microcontroller.nvm, offset=0, size=None)``: CircuitPython's non-volatile byte
  array, split in two slots written alternately.

On CircuitPython the CIRCUITPY drive is read-only to code while USB may write it: a save then
raises ``ReadOnlyStoreError`` (an OSError) whose message gives the one-line boot.py fix.

Errors: ``KeyError`` for a name never saved; ``ValueError`` for bad arguments (name not
printable ASCII or longer than 16, a value outside int32, wrong array length, a record for
another part or kind); ``StoreError`` (a ValueError) for a store whose content cannot be used
(empty, not a store, newer format version, bad length or CRC with no good copy left). A save
never overwrites a file or nvm slot it does not recognise as its own unless ``force=True``.
Warnings (one damaged copy, the other used) are printed and kept in ``Store.warnings``.
"""

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

T_NONE = const(0)
T_RAW = const(1)
T_CENTI_C = const(2)
T_MV = const(3)

MAGIC = b"TCAL"
VERSION = const(1)
MAX_NAME = const(16)
MAX_PART = const(16)
MAX_SERIAL = const(32)
MAX_VALUES = const(1024)
FRAC_MIN = const(-31)
FRAC_MAX = const(31)


class StoreError(ValueError):
    """The stored data cannot be used (empty, not a store, newer version, bad length/CRC)."""


class ReadOnlyStoreError(OSError):
    """The filesystem refused a write (on CircuitPython: CIRCUITPY is read-only to code)."""


class StoreWarning(Warning):
    """One copy of the store is damaged and another copy was used."""


class Record:
    """One sensor's calibration as loaded: ``values`` array('i'), ``frac`` array('b'), metadata."""

    def real(self, i):
        """Value i as a float: values[i] / 2**frac[i] (allocates: set-up time only)."""
        raise NotImplementedError


def fixed(x, frac):
    """round(x * 2**frac) as an int, checked to fit int32 (ValueError otherwise)."""
    raise NotImplementedError


class Store:
    """A crash-safe calibration store on a file (``path``) or a CircuitPython nvm byte array."""

    def __init__(self, path=None, nvm=None, offset=0, size=None):
        raise NotImplementedError

    def save(self, name, values):
        """Store ints (each within int32) under a short ASCII name; durable when it returns."""
        raise NotImplementedError

    def load(self, name, part=None):
        """Return the values saved under name as a tuple (KeyError if never saved)."""
        raise NotImplementedError

    def save_record(self, name, values, part="", serial="", kind=KIND_RAW, frac=0,
                    t_span=None, t_unit=None, when=None, force=False):
        """Store one sensor's record (see the module docstring); replaces one of the same name."""
        raise NotImplementedError

    def record(self, name, part=None, kind=None):
        """The loaded Record for name; ValueError if it is for another part or kind."""
        raise NotImplementedError

    def get(self, name, i):
        """Value i of a loaded record (no allocation for values within +-2**30)."""
        raise NotImplementedError

    def get_into(self, name, out):
        """Copy a record's values into out (array('i') of the same length); returns the count."""
        raise NotImplementedError

    def names(self):
        """Names of the stored records, in store order."""
        raise NotImplementedError

    def delete(self, name, force=False):
        """Remove a record (a crash-safe write like save)."""
        raise NotImplementedError

    def refresh(self):
        """Re-read the medium (after another Store object or a host tool changed it)."""
        raise NotImplementedError

    def export_module(self, dst):
        """Write the records as a Python module of const() values (path or stream)."""
        raise NotImplementedError
