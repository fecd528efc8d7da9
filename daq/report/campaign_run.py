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
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

from daq.report.campaign import CampaignRow, run_rows
from daq.report.loading import recording_name
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
    """The rows of every run, in the order of ``runs``, each named by
    :func:`recording_names`."""
    work = partial(run_rows, config_path=config_path)
    names = recording_names([files for _, files in runs])
    with executor(cluster, workers, len(runs)) as pool:
        results = pool.map(work, [files for _, files in runs])
        return [
            replace(row, recording=name)
            for name, rows in zip(names, results, strict=True)
            for row in rows
        ]


def recording_names(runs: Sequence[Sequence[Path]]) -> list[str]:
    """Each run's name in the table: its first file's path from the directory all the
    runs are in (the file name, for a campaign of one directory). Two folders' files of
    one name (``day1/recording.mcap``, ``day2/recording.mcap``) were one recording by
    their names: the page counted 1 recording and "1 more recordings hold nothing".

    >>> recording_names([[Path("/c/d1/rec.mcap")], [Path("/c/d2/rec.mcap")]])
    ['d1/rec.mcap', 'd2/rec.mcap']
    >>> recording_names([[Path("/c/a.mcap")], [Path("/c/b_1.mcap"), Path("/c/b_2.mcap")]])
    ['a.mcap', 'b_1.mcap .. b_2.mcap (2 files)']
    """
    absolute = [[Path(os.path.abspath(path)) for path in files] for files in runs]
    if not absolute:
        return []
    base = Path(os.path.commonpath([files[0].parent for files in absolute]))
    return [recording_name(files, base) for files in absolute]


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
