"""Chamber CSV -> host fit -> tempcomp.store file -> the board loads it and compensates.

AN12760 Table 10 (the note's own numbers) goes through `python -m tools.fit an12760 --store`;
the store file is then opened by the on-device code in the MicroPython VM, which must give the
note's corrected values, -1000 / 0 / +1000 mg at every temperature, from raw counts.
"""

import subprocess
import sys

from tools.board import build_mpy
from tools.firmware import mpvm as vm

TABLE10 = [  # temp_c, ref_g, RawAcc mg (AN12760 Table 10)
    (-40, -1, -1178.1), (-40, 0, -85.0), (-40, 1, 1008.1),
    (25, -1, -1046.4), (25, 0, -20.0), (25, 1, 1006.4),
    (105, -1, -884.3), (105, 0, 60.0), (105, 1, 1004.3),
]
COUNTS_PER_G = 16384


def test_fitted_record_in_the_store_compensates_table10_on_the_board(tmp_path):
    csv = tmp_path / "accel_x.csv"
    csv.write_text("temp_c,ref_g,out_mg\n" + "".join("%d,%d,%.1f\n" % r for r in TABLE10))
    cal = tmp_path / "board" / "tempcomp.cal"
    cal.parent.mkdir()
    proc = subprocess.run(
        [sys.executable, "-m", "tools.fit", "an12760", str(csv), "--json", str(tmp_path / "a.json"),
         "--store", str(cal), "--name", "accel_x"],
        cwd=build_mpy.REPO, capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    rows = [(t, g, round(mg * COUNTS_PER_G / 1000.0)) for t, g, mg in TABLE10]
    out = vm.run(
        "from tempcomp.store import Store\n"
        "from tempcomp.an12760 import AN12760\n"
        "st = Store('/flash/tempcomp.cal')\n"
        "acc = AN12760.from_record(st.load('accel_x'), counts_per_g=%d, t_scale=1 / 333.87, t_offset=21.0, out_per_g=10000)\n"
        "for t, g, raw in %r:\n"
        "    acc.update(acc.code_of(t))\n"
        "    print('ROW', t, g, acc.apply(raw))\n" % (COUNTS_PER_G, rows),
        mounts=(str(cal.parent) + ":/flash",),
    )
    got = [line.split()[1:] for line in out.splitlines() if line.startswith("ROW ")]
    assert len(got) == 9
    for t, g, y in got:
        # 0.1 mg units; raw counts quantise the input to 1/16.384 mg, and temperature codes to
        # 1/333.87 degC, so one unit either side of the note's exact value
        assert abs(int(y) - int(g) * 10000) <= 1, (t, g, y)


def test_sixpos_cross_axis_law_through_the_store_on_the_board(tmp_path):
    """Six positions at five temperatures with a drifting cross-axis matrix -> `tools.fit sixpos
    --store` -> the board reads both records from the store and applies AN12760 + the cross-axis
    law per sample in the MicroPython VM: the VM's integers are CPython's, within 0.8 LSB of
    float64 (I + E(T)) v from the fit's JSON, zero bytes per sample under heap_lock. A store
    holding a constant-matrix record of the earlier 9-value layout still loads."""
    import json

    import numpy as np

    from tempcomp import record
    from tempcomp.an12760 import AN12760
    from tempcomp.crossaxis import CrossAxis
    from tempcomp.store import Store

    csv = tmp_path / "imu.csv"
    run = [sys.executable, "-m"]
    p = subprocess.run(run + ["tools.fit.simulate", "sixpos", str(csv), "--counts-per-g", "16384", "--cross-tc",
                              "1e-4", "--temps=-40,0,25,50,85", "--seed", "4"],
                       cwd=build_mpy.REPO, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    cal = tmp_path / "board" / "tempcomp.cal"
    cal.parent.mkdir()
    p = subprocess.run(run + ["tools.fit", "sixpos", str(csv), "--counts-per-g", "16384", "--order", "2", "--json",
                              str(tmp_path / "imu.json"), "--store", str(cal), "--name", "imu"],
                       cwd=build_mpy.REPO, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    old = record.pack(record.KIND_CROSS, [0.0, -0.004, 0.002, 0.004, 0.0, 0.001, -0.002, -0.001, 0.0])
    Store(str(cal)).save("old_cross", old)
    res = json.loads((tmp_path / "imu.json").read_text())
    law = res["cross_correction_law"]
    assert len(law["coeffs"]) == 4  # --order 2: N quadratic in T, E cubic (the device's highest degree)
    temps = [-40.0, -12.5, 25.0, 70.0, 85.0, 100.0]
    codes = [int(round((t - 21.0) * 333.87)) for t in temps]
    raws = [[16000, 120, -300], [-200, -16500, 900], [11000, 11500, -700]]
    out = vm.run(
        "from array import array\n"
        "import allocprobe\n"
        "from tempcomp.store import Store\n"
        "from tempcomp.an12760 import AN12760\n"
        "from tempcomp.crossaxis import CrossAxis\n"
        "st = Store('/flash/tempcomp.cal')\n"
        "kw = {'t_scale': 1 / 333.87, 't_offset': 21.0}\n"
        "acc = AN12760.from_record(st.load('imu'), 16384, out_per_g=10000, **kw)\n"
        "ca = CrossAxis.from_record(st.load('imu_cross'), **kw)\n"
        "old = CrossAxis.from_record(st.load('old_cross'), **kw)\n"
        "v = array('i', [0, 0, 0])\n"
        "w = array('i', [0, 0, 0])\n"
        "for c in %r:\n"
        "    acc.update(c)\n"
        "    ca.update(c)\n"
        "    old.update(c)\n"
        "    for r in %r:\n"
        "        acc.apply_all(r, v)\n"
        "        ca.apply(v, w)\n"
        "        print('ROW', c, v[0], v[1], v[2], w[0], w[1], w[2])\n"
        "        old.apply(v, w)\n"
        "        print('OLD', w[0], w[1], w[2])\n"
        "codes = array('i', %r)\n"
        "raw = array('h', [16000, 120, -300])\n"
        "i = array('i', [0])\n"
        "def sample():\n"
        "    k = i[0] + 1\n"
        "    if k == len(codes):\n"
        "        k = 0\n"
        "    i[0] = k\n"
        "    acc.update(codes[k])\n"
        "    ca.update(codes[k])\n"
        "    acc.apply_all(raw, v)\n"
        "    ca.apply(v, w)\n"
        "allocprobe.report('store_cross_law', sample, (), 120)\n" % (codes, raws, codes),
        mounts=(str(cal.parent) + ":/flash",),
    )
    rows = [[int(x) for x in ln.split()[1:]] for ln in out.splitlines() if ln.startswith("ROW ")]
    olds = [[int(x) for x in ln.split()[1:]] for ln in out.splitlines() if ln.startswith("OLD ")]
    assert len(rows) == len(codes) * len(raws)
    st = Store(str(cal))
    kw = dict(t_scale=1 / 333.87, t_offset=21.0)
    acc = AN12760.from_record(st.load("imu"), 16384, out_per_g=10000, **kw)
    ca = CrossAxis.from_record(st.load("imu_cross"), **kw)
    E_old = np.array([[0.0, -0.004, 0.002], [0.004, 0.0, 0.001], [-0.002, -0.001, 0.0]])
    C = [np.array(m) for m in law["coeffs"]]
    lo, hi = law["t_span_c"]
    for k, (c, *vals) in enumerate(rows):
        r = raws[k % len(raws)]
        acc.update(c)
        ca.update(c)
        v = [0, 0, 0]
        acc.apply_all(r, v)
        w = [0, 0, 0]
        ca.apply(v, w)
        assert vals == v + w, (c, vals, v, w)  # the VM computes CPython's integers
        d = min(max(c / 333.87 + 21.0, lo), hi) - law["t_room_c"]
        E = sum(m * d ** i for i, m in enumerate(C))
        assert np.max(np.abs(np.array(w) - (np.array(v) + E @ np.array(v)))) < 0.8
        assert np.max(np.abs(np.array(olds[k]) - (np.array(v) + E_old @ np.array(v)))) < 0.8
    b, ok = vm.alloc_lines(out)["store_cross_law"]
    assert b == 0 and ok, out
