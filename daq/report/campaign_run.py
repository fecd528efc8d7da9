"""Running the campaign's per-recording work through an executor: local or a Dask cluster.

:func:`campaign` maps :func:`daq.report.campaign.run_rows` (the files of one run in,
rows out) over the runs of a campaign with a :class:`concurrent.futures.Executor`
and keeps the runs' order, so the table is the same whichever executor ran it.

- Default: local processes (:class:`~concurrent.futures.ProcessPoolExecutor`), one
  per CPU unless ``workers`` says otherwise; ``workers=1`` runs in this process.
  Workers are forked (no second of imports each) when this process has no other
  thread; otherwise they come from a ``forkserver`` that imported the report code
  once (a fork would copy other threads' locks mid-use).
- ``cluster="tcp://scheduler:8786"``: the same function on a Dask distributed
  cluster (the optional extra ``portal-daq[cluster]``), through the client's
  ``concurrent.futures`` interface. The paths are read by the workers: give paths
  as the workers see them (the data stays where it lives; only rows travel back).

A failure on one recording stops the campaign with that recording's error; a recording
that holds nothing (no frame, no estimate) is left out with a warning
(:func:`~daq.report.campaign.run_rows`).
"""

import logging
import multiprocessing
import multiprocessing.context
import os
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import Any

from daq.report.campaign import CampaignRow, run_rows
from dbc.errors import ConfigError, PortalDaqError

logger = logging.getLogger(__name__)

#: A run of the campaign: its name and its files in order (:func:`daq.recording_run.runs`).
Run = tuple[str, list[Path]]


class ClusterError(PortalDaqError):
    """The Dask cluster cannot be used (extra not installed, scheduler unreachable)."""


def campaign(
    runs: Sequence[Run],
    config_path: Path | None = None,
    *,
    cluster: str | None = None,
    workers: int | None = None,
) -> list[CampaignRow]:
    """The rows of every run, in the order of ``runs``."""
    work = partial(run_rows, config_path=config_path)
    with executor(cluster, workers, len(runs)) as pool:
        results = pool.map(work, [files for _, files in runs])
        return [row for rows in results for row in rows]


@contextmanager
def executor(cluster: str | None, workers: int | None, tasks: int) -> Iterator[Executor]:
    """Local processes, this process (``workers=1``), or a Dask cluster's executor."""
    if cluster is not None:
        with dask_executor(cluster) as pool:
            yield pool
        return
    if workers is not None and workers < 1:
        raise ConfigError("--workers", "", f"must be >= 1, got {workers}")
    count = min(workers or os.cpu_count() or 1, max(tasks, 1))
    if count == 1:
        yield InProcessExecutor()
        return
    with ProcessPoolExecutor(max_workers=count, mp_context=_start_method()) as pool:
        logger.info("campaign: %d recordings on %d local processes", tasks, count)
        yield pool


@contextmanager
def dask_executor(address: str) -> Iterator[Executor]:
    """A :class:`distributed.Client` on ``address`` and its executor; ClusterError when
    the extra is missing or the scheduler cannot be reached."""
    try:
        from distributed import Client
    except ImportError as exc:
        raise ClusterError(
            "--cluster needs Dask distributed: pip install 'portal-daq[cluster]'"
        ) from exc
    try:
        client = Client(address, timeout="10s")  # type: ignore[no-untyped-call]
    except (OSError, TimeoutError) as exc:
        raise ClusterError(f"Dask scheduler {address}: {exc} (is it running, reachable?)") from exc
    with client:
        workers = len(client.scheduler_info().get("workers", {}))
        logger.info("campaign on the Dask cluster %s (%d workers)", address, workers)
        yield client.get_executor()  # type: ignore[no-untyped-call]


def _start_method() -> multiprocessing.context.BaseContext:
    """``fork`` while this process has no other thread (the command line: workers start
    at once, the report code already imported); else ``forkserver`` (a fork would copy
    other threads' locks mid-use), preloaded with the report code."""
    if threading.active_count() == 1:
        return multiprocessing.get_context("fork")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload([run_rows.__module__])
    return context


class InProcessExecutor(Executor):
    """Runs each task at once in this process (one worker: no process to start)."""

    def map(self, fn: Callable[..., Any], *iterables: Any, **_: Any) -> Iterator[Any]:
        return map(fn, *iterables)
