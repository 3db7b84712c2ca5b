"""docs/fleet.md works as written: its shell blocks run from a checkout (the Dask one with a real
scheduler and two worker processes on 127.0.0.1), its Python block runs, and what they write
keeps the fleet contract."""

import json
import os
import re
import socket
import subprocess
import sys

from paths import REPO

DOC = os.path.join(REPO, "docs", "fleet.md")


def _blocks(kind):
    return re.findall(r"```%s\n(.*?)```" % kind, open(DOC).read(), re.S)


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_fleet_doc_runs_as_written(tmp_path):
    work = tmp_path / "checkout"
    work.mkdir()
    for name in (".venv", "tools", "lib"):
        os.symlink(os.path.join(REPO, name), work / name)
    env = dict(os.environ)
    sh = _blocks("sh")
    assert len(sh) == 3
    port = str(_free_port())
    for block in sh:
        p = subprocess.run(["bash", "-e", "-c", block.replace("8786", port)], cwd=work, capture_output=True,
                           text=True, timeout=600, env=env)
        assert p.returncode == 0, (block, p.stdout, p.stderr)
    cal = work / "cal"
    line = json.loads((cal / "line7.json").read_text())
    assert set(line) == {"units", "summary"} and len(line["units"]) == 200
    assert json.loads((cal / "line7.rec.json").read_text()) == {u: r["record"] for u, r in line["units"].items()}
    assert (cal / "line7.csv").read_text().count("\n") == 201
    one = json.loads((cal / "line7-all.json").read_text())
    assert list(one["units"]) == ["unit-%05d" % u for u in range(10)]
    for u in one["units"]:
        assert one["units"][u] == line["units"][u]
    assert json.loads((cal / "line7-dask.json").read_text())["units"] == line["units"]
    py = _blocks("python")
    assert len(py) == 1
    p = subprocess.run([sys.executable, "-c", py[0]], cwd=work, capture_output=True, text=True, timeout=600,
                       env=dict(env, PYTHONPATH=os.pathsep.join(filter(None, [str(work), env.get("PYTHONPATH")]))))
    assert p.returncode == 0, p.stderr
    assert p.stdout.split()[0] == "200"
