"""Which recording files make one run of the service, and in what order.

The recorder starts a new file when one reaches ``max_bytes`` or ``max_duration_s``
(rotation), while the live pipeline runs on: its median, contact hysteresis and
rolling counters carry over from one file to the next. A replay equals the live
estimates only when it chains the files of one run through one pipeline, in order.

How files of one run are recognised: every file carries the MCAP metadata record
:data:`~daq.mcap_file.RUN_METADATA` with the machine id, a run id drawn when the
recorder starts (one per start of the service) and the file's index in the run (0,
1, 2, ...). Not the file names or times: a restart of the service within a second
is a new run, and a clock step cannot reorder files. A file without that record (a
recording of an earlier release) is a run of its own.

:func:`run_files` takes files and directories (a directory stands for its ``*.mcap``
files), checks that they are one run, and orders them; :func:`runs` groups the files
of many runs (a campaign, whose directories stand for every ``*.mcap`` file below them)
the same way. A file given twice (a directory and a file in
it, a symbolic link) counts once, and so does a copy of a file (a backup folder in the
campaign's tree: the same bytes, found by size and then content), with a warning line:
counted twice, a copy of a run without run metadata doubled its rows, and one of a run
with it stopped everything as "two files claim one index". A file missing from the
middle or the start of a run is logged: the estimates right after it differ from
the live ones until the median has refilled.
"""

import filecmp
import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from daq.errors import RecordingError
from daq.mcap_file import RUN_METADATA
from daq.mcap_reading import RecordedMessage, RecordedMetadata, RecordingStream

logger = logging.getLogger(__name__)

MCAP_SUFFIX = ".mcap"


def run_metadata(machine_id: str, run_id: str, file_index: int) -> dict[str, str]:
    """The :data:`~daq.mcap_file.RUN_METADATA` record of file ``file_index`` of a run."""
    return {"machine_id": machine_id, "run_id": run_id, "file_index": str(file_index)}


@dataclass(frozen=True, slots=True)
class RunFile:
    """A recording file and the run it belongs to (``run`` None: no run metadata)."""

    path: Path
    #: (machine id, run id).
    run: tuple[str, str] | None
    index: int


def read_run_file(path: Path) -> RunFile:
    """The run metadata of ``path``; reads only up to it (it precedes every message)."""
    try:
        with open(path, "rb") as stream:
            for record in RecordingStream(stream, str(path), warn=False):
                if isinstance(record, RecordedMetadata) and record.name == RUN_METADATA:
                    return _run_file(path, record.metadata)
                if isinstance(record, RecordedMessage):
                    break
    except OSError as exc:
        raise RecordingError(path, f"cannot open it: {exc.strerror or exc}") from exc
    return RunFile(path, None, 0)


def _run_file(path: Path, metadata: dict[str, str]) -> RunFile:
    try:
        return RunFile(
            path, (metadata["machine_id"], metadata["run_id"]), int(metadata["file_index"])
        )
    except (KeyError, ValueError) as exc:
        raise RecordingError(path, f"unreadable {RUN_METADATA} metadata {metadata}") from exc


def expand(paths: Sequence[Path], *, recursive: bool = False) -> list[Path]:
    """The files named, a directory replaced by its ``*.mcap`` files (sorted by path);
    ``recursive``: those in its subdirectories too (a campaign's tree of days or machines:
    without, a tree of day folders was "no .mcap files", and one with a recording at its
    top was reported without its folders, unsaid). A path that does not exist is a
    :class:`~daq.errors.RecordingError`."""
    files: list[Path] = []
    for path in paths:
        if path.is_dir():
            found = _mcap_files(path, recursive)
            if not found:
                below = " or below it" if recursive else ""
                raise RecordingError(path, f"no .mcap files in this directory{below}")
            files.extend(found)
        elif path.exists():
            files.append(path)
        else:  # said first: a CAN log's was "needs --config", as if --config were missing
            raise RecordingError(path, "no such file or directory")
    if not files:
        raise RecordingError("", "no recording given")
    return list(dict.fromkeys(files))


def _mcap_files(directory: Path, recursive: bool) -> list[Path]:
    """The ``*.mcap`` files in ``directory`` (and below it, without following links to
    directories, if ``recursive``), sorted."""
    if not recursive:
        return sorted(p for p in directory.iterdir() if p.suffix.lower() == MCAP_SUFFIX)
    return sorted(
        Path(folder, name)
        for folder, _, names in os.walk(directory)
        for name in names
        if Path(name).suffix.lower() == MCAP_SUFFIX
    )


def run_files(paths: Sequence[Path]) -> list[Path]:
    """The MCAP files of ``paths`` in the order of their run.

    Raises :class:`~daq.errors.RecordingError` when they belong to more than one run.
    """
    found = runs(paths)
    if len(found) > 1:
        listing = "; ".join(f"{name}: {', '.join(f.name for f in files)}" for name, files in found)
        raise RecordingError(
            found[0][1][0].parent,
            f"these files are {len(found)} runs of the service ({listing}); "
            "give the files of one run",
        )
    return found[0][1]


def runs(paths: Sequence[Path], *, recursive: bool = False) -> list[tuple[str, list[Path]]]:
    """The runs among the MCAP files of ``paths`` (a campaign; ``recursive``: a directory's
    subdirectories' too), each as its name and its files in order; runs in the order
    their first file was given (or found).

    Raises :class:`~daq.errors.RecordingError` for an unreadable file or two files
    claiming one index of a run.
    """
    grouped: dict[tuple[str, str] | Path, list[RunFile]] = {}
    for file in _without_copies(
        [read_run_file(path) for path in expand(paths, recursive=recursive)]
    ):
        grouped.setdefault(file.run or file.path, []).append(file)
    return [(_run_name(key), _ordered(members)) for key, members in grouped.items()]


def _without_copies(files: list[RunFile]) -> list[RunFile]:
    """``files`` without the ones given twice and without copies of a file before them.

    Only files of one size (and, with run metadata, of one run and index) are compared,
    so a campaign without copies reads nothing more than its files' sizes.
    """
    kept: list[RunFile] = []
    by_slot: dict[tuple[tuple[str, str] | None, int, int], list[RunFile]] = {}
    for file in files:
        try:
            size = file.path.stat().st_size
        except OSError as exc:
            raise RecordingError(file.path, f"cannot open it: {exc.strerror or exc}") from exc
        slot = by_slot.setdefault((file.run, file.index, size), [])
        original = next((other for other in slot if _same_bytes(other.path, file.path)), None)
        if original is None:
            slot.append(file)
            kept.append(file)
        elif not os.path.samefile(original.path, file.path):
            logger.warning("%s: left out, a copy of %s (the same bytes)", file.path, original.path)
    return kept


def _same_bytes(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b) or filecmp.cmp(a, b, shallow=False)
    except OSError as exc:
        raise RecordingError(b, f"cannot read it: {exc.strerror or exc}") from exc


def _ordered(files: list[RunFile]) -> list[Path]:
    """The files of one run by index; a missing file is logged."""
    ordered = sorted(files, key=lambda file: file.index)
    indexes = [file.index for file in ordered]
    for first, second in zip(ordered, ordered[1:], strict=False):
        if first.index == second.index:
            raise RecordingError(
                second.path,
                f"claims file {second.index} of the run as {first.path} does, with other "
                "bytes (a recovered copy of a cut file, say): give one of the two",
            )
    missing = sorted(set(range(indexes[-1] + 1)) - set(indexes))
    if ordered[0].run is not None and missing:
        logger.warning(
            "run %s: file(s) %s of the run missing; the estimates after each gap differ "
            "from the live ones until the median has refilled",
            ordered[0].run[1],
            ", ".join(map(str, missing)),
        )
    return [file.path for file in ordered]


def _run_name(key: tuple[str, str] | Path) -> str:
    return f"run {key[1]} of {key[0]}" if isinstance(key, tuple) else f"{key.name} (no run id)"
