"""The exported model into the coefficient store (storetool put) and back out on the board
(tempcomp.augment.from_store) in the real MicroPython VM: the board compensates the same with
the stored model as with the JSON one."""
import json
import subprocess
import sys

import augsynth
import numpy as np
import seeds
from paths import REPO

from tools.firmware import mpvm
from tools.simgap import devmodel, export, replay
from tools.simgap.diagnose import diagnose


def test_put_then_restore_on_the_board_compensates_the_same(tmp_path):
    k = seeds.seed("store_put/log")  # the logs of this run
    tr, wh = augsynth.make("supply", seed=k), augsynth.make("supply", withheld=True, seed=k)
    res, _ = diagnose(tr, wh)
    model = tmp_path / "model.json"
    exp = export.write(str(model), res, tr)
    store = tmp_path / "tempcomp.cal"
    for name, extra in (("gyro_aug", []), ("other", ["--base"]), ("gyro_aug", [])):  # a second put replaces
        r = subprocess.run([sys.executable, "-m", "tools", "store", "put", str(store), str(model),
                            "--name", name] + extra, cwd=REPO, capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr
    assert "generation 3" in r.stdout
    inp = devmodel.board_inputs(exp["device"], wh.subset(np.arange(300)))
    rows = np.column_stack([inp["t"], inp["dt_ms"], inp["raw"], inp["supply"], inp["acc"]])
    (tmp_path / "rows.json").write_text(json.dumps(rows.tolist()))
    out = mpvm.run("""
import json
from array import array
from tempcomp.store import Store, KIND_AUGMENT
from tempcomp.augment import Augmented, from_store
st = Store('/data/tempcomp.cal')
print('NAMES', sorted(st.names()), st.record('gyro_aug').kind == KIND_AUGMENT,
      from_store(st, 'other')['features'] == [])
a = Augmented(from_store(st, 'gyro_aug'))
with open('/data/model.json') as f:
    b = Augmented(json.load(f)['device'])
with open('/data/rows.json') as f:
    rows = json.load(f)
raw = array('i', [0, 0, 0]); acc = array('i', [0, 0, 0]); oa = array('i', [0, 0, 0]); ob = array('i', [0, 0, 0])
worst = 0
for r in rows:
    raw[0], raw[1], raw[2] = r[2], r[3], r[4]
    acc[0], acc[1], acc[2] = r[6], r[7], r[8]
    a.apply(r[0], raw, oa, r[1], r[5], acc)
    b.apply(r[0], raw, ob, r[1], r[5], acc)
    worst = max(worst, abs(oa[0] - ob[0]), abs(oa[1] - ob[1]), abs(oa[2] - ob[2]))
print('WORST', worst, ob[0])
""", mounts=[str(tmp_path) + ":/data"])
    names = [ln for ln in out.splitlines() if ln.startswith("NAMES")][0]
    assert names == "NAMES ['gyro_aug', 'other'] True True"
    worst = int([ln for ln in out.splitlines() if ln.startswith("WORST")][0].split()[1])
    assert worst <= 1  # coefficients rounded to ~30 bits in the store
    full, _ = replay.replay(exp, wh.subset(np.arange(300)))
    assert full["allocated_per_sample"] == 0


def test_put_refuses_a_file_that_is_not_an_export(tmp_path):
    bad = tmp_path / "gap.json"
    bad.write_text('{"verdict": []}')
    r = subprocess.run([sys.executable, "-m", "tools", "store", "put", str(tmp_path / "s.cal"), str(bad),
                        "--name", "g"], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert "no 'store' section" in r.stderr and not (tmp_path / "s.cal").exists()
