"""Every shell, REPL and Python block in README.md and docs/ is run by a test or carries a
`<!-- not-run: REASON -->` marker (host_tests/helpers/docblocks.py): a new snippet without one
fails here."""

from docblocks import REPO, blocks, snippets

RUN = ("check: board-sh", "check: board-repl", "check: host-sh", "run-by:", "from docs/")


def kind(b):
    """'run' or 'not-run' for a block with a valid marker, else why the marker is missing or wrong."""
    if b.mark("not-run:") is not None:
        return "not-run" if len(b.mark("not-run:")) >= 15 else "a not-run marker without a reason"
    test = b.mark("run-by:")
    if test is not None:
        path = REPO / test
        if not path.is_file():
            return "run-by names a missing test %s" % test
        if b.page.name not in path.read_text():
            return "%s does not name %s" % (test, b.page.name)
        return "run"
    src = b.mark("from ")
    if src is not None:
        copies = [o for o in blocks(REPO / src) if o.body == b.body and o.lang == b.lang]
        if not copies:
            return "not a verbatim copy of a block of %s" % src
        return kind(copies[0])
    if any(m.startswith(RUN) for m in b.marks):
        return "run"
    return "no marker: run it in a test or say <!-- not-run: why -->"


def test_snippets_found():
    found = snippets()
    assert len(found) >= 40
    assert {b.page.name for b in found} >= {"README.md", "store.md", "demo.md", "install.md"}


def test_every_snippet_is_run_or_says_why_not():
    bad = ["%s (```%s): %s" % (b.where(), b.lang, kind(b)) for b in snippets() if kind(b) not in ("run", "not-run")]
    assert not bad, "\n".join(bad)


def test_run_shell_blocks_start_no_make_target():
    # make's targets set up first (npm ci, pip, firmware) and the long ones are jobs for the lead:
    # a shell block with one is marked not-run instead of run from a scratch checkout
    for b in snippets():
        if b.mark("check: board-sh") is not None or b.mark("check: host-sh") is not None:
            made = [ln for ln in b.body.splitlines() if ln.strip().startswith("make ") or " make " in ln.split("#")[0]]
            assert not made, "%s runs make: %s" % (b.where(), made)
