"""Every fenced code block of README.md and docs/*.md with the markers written just above it
(issue 14: each documented snippet is run by a test, or says why it cannot be).

Markers are HTML comments on the lines right before the fence, any order:

* ``<!-- check: board-sh -->`` / ``<!-- check: board-repl [expect: TEXT] -->``: run against one
  fresh virtual board by host_tests/docs/test_snippets_board.py;
* ``<!-- check: host-sh -->``: shell lines run in a scratch checkout by test_snippets_host.py;
* ``<!-- run-by: host_tests/X.py -->``: that test runs the block (it names the page);
* ``<!-- from docs/X.md -->`` (README): a verbatim copy of a block of that page (test_readme.py);
* ``<!-- not-run: REASON -->``: not run, and why (a real port, a long job, a usage synopsis).
"""

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PAGES = [REPO / "README.md"] + sorted((REPO / "docs").glob("*.md"))
OUTPUT_LANGS = ("text", "json", "csv")  # what a command prints or a file holds: nothing to run
FENCE = re.compile(r"^\s*```(\w*)\s*$")
COMMENT = re.compile(r"^\s*<!--\s*(.*?)\s*-->\s*$")


class Block:
    def __init__(self, page, line, lang, body, marks):
        self.page, self.line, self.lang, self.body, self.marks = page, line, lang, body, marks

    def mark(self, prefix):
        for m in self.marks:
            if m.startswith(prefix):
                return m[len(prefix):].strip()
        return None

    def where(self):
        return "%s:%d" % (self.page.relative_to(REPO), self.line)


def blocks(page):
    lines = page.read_text().split("\n")
    out = []
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        j = i + 1
        while j < len(lines) and lines[j].strip() != "```":
            j += 1
        marks = []
        k = i - 1
        while k >= 0 and COMMENT.match(lines[k]):
            marks.insert(0, COMMENT.match(lines[k]).group(1))
            k -= 1
        out.append(Block(page, i + 1, m.group(1), "\n".join(lines[i + 1:j]) + "\n", marks))
        i = j + 1
    return out


def snippets():
    """Every block that is code (not a command's printed output)."""
    return [b for p in PAGES for b in blocks(p) if b.lang not in OUTPUT_LANGS]
