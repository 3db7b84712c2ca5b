"""`make bench`'s record (docs/bench.json) under a fault: an area that raises part-way keeps its
previous figures, the areas that ran replace theirs, and the exit status says it failed."""

import types

from tools.bench import __main__ as bench_main
from tools.bench import figures, record


def _old_record():
    return {"about": "x", "full_run": None, "areas": {
        "good": {"date": "2026-01-01", "rows": {"speed": {"name": "speed", "value": 1.0, "unit": "s"}}},
        "bad": {"date": "2026-01-01", "rows": {"speed": {"name": "speed", "value": 2.0, "unit": "s"},
                                               "ram": {"name": "ram", "value": 3.0, "unit": "MB"}}}}}


def _run(monkeypatch, argv, areas):
    """main(argv) with the named fake areas, the record in memory; returns (status, saved)."""
    saved = {}
    monkeypatch.setattr(bench_main, "areas", lambda: list(areas))
    monkeypatch.setattr(bench_main.importlib, "import_module",
                        lambda name: types.SimpleNamespace(bench=areas[name.rsplit(".", 1)[1]]))
    monkeypatch.setattr(record, "load", _old_record)
    monkeypatch.setattr(record, "save", lambda rec: saved.update(rec))
    monkeypatch.setattr(figures, "write_pages", lambda rec, strict=True: [])
    monkeypatch.setattr(figures, "missing", lambda rec: [])
    return bench_main.main(argv), saved


def _good(report):
    report("speed", 9.0, "s")


def _bad(report):
    report("speed", 8.0, "s")       # printed before the fault: a partial measurement
    raise RuntimeError("simulated fault half-way")


def test_an_area_that_raises_keeps_its_previous_figures(monkeypatch, capsys):
    status, saved = _run(monkeypatch, ["good", "bad"], {"good": _good, "bad": _bad})
    assert status == 1
    assert saved["areas"]["good"]["rows"]["speed"]["value"] == 9.0
    assert saved["areas"]["bad"] == _old_record()["areas"]["bad"]
    assert "bad: the area raised RuntimeError: simulated fault half-way" in capsys.readouterr().out


def test_a_full_run_keeps_a_raised_areas_record_and_drops_none_it_had(monkeypatch):
    status, saved = _run(monkeypatch, [], {"good": _good, "bad": _bad, "new": _bad})
    assert status == 1
    assert saved["areas"]["bad"]["rows"]["speed"]["value"] == 2.0
    assert "new" not in saved["areas"]      # never measured whole: no record rather than a partial one
    assert saved["areas"]["good"]["rows"]["speed"]["value"] == 9.0


def test_a_clean_run_replaces_the_area(monkeypatch):
    status, saved = _run(monkeypatch, ["bad"], {"bad": _good})
    assert status == 0
    assert saved["areas"]["bad"]["rows"] == {"speed": {"name": "speed", "value": 9.0, "unit": "s"}}
    assert saved["areas"]["good"] == _old_record()["areas"]["good"]
