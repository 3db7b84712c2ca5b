"""The REPL examples in docs/store.md work as written (on CPython, in a temporary directory)."""

import doctest
import os
import re

from paths import REPO


def test_docs_store_examples(tmp_path, monkeypatch):
    text = open(os.path.join(REPO, "docs", "store.md")).read()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    session = "\n".join(b for b in blocks if b.lstrip().startswith(">>>"))
    assert session.count(">>>") >= 12
    session = session.replace("/tempcomp.cal", "tempcomp.cal")
    monkeypatch.chdir(tmp_path)
    test = doctest.DocTestParser().get_doctest(session, {}, "docs/store.md", "docs/store.md", 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    runner.run(test)
    assert runner.failures == 0 and runner.tries >= 12
