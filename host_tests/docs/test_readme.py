"""The README's examples work as written.

Blocks copied from a docs page carry `<!-- from docs/X.md -->` and must stand verbatim in that
page, whose own tests run them (against the simulated parts where they need hardware). The other
Python blocks with `>>>` run here as doctests on CPython, and in the MicroPython VM.
"""

import doctest
import os
import re

from tools.board import build_mpy
from tools.firmware import mpvm as vm

REPO = build_mpy.REPO
README = os.path.join(REPO, "README.md")
BLOCK = re.compile(r"(?:<!-- from (docs/[\w./-]+) -->\n)?(```[a-z]*\n(.*?)```)", re.S)


def blocks():
    """(source docs page or None, fenced block, block body) for every block in the README."""
    return [(m.group(1), m.group(2), m.group(3)) for m in BLOCK.finditer(open(README).read())]


def own_repl_blocks():
    return [body for src, fenced, body in blocks() if src is None and fenced.startswith("```python") and ">>> " in body]


def test_readme_has_repl_examples():
    assert own_repl_blocks()
    assert any(src for src, _, _ in blocks())


def test_copied_blocks_stand_verbatim_in_their_tested_docs_page():
    for src, fenced, _ in blocks():
        if src is None:
            continue
        page = open(os.path.join(REPO, src)).read()
        assert fenced in page, "README block marked as from %s differs from it:\n%s" % (src, fenced)


def test_readme_repl_examples_run_on_cpython_with_the_shown_output():
    for i, body in enumerate(own_repl_blocks()):
        test = doctest.DocTestParser().get_doctest(body, {}, "README block %d" % i, README, 0)
        runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
        runner.run(test)
        assert runner.failures == 0, "README block %d does not give the output it shows" % i


def test_readme_repl_examples_run_in_the_vm():
    for body in own_repl_blocks():
        src = "\n".join(ln[4:] for ln in body.splitlines() if ln.startswith((">>> ", "... ")))
        vm.run(src + "\n")
