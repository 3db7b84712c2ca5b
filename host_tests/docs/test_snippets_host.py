"""Shell blocks marked `<!-- check: host-sh -->` in README.md and docs/ run as written, each page's
in order under `bash -e`, in a scratch directory standing for a fresh checkout (what they read is
linked from the repository, what they write stays there). A block of printed text marked
`<!-- check: printed -->` is what the page's shell block before it prints on stdout."""

import os
import subprocess

import docblocks
import pytest
from paths import REPO

PAGES = [p for p in docblocks.PAGES if any(b.mark("check: host-sh") is not None for b in docblocks.blocks(p))]


def test_some_host_blocks_are_marked():
    assert PAGES


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_host_blocks_run_as_written(page, tmp_path):
    # no Makefile: `make` there would run its set-up (npm ci) through the linked tools/ and
    # replace the repository's node_modules; make targets are marked not-run
    for name in (".venv", "lib", "tools", "boards", "package.json", "manifest.py"):
        os.symlink(os.path.join(REPO, name), tmp_path / name)
    printed = None
    for b in docblocks.blocks(page):
        if b.mark("check: printed") is not None:
            assert printed is not None, "%s: no host-sh block before it" % b.where()
            assert " ".join(b.body.split()) in " ".join(printed.split()), (
                "%s shows\n%s\nthe commands printed\n%s" % (b.where(), b.body, printed))
        if b.mark("check: host-sh") is None:
            continue
        r = subprocess.run(["bash", "-e", "-c", b.body], cwd=tmp_path, capture_output=True, text=True, timeout=600)
        out = r.stdout + r.stderr
        assert r.returncode == 0 and "Traceback" not in out, "%s:\n%s\n%s" % (b.where(), b.body, out)
        printed = r.stdout
