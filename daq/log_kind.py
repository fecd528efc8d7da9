"""What a CAN log's content looks like, for a log whose suffix names another format.

Replay reads a log by its suffix (python-can's readers). A file saved under another
format's suffix (a candump log named ``.asc``, an ASC export named ``.log``) was read by
the wrong reader: python-can's ASC reader skips every line it does not take, so a
candump log named ``.asc`` replayed to no frame and exit 0; the other readers stopped
at the first line with their own words (``could not convert string to float:
'vcan0'``). :func:`content_suffix` tells the format from the first lines or bytes, so
that the message can say what the file is and which suffix reads it.

>>> content_suffix(b"(1796211064.171144) can0 100#461208070000001C\\n")
'.log'
>>> content_suffix(b"date Wed Dec 02 11:31:04.171 am 2026\\nbase hex  timestamps absolute\\n")
'.asc'
>>> content_suffix(b"just some notes\\n") is None
True
"""

import gzip
import re
import zlib
from pathlib import Path

#: What each suffix holds, in words.
FORMATS = {
    ".log": "a candump log",
    ".asc": "a Vector ASC log",
    ".blf": "a Vector BLF log",
    ".trc": "a PEAK TRC log",
    ".csv": "python-can's CSV log",
    ".db": "python-can's SQLite log",
    ".mf4": "an ASAM MDF4 log",
    ".mcap": "a service recording (MCAP)",
}

#: Binary formats by their first bytes.
_MAGIC = {
    b"LOGG": ".blf",
    b"\x89MCAP": ".mcap",
    b"SQLite format 3\x00": ".db",
    b"MDF     ": ".mf4",
}

#: Text formats by a line of theirs (among the first lines; the first pattern that a
#: line matches names the format).
_LINES = (
    # candump -L, and candump's readable output with a time (-ta, -tz, -tA)
    (re.compile(r"\s*\([^)]+\)\s+\S+\s+[0-9A-Fa-f]{1,8}#"), ".log"),
    (re.compile(r"\s*\([^)]+\)\s+\S+\s+(?:[RT]X\s+\S+\s+\S+\s+)?[0-9A-Fa-f]{3,8}\s+[\[{]"), ".log"),
    (re.compile(r"\s*(date\s+\w+|base\s+(hex|dec)\b|begin\s+triggerblock)", re.IGNORECASE), ".asc"),
    (re.compile(r"\s*\d+\.\d+\s+(\d+|CANFD\s+\d+)\s+[0-9A-Fa-f]{1,8}x?\s+[RT]x\s", re.I), ".asc"),
    (re.compile(r";\$FILEVERSION=|;\s+Start time:"), ".trc"),
    (re.compile(r"\s*\d+\)?\s+\d+\.?\d*\s+(\d+\s+)?(Rx|Tx|DT|FD|FB|BI|RR)\s"), ".trc"),
    (re.compile(r"timestamp,arbitration_id,", re.IGNORECASE), ".csv"),
    (re.compile(r"\d+(\.\d+)?,(0x)?[0-9A-Fa-f]+,[01],[01],[01],\d+,"), ".csv"),
)

#: How much of a file is looked at.
_HEAD_BYTES = 8192
_HEAD_LINES = 40


def content_suffix(head: bytes) -> str | None:
    """The suffix of the format ``head`` (a file's first bytes, decompressed) is in;
    None when it looks like none."""
    for magic, suffix in _MAGIC.items():
        if head.startswith(magic):
            return suffix
    text = head.decode("utf-8", errors="replace").lstrip("\ufeff")
    for line in text.splitlines()[:_HEAD_LINES]:
        for pattern, suffix in _LINES:
            if pattern.match(line):
                return suffix
    return None


#: The binary formats: their first bytes are no text to look at.
_BINARY = frozenset(_MAGIC.values())
#: The byte-order marks of UTF-16 text (a log saved by a Windows editor as "Unicode").
_UTF16_BOMS = (b"\xff\xfe", b"\xfe\xff")
#: A line of no content: blank, or a comment of a text log (TRC ``;``, ASC ``//``).
_NO_CONTENT = re.compile(r"\s*(?:$|;|//)")


def _no_log(head: bytes) -> str | None:
    """That a text log's first bytes ``head`` (of no format :func:`content_suffix` knows)
    look like no CAN log, in words; None when they hold nothing to say so (blank lines,
    comments: an empty log)."""
    lines = head.decode("utf-8", errors="replace").lstrip("\ufeff").splitlines()[:_HEAD_LINES]
    if all(_NO_CONTENT.match(line) for line in lines):
        return None
    return "nothing in its first lines looks like a line of a CAN log of any format"


def looks_like(path: Path, suffix: str, gzipped: bool = False, at_all: bool = False) -> str | None:
    """What ``path``, read as a log of ``suffix`` (``gzipped``: ``.gz`` after it), looks
    like instead, in words with the name that reads it (``it looks like a candump log:
    name it .log``; UTF-16 text); with ``at_all``, also that a text log looks like no CAN
    log at all; None when it looks like what its name says, holds nothing to tell (blank
    lines, comments), or cannot be read."""
    try:
        with open(path, "rb") as file:
            head = file.read(_HEAD_BYTES)
        compressed = head.startswith(b"\x1f\x8b")
        if compressed:  # look inside
            with gzip.open(path, "rb") as file:
                head = file.read(_HEAD_BYTES)
    except (OSError, EOFError, zlib.error):
        return None
    found = content_suffix(head)
    if compressed and not gzipped:
        kind = found or suffix
        return f"it is {FORMATS.get(kind, 'a log')} compressed by gzip: name it {kind}.gz"
    if found is None and suffix not in _BINARY:
        if head.startswith(_UTF16_BOMS):
            return "it is UTF-16 text: a CAN log is read as UTF-8 (or ASCII); save it so"
        return _no_log(head) if at_all else None
    if found is None or found == suffix:
        return None
    return f"it looks like {FORMATS[found]}: name it {found}{'.gz' if compressed else ''}"
