"""Writing an output file that takes the place of what is there only once it is complete.

``replay --out``, ``export`` and ``recover`` (into ``-o`` or in place) write through
:func:`replacing` (or :func:`replacing_path`, for a writer that opens the file itself):
a run that fails half way (a bad config, a log that stops being readable, a file that is
no MCAP) leaves what the path named as it was, never emptied or half written. And
:func:`refuse_an_input` keeps an output from naming a recording the command reads
(``replay REC.mcap --out REC.mcap`` replaced the recording with its CSV, ``export``
emptied it before reading it). :func:`named` gives a path given as ``.`` the name a
default output is derived from.
"""

import os
import stat
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from daq.errors import RecordingError


@contextmanager
def replacing_path(path: Path) -> Iterator[Path]:
    """The path to write instead of ``path``: beside it (``.NAME.part``), put in its
    place when the block ends without an exception (synced first), removed on one.

    What is there and no regular file (``/dev/null``, ``/dev/stdout``, a named pipe) is
    given as it is: replacing it would put a regular file in its place. A symbolic link
    stays one: the file it names is replaced, and a replaced file's permission bits are
    kept (a group-readable results file stays so; hard links to it keep the old content,
    as with any replace-by-rename). Raises :class:`IsADirectoryError` for a
    directory, and the file system's :class:`OSError` as they come.
    """
    if path.is_dir():
        raise IsADirectoryError(0, "it is a directory", str(path))
    if path.exists() and not path.is_file():
        yield path
        return
    real = path.resolve() if path.is_symlink() else path
    part = real.with_name(f".{real.name}.part")
    try:
        yield part
        if real.exists():
            os.chmod(part, stat.S_IMODE(real.stat().st_mode))
        descriptor = os.open(part, os.O_RDONLY)
        try:
            os.fsync(descriptor)
        finally:
            os.close(descriptor)
        os.replace(part, real)
    except BaseException:
        part.unlink(missing_ok=True)
        raise


@contextmanager
def replacing(path: Path, mode: str = "w") -> Iterator[IO[Any]]:
    """A file opened with ``mode`` (``"w"`` or ``"wb"``) that replaces ``path`` when the
    block ends without an exception, as :func:`replacing_path` says."""
    with (
        replacing_path(path) as target,
        open(target, mode, newline=None if "b" in mode else "") as out,
    ):
        yield out


def refuse_an_input(out: Path, inputs: Iterable[Path], option: str = "--out") -> None:
    """Raise :class:`~daq.errors.RecordingError` when ``out`` is one of the files
    ``inputs`` (the files a command reads) under any name: writing it would replace, or
    empty, what the command reads before it has read it."""
    if not out.exists():
        return
    for path in inputs:
        if path.exists() and os.path.samefile(out, path):
            raise RecordingError(
                out, f"{option} names {path}, which this reads; give {option} another file"
            )


def named(path: Path) -> Path:
    """``path``, or where it is ``.`` or ends in ``..`` (no name of its own), the
    directory it stands for: a default output is named after it (``report .`` was a
    ValueError traceback, ``export . --to asc`` wrote a hidden ``./.asc``).

    >>> named(Path("rec.mcap")), named(Path("/data/day1/.")), named(Path("/data/day1/.."))
    (PosixPath('rec.mcap'), PosixPath('/data/day1'), PosixPath('/data'))
    """
    return path if path.name not in ("", "..") else Path(os.path.abspath(path))
