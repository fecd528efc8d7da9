"""Hints naming what a config probably meant where a name is not in the DBC: a signal
or message spelt in another case, with a letter off, or a signal written without its
message or in another message. Pure: names in, a text out.

>>> did_you_mean("p_kolben", ["P_Kolben", "P_Stange", "Diag"])
'; did you mean P_Kolben?'
>>> did_you_mean("Temperature", ["P_Kolben", "P_Stange"])
''
"""

import difflib
from collections.abc import Iterable

from cantools.database.can import Database


def did_you_mean(name: str, names: Iterable[str]) -> str:
    """``"; did you mean X?"`` naming the names closest to ``name`` (any case first),
    or ``""`` where none is close."""
    known = list(dict.fromkeys(names))
    same = [other for other in known if other.lower() == name.strip().lower()]
    close = same or difflib.get_close_matches(name.strip(), known, n=3, cutoff=0.75)
    return f"; did you mean {' or '.join(close)}?" if close else ""


def messages_with(database: Database, signal: str) -> list[str]:
    """The messages of ``database`` that have a signal ``signal``, in DBC order."""
    return [
        message.name
        for message in database.messages
        if any(candidate.name == signal for candidate in message.signals)
    ]
