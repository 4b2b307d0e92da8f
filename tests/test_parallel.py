"""The parallel map: order kept, failures collected, local and Dask give identical results."""

from __future__ import annotations

import numpy as np
import pytest

from appeal.parallel import parallel_map, resolve_scheduler, spawn_seeds


def _work(item: tuple[int, int]) -> float:
    """A deterministic piece of work that uses its own seed."""
    value, seed = item
    if value == 3:
        raise ValueError(f"item {value} is bad")
    rng = np.random.default_rng(seed)
    return float(value + rng.standard_normal(1000).mean())


ITEMS = list(zip(range(8), spawn_seeds(42, 8)))


def test_sequential_keeps_order_and_collects_failures():
    res = parallel_map(_work, ITEMS, n_jobs=1)
    assert res.backend == "sequential"
    assert [f.index for f in res.failures] == [3]
    assert res.failures[0].error == "ValueError: item 3 is bad"
    assert "Traceback" in res.failures[0].traceback
    assert res.results[3] is None
    assert len(res.successful()) == 7
    assert "failed" in res.summary()


def test_local_processes_match_sequential():
    seq = parallel_map(_work, ITEMS, n_jobs=1)
    loc = parallel_map(_work, ITEMS, n_jobs=2)
    assert loc.backend == "loky x2"
    assert loc.results == seq.results
    assert [f.index for f in loc.failures] == [3]


def test_dask_local_cluster_matches_local(monkeypatch):
    distributed = pytest.importorskip("distributed")
    loc = parallel_map(_work, ITEMS, n_jobs=2)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        dsk = parallel_map(_work, ITEMS, scheduler=cluster.scheduler_address)
        assert dsk.backend.startswith("dask ")
        assert dsk.results == loc.results
        assert [(f.index, f.error) for f in dsk.failures] == [(f.index, f.error) for f in loc.failures]
        # the environment variable selects the cluster too
        monkeypatch.setenv("APPEAL_SCHEDULER", cluster.scheduler_address)
        assert resolve_scheduler() == cluster.scheduler_address
        env = parallel_map(_work, ITEMS)
        assert env.backend.startswith("dask ") and env.results == loc.results


def test_spawn_seeds_reproducible_and_distinct():
    a, b = spawn_seeds(1, 5), spawn_seeds(1, 5)
    assert a == b and len(set(a)) == 5
    assert spawn_seeds(2, 5) != a
