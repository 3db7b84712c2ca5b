"""docs/adi_nxp.md works as written: its shell blocks run from a checkout, its REPL blocks give the
output they show on CPython and run in the MicroPython VM on the records those commands wrote."""

import doctest
import os
import re
import shutil
import subprocess
import sys

from paths import REPO

from tools.firmware import mpvm as vm

DOC = os.path.join(REPO, "docs", "adi_nxp.md")

# The REPL's board module on this host: the simulated ADXRS behind the two ADC channels, with a
# scripted rate table (the first 512 rate reads at rest, the next 512 at +200 dps, then at rest)
BOARD = '''
from tools.sim.analog_gyro_sim import AnalogGyroSim

ADC_VREF_MV = 3300
_sim = AnalogGyroSim(vref_mv=3300, divider=2.0)


class _Table:
    def __init__(self, ch):
        self.ch = ch
        self.n = 0

    def read_u16(self):
        self.n += 1
        _sim.rate_dps = 200.0 if 512 < self.n <= 1024 else 0.0
        return self.ch.read_u16()


def adc(name):
    return _Table(_sim.rate) if name == "rate" else _sim.temp
'''


def _blocks(kind):
    return re.findall(r"```%s\n(.*?)```" % kind, open(DOC).read(), re.S)


def test_doc_commands_and_repl(tmp_path, monkeypatch):
    work = tmp_path / "checkout"
    work.mkdir()
    for name in (".venv", "tools", "lib"):
        os.symlink(os.path.join(REPO, name), work / name)
    sh = _blocks("sh")
    assert len(sh) == 3
    for block in sh:
        p = subprocess.run(["bash", "-e", "-c", block], cwd=work, capture_output=True, text=True)
        assert p.returncode == 0, (block, p.stdout, p.stderr)
    # `mpremote cp cal/X :X`: the board's flash is a directory here
    board = tmp_path / "board"
    board.mkdir()
    for f in ("accel_x.rec.json", "imu.rec.json", "imu_cross.rec.json", "gyro.rec.json"):
        shutil.copy(work / "cal" / f, board / f)
    (board / "tempcomp_board.py").write_text(BOARD)
    repl = [b for b in _blocks("python") if ">>> " in b]
    assert len(repl) == 4
    # CPython: doctest, output as shown
    monkeypatch.chdir(board)
    monkeypatch.syspath_prepend(str(board))
    monkeypatch.syspath_prepend(REPO)
    for i, block in enumerate(repl):
        sys.modules.pop("tempcomp_board", None)
        test = doctest.DocTestParser().get_doctest(block, {}, "adi_nxp block %d" % i, DOC, 0)
        runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
        runner.run(test)
        assert runner.failures == 0, "docs/adi_nxp.md block %d does not give the output it shows" % i
    # MicroPython VM: the same lines run, the shown output checked
    for block in repl:
        lines = [ln[4:] for ln in block.splitlines() if ln.startswith(">>> ")]
        src = "import os\nos.chdir('/board')\n" + "\n".join(re.sub(r"\s+#.*$", "", ln) for ln in lines) + "\n"
        if "(10000, 0, -10000)" in block:
            src = src.replace("acc.apply(16454), acc.apply(983), acc.apply(-14488)",
                              "print((acc.apply(16454), acc.apply(983), acc.apply(-14488)))")
        out = vm.run(src, mounts=(str(board) + ":/board", REPO + "/tools:/tools"), paths=("/board", "/"))
        if "(10000, 0, -10000)" in block:
            assert out.strip() == "(10000, 0, -10000)", out
