"""Store figures for `make bench`: bench(report) runs one MicroPython VM session and reports.

Sizes are exact; times are the WebAssembly VM's on an in-memory filesystem (relative figures:
flash writes on a board add the erase/program time of the filesystem).
"""


_CODE = """
import gc, time
from array import array
import allocprobe
from tempcomp import store as st

s = st.Store("/bench.cal")
vals = [i * 1000 - 12000 for i in range(24)]
t0 = time.ticks_us()
for k in range(4):
    s.save_record("sensor%d" % k, vals, part="MPU6050", serial="SN%d" % k,
                  kind=st.KIND_MPU_POLY, frac=14, t_span=(-2000, 6000), when=1767225600)
t_save = time.ticks_diff(time.ticks_us(), t0) / 4
f = open("/bench.cal", "rb"); size = len(f.read()); f.close()
gc.collect()
a0 = gc.mem_alloc()
t0 = time.ticks_us()
s2 = st.Store("/bench.cal")
s2.refresh()
t_load = time.ticks_diff(time.ticks_us(), t0)
alloc = gc.mem_alloc() - a0
out = array("i", [0] * 24)
print("BENCH image_bytes", size)
print("BENCH save_us", t_save)
print("BENCH load_us", t_load)
print("BENCH load_alloc", alloc)
allocprobe.report("get_into", s2.get_into, ("sensor3", out))
"""


def bench(report):
    from tools.firmware import mpvm

    out = mpvm.run(_CODE)
    figures = {}
    for line in out.splitlines():
        if line.startswith("BENCH "):
            _, name, value = line.split()
            figures[name] = float(value)
    report("store image, 4 sensors x 24 values", figures["image_bytes"], "bytes")
    report("store bytes per value (4 x 24 values)", figures["image_bytes"] / 96, "bytes")
    report("store save (VM, in-memory FS)", figures["save_us"] / 1000, "ms")
    report("store load of 4 records (VM)", figures["load_us"] / 1000, "ms")
    report("store load allocation (4 x 24 values)", figures["load_alloc"], "bytes")
    gi = mpvm.alloc_lines(out)["get_into"][0]
    report("store get_into allocation", gi, "bytes/call", ok=gi == 0)


if __name__ == "__main__":
    bench(lambda name, value, unit: print("%-45s %10.3f %s" % (name, value, unit)))
