"""Every figure table of README.md and docs/ is one `make bench` run's output, and the figures that
do not depend on the machine are what the code gives now.

* The tables (and the paragraphs built from the same figures) sit between ``<!-- figures: NAME -->``
  markers and are rendered from the record `make bench` writes, docs/bench.json, by
  tools/bench/figures.py: a page whose block differs from the record's rendering fails here (a
  figure edited by hand, or a record refreshed without rendering the pages).
* Every other table of the pages is listed below as reference (no measured figure in it),
  history (figures of a past change, said so on the page) or pending (a figure table not rendered
  yet, with what it takes): a new figure table fails until it is rendered from the record or listed.
* The deterministic figures of the record (worst errors against float64 computed on CPython, the
  bias left by a calibration of the simulated part) are computed again here and must agree to the
  record's six significant digits; instruction counts, heap figures and the augmented-model table
  are checked by the tests that compute them (host_tests/augment/test_export_replay.py compares
  its before/after figures with the record); the blind benchmark's scores, deterministic but minutes
  to compute, by the fingerprint of the code that measured them (host_tests/simgap/test_simgap_blind.py). Timing figures are only required to be the record's:
  a run on another machine, or under another load, gives others.

When this fails after a change that moves figures: ``python -m tools bench AREA`` (or ``make
bench``) measures again, writes the record and renders the pages; commit docs/bench.json with them.
"""
import os
import re

import numpy as np
import pytest
from paths import REPO

from tools.bench import figures, record

REC = record.load()

# tables outside the figure blocks, by (page, header row): why they hold no figure of a run
REFERENCE = {
    ("README.md", "| offset | size | field | meaning |"): "the store's binary format (checked by test_store_format)",
    ("README.md", "| path | what | may import |"): "the layout (checked by test_layout)",
    ("README.md", "| board class | install path |"): "install paths",
    ("README.md", "| interpreter | build | what ran | result |"): "what the tests run where (pass/fail, no figures)",
    ("docs/adi_nxp.md", "| what | host command | on the board |"): "commands",
    ("docs/augment.md", "| feature | value | unit | from the effect |"): "the model's features",
    ("docs/demo.md", "| what | who can reach it |"): "the virtual board's exposure",
    ("docs/install.md", "| board class | examples | install path | command |"): "install paths",
    ("docs/mlx90609.md", "| Situation | What happens |"): "errors",
    ("docs/simgap.md", "| effect | gyro | accelerometer | basis |"): "the tool's plausibility limits (constants)",
    ("docs/simgap.md", "| effect | needs in the training log |"): "experiment design",
    ("docs/simgap.md", "| key | meaning |"): "the JSON contract",
    ("docs/simgap.md", "| name | fields | adds |"): "the JSON contract",
    ("docs/store.md", "| kind | constant | what the values are |"): "the store's kinds (checked by test_store_format)",
    ("docs/store.md", "| what | error |"): "errors",
    ("docs/store.md", "| offset | size | field | meaning |"): "the binary format (checked by test_store_format)",
    ("docs/security.md", "| attack | what happens | test |"): "the virtual board's threat model",
    ("docs/security.md", "| attack | what holds | test |"): "the virtual Pico's threat model",
    ("docs/simgap.md", "| situation | planted (truth) | noise |"): "the wander benchmark's situations (design)",
    ("docs/host-libraries.md", "| module | was | now |"): "libraries that replaced home-made code",
    ("docs/host-libraries.md", "| module | what it does by hand | why |"): "what is kept, and why",
}
# figure tables not rendered from the record yet, with what it takes: each one is a known gap
PENDING = {
}
HISTORY = {
    ("docs/ram.md", "| boot | before | after |"): "the mpu_tcc change, before and after (2026-11-25)",
    ("docs/ram.md", "| step | before the store split | after |"): "the store split, before and after (2026-11-25)",
    ("docs/ram.md", "| step (cumulative) | heap kept |"): "the sensors.restore boot before its cut below 24 KB, "
                                                         "where the bytes went (2026-11-27)",
    ("docs/ram.md", "| import | files over the mount (the bench) | files read in place (ROMFS, as from flash) |"):
        "the .py imports' headroom under a ballast, measured once for test_ram's route (2026-11-27)",
    ("docs/host-libraries.md", "| reader | per file |"): "fastcsv against pandas and pyarrow, measured once for "
                                                        "the decision to keep it (2026-11-27)",
    ("docs/simgap.md", "| situation | seeds passed | named alone / no verdict | withheld RMS / oracle floor: median, "
                       "worst | misses |"): "one wander-set sweep (python -m tools gap-check --set wander, seeds "
                                            "1-20, one log each) on the noise branch (2026-11-27)",
    ("docs/simgap.md", "| situation | named alone / no verdict | withheld RMS within 1.25x the oracle floor "
                       "(median, worst of the worst axis) | misses |"): "the wander-set sweep over seeds 21-81 "
                                                                       "(one log each) on main 6dce6f0 (2026-11-28)",
}


def _pages():
    return ["README.md"] + sorted(os.path.join("docs", f) for f in os.listdir(os.path.join(REPO, "docs"))
                                  if f.endswith(".md"))


@pytest.mark.parametrize("page", figures.pages())
def test_the_pages_figures_are_the_records(page):
    text = open(os.path.join(REPO, page), encoding="utf-8").read()
    want = figures.rendered(page, REC)
    if text != want:
        a, b = text.splitlines(), want.splitlines()
        k = next((i for i, (x, y) in enumerate(zip(a, b)) if x != y), min(len(a), len(b)))
        pytest.fail("%s line %d is not docs/bench.json's rendering (run `python -m tools bench --docs`, or the "
                    "area that measures it):\n  page:   %s\n  record: %s" % (
                        page, k + 1, a[k] if k < len(a) else "<end>", b[k] if k < len(b) else "<end>"))


def test_every_table_is_rendered_or_listed():
    unlisted = []
    seen = set()
    for page in _pages():
        inside = False
        prev = False
        for n, line in enumerate(open(os.path.join(REPO, page), encoding="utf-8").read().split("\n")):
            if figures.BEGIN.match(line):
                inside = True
            elif line == figures.END:
                inside = False
            table = line.startswith("|")
            if table and not prev and not inside:
                key = (page, line.strip())
                seen.add(key)
                if key not in REFERENCE and key not in HISTORY and key not in PENDING:
                    unlisted.append("%s:%d %s" % (page, n + 1, line))
            prev = table
    assert not unlisted, ("tables with figures must be rendered from docs/bench.json (tools/bench/figures.py), or "
                          "listed here as reference or history: %s" % unlisted)
    listed = set(REFERENCE) | set(HISTORY) | set(PENDING)
    assert not listed - seen, "listed but gone: %s" % (listed - seen)


def test_every_block_renders_from_the_record():
    # every figure a template uses is in the record, and every page with a template has its block
    assert not figures.missing(REC), figures.missing(REC)
    for page in figures.pages():
        names = set(figures.blocks(open(os.path.join(REPO, page), encoding="utf-8").read()))
        assert names == {n for p, n in figures.BLOCKS if p == page}, page


def test_a_figure_edited_by_hand_fails(tmp_path, monkeypatch):
    # the check can fail: README with one figure of the instruction table changed
    readme = open(os.path.join(REPO, "README.md"), encoding="utf-8").read()
    i = readme.index("<!-- figures: instructions -->")
    row = re.compile(r"(\| empty loop[^|]*\| )([\d,]+)")
    edited = readme[:i] + row.sub(lambda m: m.group(1) + "1" + m.group(2), readme[i:], count=1)
    assert edited != readme
    (tmp_path / "README.md").write_text(edited, encoding="utf-8")
    monkeypatch.setattr(figures, "REPO", str(tmp_path))
    assert figures.rendered("README.md", REC) == readme


def _close(recorded, now, what):
    # the record keeps six significant digits: 5e-6 relative at the most
    assert recorded == pytest.approx(now, rel=1e-5, abs=1e-9), "%s: docs/bench.json says %r, the code gives %r now (run " \
        "`python -m tools bench` for that area)" % (what, recorded, now)


def _row(area, key):
    return REC["areas"][area]["rows"][key]["value"]


def test_core_precision_figures_are_the_codes():
    # tools/bench/core.py's sweep (every raw code at 9 temperatures, 3 axes) on CPython, whose
    # integers the VM's equal (host_tests/core/test_kernels.py, test_precision.py)
    from tempcomp.fixedpoint import Compensator
    from tools.bench import core

    c = Compensator(core.OFFS, core.SCS, core.T_CAL, out_scale=core.OUT_SCALE)
    raws = np.arange(-32768, 32768)
    worst, exact, total = 0.0, 0, 0
    for t in [int(t) for t in np.linspace(core.T_CAL[0], core.T_CAL[1], 9)]:
        c.update(t)
        for k in range(3):
            ys = np.array([c.apply(int(r), k) for r in raws], dtype=float)
            ref = core.reference(k, t, raws.astype(float))
            worst = max(worst, float(np.abs(ys - ref).max()))
            exact += int(np.sum(ys == np.floor(ref + 0.5)))
            total += len(ys)
    _close(_row("core", "worst"), worst, "core.worst")
    _close(_row("core", "exact_pct"), 100.0 * exact / total, "core.exact_pct")


def test_fit_precision_figures_are_the_codes():
    from tools.bench import fit

    got = {}
    fit._precision(lambda name, value, unit, key=None, ok=None: got.__setitem__(key or record.slug(name), value))
    for k, v in got.items():
        _close(_row("fit", k), v, "fit." + k)


def test_mlx90609_precision_figure_is_the_codes():
    from tools.bench import mlx90609

    _close(_row("mlx90609", "worst"), mlx90609._worst_error(), "mlx90609.worst")


def test_instruction_counts_are_the_codes():
    # the fixed-point core's Cortex-M3 rows of README's instruction table (the core script of
    # tools/bench/instructions.py; the whole table takes minutes), measured again under qemu
    # -icount: exact but for a few instructions of UART interrupts (the host mount), so within
    # 0.5 % + 10
    from tools.bench import instructions
    from tools.firmware import interp as fw

    why = fw.missing("an385")
    if why:
        from paths import skip_unless_ci

        skip_unless_ci("an385 cannot run: %s" % why)
    got, notes = instructions.measure(names=("an385",), areas=("core",))
    assert "differ" not in notes.get("an385", "") and "failed" not in notes.get("an385", ""), notes
    stale = []
    assert len(got["an385"]) >= 10, got
    for key in got["an385"]:
        was = _row("instructions", "an385_" + key)
        now = got["an385"][key]
        if abs(was - now) > 0.005 * now + 10:
            stale.append("%s: %s in docs/bench.json, %s now" % (key, was, now))
    assert not stale, "instruction counts moved (run `python -m tools bench instructions`): %s" % stale
