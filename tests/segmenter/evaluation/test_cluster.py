"""Continuous recordings: the folds on a dask.distributed cluster give the same JSON as local
processes (docs/segmentation.md, "--scheduler")."""

import json

import pytest

from handflow.plugins.segmenter.cli import register_evaluate
from handflow.plugins.segmenter.evaluation import _folds as folds_module
from tests.conftest import run_command

distributed = pytest.importorskip("dask.distributed", reason="the cluster extra: pip install 'handflow[cluster]'")


def _result(capsys, argv) -> dict:
    assert run_command(register_evaluate, argv) == 0
    result = json.loads(capsys.readouterr().out)
    result.pop("runtime_s"), result.pop("timing")
    return result


@pytest.mark.slow  # a whole evaluation (docs/testing.md)
def test_folds_on_a_cluster_of_two_workers_give_the_local_figures(three_recordings_npz, capsys):
    """A manifold method with its online replay and a score method, on one view and the fewest
    recordings (screening more views is the same computation wherever a fold runs)."""
    methods = ["--methods", "ukr_clm,ukr_clm_online,dtw_1nn", "--normalise", "training", "--derived", "none"]
    argv = [str(three_recordings_npz), "--quick", "--json", *methods]
    local = _result(capsys, [*argv, "--jobs", "2"])
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        remote = _result(capsys, [*argv, "--scheduler", cluster.scheduler_address])
    assert remote == local
    assert [f["recording"] for f in remote["methods"]["ukr_clm"]["folds"]] == ["r0", "r1", "r2"]


def test_no_scheduler_at_the_address_says_how_to_start_one(three_class_npz, capsys, monkeypatch):
    monkeypatch.setattr(folds_module, "CONNECT_TIMEOUT", "1s")  # nothing listens there: the documented 10 s, shortened
    argv = [str(three_class_npz), "--quick", "--methods", "dtw_1nn", "--scheduler", "tcp://127.0.0.1:9"]
    assert run_command(register_evaluate, argv) == 2
    err = capsys.readouterr().err
    assert "no dask scheduler answers at tcp://127.0.0.1:9" in err and "dask worker" in err
