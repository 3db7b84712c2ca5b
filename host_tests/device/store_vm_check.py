"""Store checks run inside the MicroPython VM (imported by host_tests/store/test_store_vm.py).

Prints machine-readable lines: "OK name", "VAL name repr", "HEX name hex", ALLOC lines.
"""
import builtins
import os
import struct
from array import array

import allocprobe

from tempcomp import store as st
from tempcomp import store_write
from tempcomp.store_encode import encode
from tempcomp.store_format import crc


class PowerCut(BaseException):
    pass


def ok(name, cond):
    print(("OK " if cond else "FAIL ") + name)


def _rm(p):
    for q in (p, p + ".old", p + ".new"):
        try:
            os.remove(q)
        except OSError:
            pass


class _Torn:
    def __init__(self, f, k):
        self.f = f
        self.k = k

    def write(self, data):
        self.f.write(bytes(data)[: self.k])
        self.f.close()
        raise PowerCut()

    def close(self):
        pass

    def flush(self):
        pass


class _CutOs:
    """The os module with rename replaced."""

    def __init__(self, rename):
        self.rename = rename

    def __getattr__(self, name):
        return getattr(os, name)


def torn_writes(p):
    """A save torn at several bytes: the store loads the old or the new values, never garbage."""
    old = (1, 2, 2147483647)
    new = (-5, -6, -2147483648)
    real_open = builtins.open
    n = len(encode(1, [st.Record("g", new, [0] * 3)]))
    good = True
    for k in (0, 1, 4, 15, 16, 40, n - 5, n - 1, n):
        _rm(p)
        st.Store(p).save("g", old)

        def cut_open(path, mode="r", k=k):
            f = real_open(path, mode)
            return _Torn(f, k) if ("w" in mode or "x" in mode) else f

        builtins.open = cut_open
        try:
            st.Store(p).save("g", new)
            good = False
        except PowerCut:
            pass
        finally:
            builtins.open = real_open
        got = st.Store(p).load("g")
        good = good and got in (old, new)
    ok("torn_writes", good)
    # a cut inside rename: before and after the real one
    real_rename = os.rename
    for when in ("before", "after"):
        _rm(p)
        st.Store(p).save("g", old)

        def cut_rename(a, b, when=when):
            if when == "after":
                real_rename(a, b)
            raise PowerCut()

        # store_write's own `os` name, not the os module: bare-metal ports' os is read-only
        store_write.os = _CutOs(cut_rename)
        try:
            st.Store(p).save("g", new)
        except PowerCut:
            pass
        finally:
            store_write.os = os
        ok("rename_cut_" + when, st.Store(p).load("g") in (old, new))


def main():
    p = "/cal.bin"
    _rm(p)
    s = st.Store(p)
    try:
        s.load("g")
        ok("keyerror", False)
    except KeyError:
        ok("keyerror", True)
    s.save("g", (1, -2, 2147483647, -2147483648))
    print("VAL load", repr(st.Store(p).load("g")))
    s.save_record("mpu", [100, -200, 300], part="MPU6050", serial="SN1", kind=st.KIND_MPU_POLY,
                  frac=[4, 4, 0], t_span=(-500, 2500), when=1767225600)
    r = st.Store(p).record("mpu", part="MPU6050", kind=st.KIND_MPU_POLY)
    print("VAL rec", repr((r.part, r.serial, r.kind, r.t_lo, r.t_hi, r.t_unit, r.counter, r.time,
                           tuple(r.frac), tuple(r.values), r.real(0))))
    try:
        st.Store(p).load("mpu", part="MLX90609")
        ok("other_part", False)
    except ValueError as e:
        ok("other_part", "MLX90609" in str(e))
    try:
        s.save("bad\tname", (1,))
        ok("bad_name", False)
    except ValueError:
        ok("bad_name", True)
    try:
        s.save("big", (2147483648,))
        ok("int32", False)
    except ValueError as e:
        ok("int32", "int32" in str(e))
    try:
        s.save("gyr\u00f3", (1,))  # MicroPython's encode() does not validate ASCII: we do
        ok("non_ascii", False)
    except ValueError:
        ok("non_ascii", True)
    print("VAL names", repr(st.Store(p).names()))
    print("VAL files", repr(sorted(f for f in os.listdir("/") if f.startswith("cal.bin"))))

    # a store made on the host, read here; a record added here, read back on the host
    h = st.Store("/hostdata/host.cal")
    print("VAL host", repr(h.load("mlx", part="MLX90609")))
    h.save_record("vm", [7, -8], part="ADXL355", kind=st.KIND_ADI_3POINT, frac=1,
                  t_span=(-4000, 8500), t_unit=st.T_CENTI_C, when=1767225600)
    f = open("/hostdata/host.cal", "rb")
    print("HEX hostfile", f.read().hex())
    f.close()

    # export as a const() module and import it
    s.export_module("/calib_const.py")
    import calib_const

    print("VAL export", repr(calib_const.RECORDS["mpu"]))

    # nvm backend on a plain bytearray
    nvm = bytearray(b"\xff" * 512)
    n = st.Store(nvm=nvm)
    n.save("g", (3, 4))
    n.save("g", (5, 6))
    ok("nvm", st.Store(nvm=nvm).load("g") == (5, 6) and nvm[256:260] == b"TCAL")
    nvm[300] ^= 1
    n2 = st.Store(nvm=nvm)
    ok("nvm_flip", n2.load("g") == (3, 4) and len(n2.warnings) == 1)

    # a whole newest copy (CRC right) with a malformed entry: the older copy is used and the
    # warning names the fault in words (tempcomp.store_check, from the decoder's code)
    _rm("/mal.cal")
    m = st.Store("/mal.cal")
    m.save("g", (1,))
    m.save("g", (2,))
    f = open("/mal.cal", "rb")
    img = bytearray(f.read())
    f.close()
    img[16 + 28 + 1] = 40  # header, fixed entry, name "g": frac[0]
    img[-4:] = struct.pack("<I", crc(img[:-4]))
    f = open("/mal.cal", "wb")
    f.write(img)
    f.close()
    m2 = st.Store("/mal.cal")
    ok("malformed", m2.load("g") == (1,) and len(m2.warnings) == 1
       and "/mal.cal is malformed: entry 0: frac[0] = 40 out of range; using /mal.cal.old" in m2.warnings[0])
    _rm("/mal.cal")

    torn_writes("/torn.bin")

    # allocation: lookups after load
    s = st.Store(p)
    s.refresh()
    out3 = array("i", [0, 0, 0])
    names = ("mpu", "g")
    state = array("i", [0])

    def lookup_varied(out):
        # alternate records and indexes so nothing is a cached repeat
        i = state[0]
        state[0] = (i + 1) & 3
        s.get_into(names[0], out)
        return s.get(names[i & 1], i & 1) + out[i % 3]

    allocprobe.report("store_get_into", s.get_into, ("mpu", out3))
    allocprobe.report("store_get", s.get, ("mpu", 2))
    allocprobe.report("store_lookup_varied", lookup_varied, (out3,))
    rec = s.record("mpu")
    vals = rec.values

    def rec_sum(v):
        return v[0] + v[1] + v[2]

    allocprobe.report("store_record_values", rec_sum, (vals,))
    print("DONE")


main()
