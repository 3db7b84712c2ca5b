"""The README's REPL examples work as written, on CPython and in the MicroPython VM."""

import doctest
import os
import re

import mpvm as vm

from tools import build_mpy

README = os.path.join(build_mpy.REPO, "README.md")


def repl_blocks(path=README):
    """Each ```python block made of >>> lines, as runnable source."""
    text = open(path).read()
    out = []
    for block in re.findall(r"```python\n(.*?)```", text, re.S):
        lines = [ln[4:] for ln in block.splitlines() if ln.startswith(">>> ") or ln.startswith("... ")]
        if lines:
            out.append("\n".join(re.sub(r"\s+#.*$", "", ln) for ln in lines) + "\n")
    return out


def test_readme_has_repl_examples():
    assert repl_blocks()


def test_readme_repl_examples_run_on_cpython_with_the_shown_output():
    text = open(README).read()
    for i, block in enumerate(re.findall(r"```python\n(.*?)```", text, re.S)):
        if ">>> " not in block or "tempcomp_board" in block:
            continue
        test = doctest.DocTestParser().get_doctest(block, {}, "README block %d" % i, README, 0)
        runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
        runner.run(test)
        assert runner.failures == 0, "README block %d does not give the output it shows" % i


def test_readme_repl_examples_run_in_the_vm():
    for src in repl_blocks():
        if "tempcomp_board" in src or "import board" in src:
            continue  # needs real hardware or the virtual board
        vm.run(src)
