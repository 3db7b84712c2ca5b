"""Store attacks through path.new, run inside the MicroPython VM (host_tests/store/test_store_newfile.py).

The test makes /d/cal.bin.new a symlink to /d/victim.txt and /d/dangle.bin.new a symlink to a
file that does not exist, with the VM runner's --symlink, before this runs. MicroPython has no
lstat and no O_EXCL on this port (VfsPosix): the store must still refuse both.
Prints "OK name" / "FAIL name" lines and "VAL name repr".
"""
import os

from tempcomp import store as st

VICTIM = b"precious data, not a store"


def ok(name, cond):
    print(("OK " if cond else "FAIL ") + name)


def read(p):
    f = open(p, "rb")
    try:
        return f.read()
    finally:
        f.close()


def types(d):
    return sorted((e[0], e[1] & 0o170000) for e in os.ilistdir(d))


def main():
    f = open("/d/victim.txt", "wb")
    f.write(VICTIM)
    f.close()
    s = st.Store("/d/cal.bin")
    ok("reads_with_warning", s.names() == [] and "symbolic link" in s.warnings[0])
    try:
        s.save("g", (1, 2))
        ok("symlink_refused", False)
    except st.StoreError as e:
        print("VAL symlink_error %r" % (str(e),))
        ok("symlink_refused", "symbolic link" in str(e) and "refusing" in str(e))
    ok("victim_intact", read("/d/victim.txt") == VICTIM)
    ok("link_kept", ("cal.bin.new", 0o120000) in types("/d") and "cal.bin" not in os.listdir("/d"))
    # the dangling link: following it would create /d/nothere
    try:
        st.Store("/d/dangle.bin").save("g", (1,))
        ok("dangling_refused", False)
    except st.StoreError:
        ok("dangling_refused", "nothere" not in os.listdir("/d"))
    # force=True removes the link itself and saves; the target is never written
    s.save_record("g", (3, 4), force=True)
    ok("force_removes_link", st.Store("/d/cal.bin").load("g") == (3, 4)
       and read("/d/victim.txt") == VICTIM and "cal.bin.new" not in os.listdir("/d"))
    # a foreign plain file at path.new is refused too, and kept
    f = open("/d/cal.bin.new", "wb")
    f.write(b"my notes")
    f.close()
    try:
        s.save("g", (5,))
        ok("foreign_refused", False)
    except st.StoreError as e:
        ok("foreign_refused", "not a tempcomp store" in str(e) and read("/d/cal.bin.new") == b"my notes")
    # a torn scratch file of our own (a cut after the create) is removed by the next save
    f = open("/d/cal.bin.new", "wb")
    f.write(b"TCA")
    f.close()
    s.save("g", (6,))
    ok("own_torn_new_replaced", st.Store("/d/cal.bin").load("g") == (6,) and "cal.bin.new" not in os.listdir("/d"))
    print("DONE")


main()
