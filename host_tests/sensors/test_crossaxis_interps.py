"""The cross-axis temperature law on every real interpreter (WebAssembly VM, Cortex-M3 and M7
firmware, CircuitPython): the integers CPython computes, and nothing allocated per sample with the
heap locked (update on a new temperature code + apply, the per-sample worst case)."""

from tempcomp.crossaxis import CrossAxis

E0 = [0.01, -0.004, 0.02, 0.004, -0.002, 0.001, -0.002, -0.031, 0.0005]
LAW = [[1e-4, -1e-4, 2e-5, 1e-4, 0.0, -3e-5, 1e-4, 1.5e-4, -1e-4], [1e-6, -5e-7, 0.0, 2e-7, 8e-7, 0.0, -1e-6, 0.0, 3e-7],
       [2e-9, 0.0, -3e-9, 0.0, 1e-9, 0.0, 0.0, -2e-9, 0.0]]
T_SCALE = 1 / 333.87
# codes across the MPU-6500's whole -40..85 degC span and beyond it (held at the edges)
CODES = list(range(-30000, 25001, 2750))
V = [[262143, -262143, 262143], [150000, -200000, 262143], [-1, 0, 255], [-262143, 131071, -65536]]

CODE = r"""
import micropython
from tempcomp.crossaxis import CrossAxis
cl = CrossAxis(E0, law=LAW, t_span_c=(-40, 85), t_scale=1 / 333.87, t_offset=21.0)
out = [0, 0, 0]
codes = CODES
vs = V
for c in codes:
    cl.update(c)
    for v in vs:
        cl.apply(v, out)
        print("ROW", c, out[0], out[1], out[2])
def run(n):
    i = 0
    k = 0
    while i < n:
        cl.update(codes[k])
        cl.apply(vs[0], out)
        k += 1
        if k == len(codes):
            k = 0
        i += 1
run(3)
micropython.heap_lock()
try:
    run(200)
    print("LOCKED ok")
except MemoryError:
    print("LOCKED fail")
finally:
    micropython.heap_unlock()
"""


def test_cross_axis_law_on_every_interpreter(interp):
    code = CODE.replace("E0", repr(E0)).replace("LAW", repr(LAW)).replace("CODES", repr(CODES)).replace("V\n", repr(V) + "\n")
    out = interp.run(code)
    got = [[int(x) for x in ln.split()[1:]] for ln in out.splitlines() if ln.startswith("ROW ")]
    cl = CrossAxis(E0, law=LAW, t_span_c=(-40, 85), t_scale=T_SCALE, t_offset=21.0)
    want = []
    for c in CODES:
        cl.update(c)
        for v in V:
            o = [0, 0, 0]
            cl.apply(v, o)
            want.append([c] + o)
    assert got == want, interp.name
    assert "LOCKED ok" in out, (interp.name, out)
