"""The fleet's per-unit function runs unchanged on a real Dask cluster (a LocalCluster here: one
worker process on 127.0.0.1), through the Python API and through ``python -m tools fit --dask``,
with the same results as the one-process run (docs/fleet.md)."""

import json

import numpy as np
import pytest
import seeds
from distributed import Client, LocalCluster
from fleet_checks import check_flags

from tools.fit import __main__ as fitcli
from tools.fit import fleet
from tools.fit import simulate as S

CPG = 16384.0


@pytest.fixture(scope="module")
def cluster():
    # a worker process of its own: every unit's data, options and result cross a process
    # boundary pickled, as on a real cluster
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as c, Client(c) as client:
        yield c, client


@pytest.fixture(scope="module")
def units_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("dask") / "units"
    S.fleet_files(str(d), 12, np.random.default_rng(seeds.seed("fleet_dask_units")), samples=10, cpg=CPG, outliers=(4,))
    return d


def test_same_results_on_the_cluster_as_here(cluster, units_dir):
    _, client = cluster
    units = fleet.units_of(str(units_dir), "sixpos")
    opts = fleet.options("sixpos", counts_per_g=CPG)
    local, failed_here = fleet.run("sixpos", units, opts)
    remote, failed_there = fleet.run("sixpos", units, opts, client=client)
    assert failed_here == failed_there == {}
    assert list(remote) == list(local) == ["unit-%05d" % u for u in range(12)]
    assert remote == local
    # the worker really ran them: it holds the task results' keys in its log of tasks
    assert client.run(lambda: 1)  # a live worker answered
    assert any("fit_unit_safe" in str(k) for k in client.run_on_scheduler(
        lambda dask_scheduler: list(dask_scheduler.task_prefixes)))


def test_unit_column_sources_pickle_to_the_worker(cluster, tmp_path):
    _, client = cluster
    f = tmp_path / "line.csv"
    rows = ["unit,temp_c,ref_g,out_mg"]
    rng = np.random.default_rng(seeds.seed("fleet_dask_2"))
    for u in ("A7", "B2", "C9"):
        for t in (-40.0, 25.0, 85.0):
            for g in (-1.0, 1.0):
                rows.append("%s,%g,%g,%.3f" % (u, t, g, 5 + 0.2 * (t - 25) + g * 1003 + rng.normal(0, 0.3)))
    f.write_text("\n".join(rows) + "\n")
    units = fleet.units_of(str(f), "an12760")
    opts = fleet.options("an12760")
    assert fleet.run("an12760", units, opts, client=client) == fleet.run("an12760", units, opts)


def test_command_line_on_the_cluster(cluster, units_dir, tmp_path, capsys):
    c, _ = cluster
    out = tmp_path / "f.json"
    rc = fitcli.main(["sixpos", str(units_dir), "--counts-per-g", str(CPG), "--json", str(out),
                      "--dask", c.scheduler_address])
    text, err = capsys.readouterr()
    assert rc == 0, err
    doc = json.loads(out.read_text())
    assert len(doc["units"]) == 12
    check_flags(doc["summary"], ["unit-00004"])
    assert "12 unit(s) fitted" in text


def test_a_cluster_without_workers_is_one_line_not_a_hang(units_dir, tmp_path, capsys):
    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as empty:
        rc = fitcli.main(["sixpos", str(units_dir), "--counts-per-g", str(CPG), "--json", str(tmp_path / "f.json"),
                          "--dask", empty.scheduler_address, "--dask-wait", "1"])
    _, err = capsys.readouterr()
    assert rc == 2 and err.count("\n") == 1 and "no scheduler with a worker" in err, err
    assert not (tmp_path / "f.json").exists()
