"""Writing an output file that takes the place of what is there only once it is complete.

``replay --out`` and ``recover`` (into ``-o`` or in place) write through
:func:`replacing`: a run that fails half way (a bad config, a log that stops being
readable, a file that is no MCAP) leaves what the path named as it was, never emptied or
half written.
"""

import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any


@contextmanager
def replacing(path: Path, mode: str = "w") -> Iterator[IO[Any]]:
    """A file opened with ``mode`` (``"w"`` or ``"wb"``) that replaces ``path`` when the
    block ends without an exception, written beside it (``.NAME.part``, removed on an
    exception). A regular file is synced before it takes the place.

    What is there and no regular file (``/dev/null``, ``/dev/stdout``, a named pipe) is
    written to as it is: replacing it would put a regular file in its place. A symbolic
    link stays one: the file it names is replaced, and a replaced file's permission bits
    are kept (a group-readable results file stays so; hard links to it keep the old
    content, as with any replace-by-rename). Raises :class:`IsADirectoryError` for a
    directory, and the file system's :class:`OSError` as they come.
    """
    if path.is_dir():
        raise IsADirectoryError(0, "it is a directory", str(path))
    if path.exists() and not path.is_file():
        with open(path, mode) as direct:
            yield direct
        return
    real = path.resolve() if path.is_symlink() else path
    part = real.with_name(f".{real.name}.part")
    try:
        with open(part, mode, newline=None if "b" in mode else "") as out:
            yield out
            out.flush()
            if stat.S_ISREG(os.fstat(out.fileno()).st_mode):
                if real.exists():
                    os.fchmod(out.fileno(), stat.S_IMODE(real.stat().st_mode))
                os.fsync(out.fileno())
        os.replace(part, real)
    except BaseException:
        part.unlink(missing_ok=True)
        raise
