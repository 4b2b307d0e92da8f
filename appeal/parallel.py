"""Map a function over items: local processes (joblib/loky) or a Dask distributed cluster.

Single-item failures are collected and reported, never fatal; results keep the input order,
so the local and the Dask path give identical results for the same items.
"""

from __future__ import annotations

import os
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import numpy as np

from appeal.logs import logger
from appeal.progress import progress

__all__ = ["ItemFailure", "MapResult", "parallel_map", "resolve_scheduler", "spawn_seeds"]

T = TypeVar("T")
R = TypeVar("R")

#: Environment variable naming a Dask scheduler address (same as ``--scheduler``).
SCHEDULER_ENV = "APPEAL_SCHEDULER"


@dataclass(frozen=True)
class ItemFailure:
    """One item whose call raised: its index, a label, the error line and the traceback."""

    index: int
    label: str
    error: str
    traceback: str = ""


@dataclass
class MapResult(Generic[R]):
    """Results in input order (``None`` where an item failed) plus the failures."""

    results: list[R | None]
    failures: list[ItemFailure] = field(default_factory=list)
    backend: str = "sequential"

    @property
    def ok(self) -> bool:
        """True when no item failed."""
        return not self.failures

    def successful(self) -> list[R]:
        """The results of the items that did not fail, in input order."""
        failed = {f.index for f in self.failures}
        return [r for i, r in enumerate(self.results) if i not in failed]  # type: ignore[misc]

    def summary(self) -> str:
        """One line: how many items ran, how many failed and which."""
        n = len(self.results)
        if not self.failures:
            return f"{n} items done ({self.backend})"
        names = ", ".join(f.label for f in self.failures[:5]) + (" ..." if len(self.failures) > 5 else "")
        return f"{n - len(self.failures)} of {n} items done ({self.backend}); failed: {names}"


#: How much a local worker's memory may grow over its first item's before loky restarts it as
#: leaking (loky's own bound is 300 MB). A render worker keeps the textures it drew (a scan's
#: albedo, normal and specular maps are 11 MB each, mipmapped on the GPU side too) to draw the
#: next image of the same material without uploading them again; at 300 MB loky restarted it
#: every few dozen images (re-importing pyrender and making a new OpenGL context, seconds each),
#: warning "A worker stopped while some jobs were given to the executor".
WORKER_MEMORY_GROWTH = 3 * 2**30


def _call(func: Callable[[Any], Any], item: Any) -> tuple[bool, Any, str]:
    """Run ``func(item)``; return (ok, value-or-error-line, traceback). Runs in workers."""
    from joblib.externals.loky import process_executor

    process_executor._MAX_MEMORY_LEAK_SIZE = WORKER_MEMORY_GROWTH  # read by the worker loop after each item
    try:
        return True, func(item), ""
    except Exception as exc:  # noqa: BLE001 - collected and reported by the caller
        return False, f"{type(exc).__name__}: {exc}".splitlines()[0], traceback.format_exc()


def _indexed_call(index: int, func: Callable[[Any], Any], item: Any) -> tuple[int, tuple[bool, Any, str]]:
    return index, _call(func, item)


def resolve_scheduler(scheduler: str | None = None) -> str | None:
    """The Dask scheduler address to use: ``scheduler``, else ``$APPEAL_SCHEDULER``, else None."""
    return scheduler or os.environ.get(SCHEDULER_ENV) or None


def spawn_seeds(seed: int | None, n: int) -> list[int]:
    """``n`` independent, reproducible 32-bit seeds derived from ``seed`` (NumPy SeedSequence)."""
    ss = np.random.SeedSequence(seed)
    return [int(s.generate_state(1)[0]) for s in ss.spawn(n)]


def _run_sequential(func, items, desc):
    for i, item in enumerate(progress(items, total=len(items), desc=desc)):
        yield i, _call(func, item)


def _run_loky(func, items, n_jobs, desc):
    from joblib import Parallel, delayed

    par = Parallel(n_jobs=n_jobs, backend="loky", return_as="generator_unordered")
    tasks = (delayed(_indexed_call)(i, func, it) for i, it in enumerate(items))
    yield from progress(par(tasks), total=len(items), desc=desc)


def _run_dask(func, items, address, desc):
    from distributed import Client, as_completed

    with Client(address, set_as_default=False) as client, client.as_current():
        futures = client.map(_call, [func] * len(items), items, pure=False)
        index = {fut.key: i for i, fut in enumerate(futures)}
        for fut in progress(as_completed(futures), total=len(items), desc=desc):
            yield index[fut.key], fut.result()


def parallel_map(
    func: Callable[[T], R],
    items: Sequence[T],
    *,
    n_jobs: int | None = None,
    scheduler: str | None = None,
    desc: str | None = None,
    labels: Sequence[str] | None = None,
) -> MapResult[R]:
    """Apply ``func`` to every item, in parallel, collecting failures instead of stopping.

    Parameters
    ----------
    func : callable
        A picklable function of one item (a module-level function or a
        :func:`functools.partial` of one).
    items : sequence
        The items. Results come back in this order.
    n_jobs : int | None
        Local worker processes; ``None`` uses all cores, ``1`` runs in this process.
        Ignored when a Dask scheduler is used.
    scheduler : str | None
        Address of a Dask distributed scheduler (``tcp://host:8786``). Defaults to the
        ``APPEAL_SCHEDULER`` environment variable; when neither is set, work stays local.
    desc : str | None
        Label of the progress bar.
    labels : sequence of str | None
        Names of the items for failure reports (default: ``str(item)``).

    Returns
    -------
    MapResult
        ``results`` in input order (``None`` for failed items) and ``failures``.
    """
    items = list(items)
    labels = [str(x) for x in (labels if labels is not None else items)]
    address = resolve_scheduler(scheduler)
    n_jobs = (os.cpu_count() or 1) if n_jobs is None else n_jobs
    if address:
        backend, stream = f"dask {address}", _run_dask(func, items, address, desc)
    elif n_jobs == 1 or len(items) <= 1:
        backend, stream = "sequential", _run_sequential(func, items, desc)
    else:
        backend, stream = f"loky x{n_jobs}", _run_loky(func, items, n_jobs, desc)
    results: list[Any] = [None] * len(items)
    failures: list[ItemFailure] = []
    for i, (ok, value, tb) in stream:
        if ok:
            results[i] = value
        else:
            failures.append(ItemFailure(i, labels[i], value, tb))
            logger.warning("%s failed: %s", labels[i], value)
            logger.debug("%s", tb)
    failures.sort(key=lambda f: f.index)
    return MapResult(results=results, failures=failures, backend=backend)
