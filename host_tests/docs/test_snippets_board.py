"""Shell and REPL snippets in README.md and docs/*.md that talk to a board, run as written against
a fresh virtual board (issue 14).

A snippet opts in with a marker on the line before its code fence:

* ``<!-- check: board-sh -->``: each line is a shell command (mpremote, make, python -m tools),
  run from the repository root with the .venv first on PATH;
* ``<!-- check: board-repl -->``: the block is Python typed at the board's REPL, run with
  ``mpremote exec``; ``<!-- check: board-repl expect: TEXT -->`` also wants TEXT in its output.

The documented address ``socket://127.0.0.1:2323`` and tty ``build/vboard/tty`` are replaced by
the test board's own (a free port, its own flash), and each file's snippets run in order on one
fresh board, as a reader following the page would.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from vboard_line import REPO, VirtualBoard

MARK = re.compile(r"<!-- check: (board-sh|board-repl)(?: expect: (.*?))? -->\n```[a-z]*\n(.*?)```", re.S)
PAGES = [REPO / "README.md"] + sorted((REPO / "docs").glob("*.md"))


def snippets(page):
    return [(m.group(1), m.group(3), m.group(2)) for m in MARK.finditer(page.read_text())]


MARKED = [p for p in PAGES if snippets(p)]


def test_some_board_snippets_are_marked():
    # the README's virtual-board commands at least; a marker typo would silently test nothing
    assert REPO / "README.md" in MARKED
    for p in PAGES:
        n = p.read_text().count("<!-- check: board-")
        assert n == len(snippets(p)), "%s: a check marker not followed by a code block" % p.name


@pytest.mark.parametrize("page", MARKED, ids=[p.name for p in MARKED])
def test_board_snippets_run_as_written(page, tmp_path):
    b = VirtualBoard(tmp_path / "flash").start()
    try:
        env = dict(os.environ)
        env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
        env["BOARD_TCP"] = str(b.port)

        def local(text):
            text = text.replace("socket://127.0.0.1:2323", b.url)
            return text.replace("build/vboard/tty", b.pty or "build/vboard/tty")

        for kind, body, expect in snippets(page):
            if kind == "board-sh":
                for line in body.splitlines():
                    line = line.split("  #")[0].strip()
                    if not line:
                        continue
                    r = subprocess.run(local(line), shell=True, cwd=REPO, env=env, capture_output=True,
                                       text=True, timeout=300)
                    out = r.stdout + r.stderr
                    assert r.returncode == 0, "%s: `%s` failed:\n%s" % (page.name, line, out)
                    assert "Traceback" not in out, "%s: `%s`:\n%s" % (page.name, line, out)
            else:
                r = b.mpremote("exec", body, timeout=300, check=False)
                out = r.stdout + r.stderr
                assert r.returncode == 0 and "Traceback" not in out, "%s:\n%s\n%s" % (page.name, body, out)
                if expect:
                    assert expect in out, "%s: %r not in the output of\n%s\n%s" % (page.name, expect, body, out)
    finally:
        b.stop()
