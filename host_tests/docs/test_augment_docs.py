"""docs/augment.md works as written: its shell block from a log to the store (on logs from our own
generator, in a scratch directory; the mpremote copy is replaced by mounting the store into the
VM) and its board block, in the MicroPython VM, restoring the model from that store."""
import os
import re
import shlex
import subprocess
import sys

import augsynth
import seeds
from paths import REPO

from tools.firmware import mpvm
from tools.simgap.logio import write_log

DOC = os.path.join(REPO, "docs", "augment.md")


def blocks():
    return re.findall(r"```(\w*)\n(.*?)```", open(DOC).read(), re.S)


def write(path, log):
    cols = {"time_s": log.t, "temp_c": log.temp}
    cols.update({"out_%s" % a: log.out[:, i] for i, a in enumerate("xyz")})
    cols.update({"ref_%s" % a: log.ref[:, i] for i, a in enumerate("xyz")})
    write_log(path, cols, log.meta)


def test_shell_block_then_board_block(tmp_path):
    k = seeds.seed("augment_docs/log")  # the logs of this run
    write(str(tmp_path / "TRAIN.csv"), augsynth.make("hysteresis", seed=k))
    write(str(tmp_path / "HELD.csv"), augsynth.make("hysteresis", withheld=True, seed=k))
    (tmp_path / "out").mkdir()
    shell = [b for lang, b in blocks() if lang == ""][0]
    env = dict(os.environ, PYTHONPATH=REPO)
    ran = 0
    for line in shell.splitlines():
        cmd = shlex.split(line.split("#")[0])
        if not cmd:
            continue
        if cmd[0] == "mpremote":
            continue  # the VM below mounts the store where mpremote would have copied it
        assert cmd[:3] == ["python", "-m", "tools"], line
        r = subprocess.run([sys.executable] + cmd[1:], cwd=tmp_path, env=env, capture_output=True,
                           text=True, timeout=300)
        assert r.returncode == 0, (line, r.stderr)
        ran += 1
    assert ran == 4 and (tmp_path / "tempcomp.cal").exists()
    board, burst = [b for lang, b in blocks() if lang == "python"][:2]
    out = mpvm.run("t, dt_ms, supply = 2500, 1000, 0\nfifo, n = bytearray(6 * 8), 8\n" + board
                   + "\nprint('OUT', out[0], out[1], out[2])\n" + burst
                   # the burst against n samples through apply() on the same model from the store
                   + "\nb = Augmented(from_store(Store('/tempcomp.cal'), 'gyro_aug'))\n"
                   + "for i in range(n + 1):\n    b.apply(t, raw, out, dt_ms, supply, acc)\n"
                   + "print('BURST', list(outn[-3:]) == list(out))\n",
                   mounts=[str(tmp_path / "tempcomp.cal") + ":/tempcomp.cal"])
    assert "OUT" in out
    assert "BURST True" in out
