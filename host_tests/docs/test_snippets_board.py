"""Shell and REPL snippets in README.md and docs/*.md that talk to a board, run as written against
a fresh virtual board (issue 14).

A snippet opts in with a marker on the line before its code fence:

* ``<!-- check: board-sh -->``: the block runs in ``bash -e`` in a scratch copy of the checkout,
  with the .venv on PATH only once a block has run ``. .venv/bin/activate`` as README says;
* ``<!-- check: board-repl -->``: the block is Python typed at the board's REPL, run with
  ``mpremote exec``; ``<!-- check: board-repl expect: TEXT -->`` also wants TEXT in its output.
  A ``>>>`` session must print on the board what the page shows after each line.

The documented address ``socket://127.0.0.1:2323`` and tty ``build/vboard/tty`` are replaced by
the test board's own (a free port, its own flash), a bare ``mpremote`` (auto-connect) is pointed
at it, and every page's snippets run in order (README first) on one fresh board, from a scratch
copy of the checkout, as a reader following README then the docs would. A page's second and later
REPL blocks run with ``mpremote resume``: the same REPL session, names kept.
"""

import doctest
import os
import re
import subprocess
import sys
from pathlib import Path

import docblocks
from vboard_line import REPO, VirtualBoard

PAGES = docblocks.PAGES


def snippets(page):
    """(kind, body, expected text) of the page's blocks marked for the board, in order."""
    out = []
    for b in docblocks.blocks(page):
        sh, repl = b.mark("check: board-sh"), b.mark("check: board-repl")
        if sh is not None:
            out.append(("board-sh", b.body, None))
        elif repl is not None:
            out.append(("board-repl", b.body, repl[len("expect:"):].strip() if repl.startswith("expect:") else None))
    return out


MARKED = [p for p in PAGES if snippets(p)]


def test_some_board_snippets_are_marked():
    # the README's virtual-board commands at least; a marker typo would silently test nothing
    assert REPO / "README.md" in MARKED
    for p in PAGES:
        n = p.read_text().count("<!-- check: board-")
        assert n == len(snippets(p)), "%s: a check marker not right above a code block" % p.name


def board_doctest(body):
    """A `>>>` session as one script for the board, and what each line should print: every input
    line runs, an expression's value is printed as the REPL echoes it (repr, nothing for None), an
    expected traceback is caught and its exception name printed."""
    script, wants = [], []
    for i, ex in enumerate(doctest.DocTestParser().get_examples(body)):
        src = ex.source.rstrip("\n")
        script.append("print('@@%d')" % i)
        if ex.exc_msg is not None:
            want = ex.exc_msg.split(":")[0].split(".")[-1].strip()
            script += ["try:"] + ["    " + ln for ln in src.splitlines()]
            script += ["    print('no exception')", "except Exception as e:", "    print(type(e).__name__)"]
        else:
            want = ex.want
            try:
                compile(src, "snippet", "eval")
                script += ["_ = (%s\n)" % src, "if _ is not None:", "    print(repr(_))"]
            except SyntaxError:
                script.append(src)
        wants.append((src, " ".join(want.split())))
    return "\n".join(script) + "\n", wants


def check_doctest(out, wants):
    """The board's output of board_doctest(), line by line against what the page shows."""
    parts = re.split(r"^@@(\d+)\r?$", out, flags=re.M)
    got = {int(parts[k]): " ".join(parts[k + 1].split()) for k in range(1, len(parts) - 1, 2)}
    for i, (src, want) in enumerate(wants):
        assert i in got, "stopped before `%s`:\n%s" % (src, out)
        assert got[i] == want, "`%s` printed %r on the board, the page shows %r" % (src, got[i], want)


def checkout(tmp_path):
    """A scratch directory standing for the reader's checkout: what the commands read is linked,
    what they write (tempcomp.cal, cal.json, ...) stays out of the repository."""
    work = tmp_path / "checkout"
    work.mkdir()
    # no Makefile: `make` there would run its set-up (npm ci) through the linked tools/ and
    # replace the repository's node_modules; make targets are marked not-run
    for name in (".venv", "lib", "tools", "boards", "package.json", "manifest.py"):
        os.symlink(REPO / name, work / name)
    return work


def test_board_snippets_run_as_written(tmp_path):
    # one fresh board for every page, README first: a reader follows the README's set-up and
    # calibration, then the docs pages on the same board
    b = VirtualBoard(tmp_path / "flash").start()
    work = checkout(tmp_path)
    try:
        # the reader's shell: no .venv on PATH until a snippet activates it as the README says
        venv_bins = {str(Path(sys.executable).parent), str(REPO / ".venv" / "bin"),
                     os.path.realpath(REPO / ".venv" / "bin")}
        env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
        env["PATH"] = os.pathsep.join(d for d in os.environ.get("PATH", "").split(os.pathsep)
                                      if d and d not in venv_bins)
        env["BOARD_TCP"] = str(b.port)
        activate = ""  # the reader's shell stays activated for the pages after

        def local(text):
            text = text.replace("socket://127.0.0.1:2323", b.url)
            # a bare `mpremote cp ...` finds the one board attached: here, this one
            text = re.sub(r"^mpremote (?!connect )", "mpremote connect %s " % b.url, text, flags=re.M)
            return text.replace("build/vboard/tty", b.pty or "build/vboard/tty")

        ran = 0
        for page in MARKED:
            resume = ()
            for kind, body, expect in snippets(page):
                ran += 1
                if kind == "board-sh":
                    r = subprocess.run(["bash", "-e", "-x", "-c", activate + local(body)], cwd=work, env=env,
                                       capture_output=True, text=True, timeout=600)
                    out = r.stdout + r.stderr
                    assert r.returncode == 0, "%s: failed:\n%s\n%s" % (page.name, body, out)
                    assert "Traceback" not in out, "%s:\n%s\n%s" % (page.name, body, out)
                    if ". .venv/bin/activate" in body:
                        activate = ". .venv/bin/activate\n"
                    resume = ()
                else:
                    # the page's later REPL blocks continue the same REPL session (no soft reset)
                    script, wants = board_doctest(body) if ">>> " in body else (body, None)
                    r = b.mpremote(*resume, "exec", script, timeout=300, check=False)
                    resume = ("resume",)
                    out = r.stdout + r.stderr
                    assert r.returncode == 0 and "Traceback" not in out, "%s:\n%s\n%s" % (page.name, body, out)
                    if wants is not None:
                        check_doctest(out, wants)
                    if expect:
                        assert expect in out, "%s: %r not in the output of\n%s\n%s" % (page.name, expect, body, out)
        assert ran == sum(len(snippets(p)) for p in MARKED)
    finally:
        b.stop()
