"""Loading the CAN database (DBC) with cantools, with errors a person can act on."""

import codecs
import logging
import re
from collections import OrderedDict
from pathlib import Path

import cantools
from cantools.database.can import Database, Message
from cantools.database.conversion import BaseConversion
from cantools.database.errors import Error as CantoolsError
from cantools.database.errors import UnsupportedDatabaseFormatError

from dbc.errors import DbcError

logger = logging.getLogger(__name__)

#: How a DBC file's bytes are read where they are not UTF-8 (cantools' ``load_file`` default
#: for DBC: Vector's tools write Windows-1252, e.g. a unit "°C"), the file and a
#: recording's copy of it alike.
DBC_ENCODING = "cp1252"
#: Byte-order marks a DBC may start with (an editor's "UTF-8 with BOM", Windows'
#: "Unicode" = UTF-16), each with the encoding it declares: it wins over DBC_ENCODING.
_BOM_ENCODINGS = (
    (codecs.BOM_UTF8, "utf-8-sig"),
    (codecs.BOM_UTF16_LE, "utf-16"),
    (codecs.BOM_UTF16_BE, "utf-16"),
)
#: CAN databases of other formats (cantools reads them; the config takes a DBC, which a
#: recording embeds): what their text starts with, and the format's name.
_OTHER_FORMATS = (
    ("<NetworkDefinition", "a KCD"),
    ("<AUTOSAR", "an ARXML"),
    ("FormatVersion=", "a SYM"),
)


def load_database(path: str | Path) -> Database:
    """Load a DBC file with cantools' checks (a message whose signals overlap or do not
    fit in it is read without them, with a warning: :func:`_without_layout_checks`).

    Raises :class:`DbcError` naming the file when it is missing, unreadable,
    malformed or not a CAN database.
    """
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError as exc:
        raise DbcError(path, "no such file; set machine.dbc in the config to the DBC") from exc
    except OSError as exc:
        raise DbcError(path, f"cannot read it: {exc.strerror or exc}") from exc
    try:
        return load_database_bytes(data, str(path))
    except DbcError as exc:
        head = data[:4096].decode("utf-8", errors="replace")
        kind = next((kind for start, kind in _OTHER_FORMATS if start in head), None)
        if kind is None:
            raise
        dbc_path = Path(path).with_suffix(".dbc")
        raise DbcError(
            path,
            f"{kind} file, not a DBC: portal-daq reads DBC only; convert it with "
            f"`cantools convert {path} {dbc_path}`",
        ) from exc


def load_database_string(text: str, source: str) -> Database:
    """Load a DBC from its text (e.g. one embedded in a recording); ``source`` names it."""
    if not text.strip():
        raise DbcError(source, "is empty: no CAN messages")
    text = _with_attribute_definitions(_with_extended_flags(text, source), source)
    try:
        database = _load(text, source, strict=True)
    except (UnsupportedDatabaseFormatError, ValueError, KeyError) as exc:
        database = _without_layout_checks(text, source, exc)
    else:
        if isinstance(database, Database):
            _warn_undecodable(database, source)
    if not isinstance(database, Database) or not database.messages:
        raise DbcError(source, "holds no CAN messages")
    _mark_j1939_network(database)
    _signed_value_tables(database)
    return database


def _signed_value_tables(database: Database) -> None:
    """Keys the value tables of signed integer signals by the values their bits decode
    to: a table that lists the bits as unsigned (``VAL_ ... 65535 "SNA" 65534 "Error"``
    of a 16-bit signed signal, as a vendor's sheet writes them) is keyed -1, -2, what
    cantools looks a frame's raw value up by. Keyed 65535 the name was never found: a
    transducer's "not available" 0xFFFF was a valid -1 step (-0.01 bar), and encoding
    the name overflowed. Where both forms name one value, the signed one is kept."""
    for message in database.messages:
        for signal in message.signals:
            if not signal.is_signed or signal.is_float or not signal.choices:
                continue
            half = 1 << (signal.length - 1)
            unsigned = [raw for raw in signal.choices if half <= raw < 2 * half]
            if not unsigned:
                continue
            choices = OrderedDict(
                (raw, name) for raw, name in signal.choices.items() if raw not in unsigned
            )
            for raw in unsigned:
                choices.setdefault(raw - 2 * half, signal.choices[raw])
            signal.conversion = BaseConversion.factory(
                signal.scale, signal.offset, choices, signal.is_float
            )


def _mark_j1939_network(database: Database) -> None:
    """Marks the 29-bit messages of a J1939 network (the DBC's ``ProtocolType`` is
    ``"J1939"``, as in Vector's J1939 template) J1939 where they say no ``VFrameFormat``
    of their own: cantools reads only that attribute, so such a DBC's messages were
    matched by their whole ID, and a transducer sending at another priority or from
    another address than the DBC's ID was ``unknown_id``, its leg stale."""
    network = database.dbc.attributes.get("ProtocolType") if database.dbc else None
    if network is None or str(network.value).strip().upper() != "J1939":
        return
    for message in database.messages:
        own = message.dbc.attributes if message.dbc is not None else {}
        if message.is_extended_frame and message.protocol is None and "VFrameFormat" not in own:
            message.protocol = "j1939"


def _without_layout_checks(text: str, source: str, refused: Exception) -> Database:
    """The DBC as cantools reads it without its checks of the signals' layout, where
    those alone refused it: a whole vehicle's DBC may have a message whose signals
    overlap or do not fit (CANdb++ warns and saves it) that no leg uses. The machine
    config refuses such a message where it uses one (:func:`unsound`)."""
    try:
        database = _load(text, source, strict=False)
    except (UnsupportedDatabaseFormatError, ValueError, KeyError):
        reason = _first_line(refused)
        raise DbcError(source, f"not a valid DBC: {reason}{_hint(reason, text)}") from refused
    if not isinstance(database, Database):
        raise DbcError(source, "holds no CAN messages")
    problems = [problem for problem in map(unsound, database.messages) if problem]
    logger.warning(
        "%s: read as cantools reads it, without its checks: %s",
        source,
        "; ".join(problems or [_first_line(refused)]),
    )
    return database


#: A message's ID where a statement after the messages names one: its attributes,
#: value tables, comments, float types, multiplexer values, senders, signal groups.
_NAMES_A_MESSAGE = re.compile(
    r'^(?P<head>[ \t]*(?:BA_[ \t]+"[^"]*"[ \t]+(?:BO_|SG_)|BA_REL_[ \t]+"[^"]*"[ \t]+'
    r"BU_SG_REL_[ \t]+\w+[ \t]+SG_|VAL_|CM_[ \t]+(?:BO_|SG_)|SIG_VALTYPE_|SG_MUL_VAL_|"
    r"BO_TX_BU_|SIG_GROUP_)[ \t]+)(?P<id>\d+)\b",
    re.M,
)
_MESSAGE_ID = re.compile(r"^[ \t]*BO_[ \t]+(\d+)[ \t]", re.M)
#: The DBC's flag of a 29-bit ID (bit 31 of the number a ``BO_`` line writes).
EXTENDED_FLAG = 0x80000000


def _with_extended_flags(text: str, source: str) -> str:
    """``text`` with the statements that name a 29-bit message by its ID without the
    extended flag (``BA_ "GenMsgCycleTime" BO_ 419373089 10;`` for ``BO_ 2566856737``:
    a hand edit, or a script writing the ID both ways) naming it as its ``BO_`` does,
    with one warning: cantools ignored such an attribute (the cycle time was "not in the
    DBC") and refused such a value table (left out: a status had no names)."""
    ids = {int(number) for number in _MESSAGE_ID.findall(text)}
    fixed: dict[int, int] = {}

    def flagged(match: re.Match[str]) -> str:
        number = int(match["id"])
        if number in ids or number | EXTENDED_FLAG not in ids:
            return match[0]
        fixed[number] = number | EXTENDED_FLAG
        return f"{match['head']}{number | EXTENDED_FLAG}"

    text = _NAMES_A_MESSAGE.sub(flagged, text)
    if fixed:
        logger.warning(
            "%s: read as the 29-bit messages they are: the statements naming %s without "
            "the extended flag (bit 31)",
            source,
            ", ".join(f"{number} (BO_ {flagged_id})" for number, flagged_id in fixed.items()),
        )
    return text


#: An attribute's definition, and a value given to one: ``BA_DEF_ BO_ "NAME" ...`` and
#: ``BA_ "NAME" BO_ 123 10;`` (the network's, a node's, a message's, a signal's ...).
_DEFINED = re.compile(r'^[ \t]*BA_DEF_[ \t]+(?:(?:BU_|BO_|SG_|EV_)[ \t]+)?"([^"]*)"', re.M)
_ASSIGNED = re.compile(
    r'^[ \t]*BA_[ \t]+"(?P<name>[^"]*)"[ \t]+(?:(?P<kind>BU_|BO_|SG_|EV_)[ \t]+)?'
    r'(?:[^;"]*[ \t])?(?P<value>"[^"]*"|[-+.\w]+)[ \t]*;',
    re.M,
)
#: Vector's frame formats, as its templates define ``VFrameFormat`` (3: J1939).
VFRAME_FORMATS = (
    '"StandardCAN","ExtendedCAN","reserved","J1939PG",'
    + ",".join(['"reserved"'] * 10)
    + ',"StandardCAN_FD","ExtendedCAN_FD"'
)


def _with_attribute_definitions(text: str, source: str) -> str:
    """``text`` with a definition for each attribute it gives a value to without
    defining it (``BA_ "GenMsgCycleTime" BO_ 256 10;`` with no ``BA_DEF_``: a DBC
    written by hand or by a script), by the values given (a number, a string;
    ``VFrameFormat`` as Vector defines it), with one warning: cantools refused the whole
    DBC with the attribute's name alone (``DBC: "'GenMsgCycleTime'"``)."""
    defined = set(_DEFINED.findall(text))
    missing: dict[str, tuple[str, list[str]]] = {}
    for match in _ASSIGNED.finditer(text):
        if match["name"] not in defined:
            kind, values = missing.setdefault(match["name"], (match["kind"] or "", []))
            values.append(match["value"])
    if not missing:
        return text
    definitions = []
    for name, (kind, values) in missing.items():
        if name == "VFrameFormat":
            value_type = f"ENUM {VFRAME_FORMATS}"
        elif all(value.startswith('"') for value in values):
            value_type = "STRING"
        elif all(re.fullmatch(r"[-+]?\d+", value) for value in values):
            value_type = "INT -2147483648 2147483647"
        else:
            value_type = "FLOAT -1e308 1e308"
        definitions.append(f'BA_DEF_ {kind} "{name}" {value_type};'.replace("  ", " "))
    logger.warning(
        "%s: attributes given without a definition (BA_DEF_), defined by their values: %s",
        source,
        ", ".join(missing),
    )
    first = re.search(r"^[ \t]*BA_(?:DEF_)?[ \t]", text, re.M)
    at = first.start() if first is not None else len(text)
    return text[:at] + "\n".join(definitions) + "\n" + text[at:]


#: cantools' refusal of a value table or float type naming a signal the DBC does not
#: have, one ``VAL_ <frame id> <signal>`` line each after the first.
_ORPHANS = re.compile(r"unused (?:VAL_|SIG_VALTYPE_) entries in DBC:")
_ORPHAN = re.compile(r"^\s*(VAL_|SIG_VALTYPE_) (\d+) (\w+)", re.M)


def _load(text: str, source: str, strict: bool) -> object:
    """cantools' :func:`~cantools.database.load_string`, leaving out, with one warning,
    the value tables (``VAL_``) and float types (``SIG_VALTYPE_``) of signals the DBC
    does not have: cantools refuses the whole DBC for one (a table left behind when a
    signal was deleted or renamed by hand), which says nothing about the rest."""
    while True:
        try:
            return cantools.database.load_string(text, database_format="dbc", strict=strict)
        except (UnsupportedDatabaseFormatError, ValueError) as exc:
            orphans = _ORPHAN.findall(str(exc)) if _ORPHANS.search(str(exc)) else []
            left = text
            for kind, frame_id, signal in orphans:
                statement = rf"^[ \t]*{kind}[ \t]+{frame_id}[ \t]+{signal}\b[^;]*;"
                left = re.sub(statement, "", left, flags=re.M)
            if left == text:  # no such entries, or not found as written: never loop
                raise
            logger.warning(
                "%s: left out, naming no signal of the DBC: %s",
                source,
                ", ".join(" ".join(orphan) for orphan in orphans),
            )
            text = left


#: The most bytes a CAN frame carries (CAN FD).
CAN_FD_MAX_BYTES = 64


#: The lengths of an IEEE float signal (``SIG_VALTYPE_``) cantools decodes: half, single
#: and double precision.
FLOAT_BITS = (16, 32, 64)


def undecodable(message: Message) -> str | None:
    """Why no frame on the bus can be ``message``, which cantools' checks take: longer
    than a CAN FD frame (every frame was ``wrong_dlc``), or an IEEE float signal of
    another length than 16, 32 or 64 bits (a ``SIG_VALTYPE_`` on the wrong signal:
    cantools cannot unpack it, and every frame of the message was ``decode_error``);
    None where it can be decoded."""
    if message.length > CAN_FD_MAX_BYTES:
        return (
            f"{message.name} is {message.length} bytes long: a CAN frame carries "
            f"{CAN_FD_MAX_BYTES} at most (CAN FD)"
        )
    for signal in message.signals:
        if signal.is_float and signal.length not in FLOAT_BITS:
            return (
                f"{message.name}.{signal.name} is an IEEE float by its SIG_VALTYPE_ but "
                f"{signal.length} bits long (a float is 16, 32 or 64): no frame of "
                f"{message.name} can be decoded (remove the SIG_VALTYPE_ or fix the length)"
            )
    return None


def _warn_undecodable(database: Database, source: str) -> None:
    """One warning line naming the messages no frame can be (:func:`undecodable`) in a
    DBC that cantools' checks take: the config refuses one it uses (:func:`unsound`)."""
    problems = [problem for problem in map(undecodable, database.messages) if problem]
    if problems:
        logger.warning("%s: %s", source, "; ".join(problems))


def unsound(message: Message) -> str | None:
    """Why cantools' checks refuse ``message`` (signals that overlap, or do not fit in
    its length; two of one name, which cantools tells as overlapping), or why no frame
    can be it (:func:`undecodable`); None where they pass."""
    problem = undecodable(message)
    if problem is not None:
        return problem
    names = [signal.name for signal in message.signals]
    twice = next((name for name in names if names.count(name) > 1), None)
    if twice is not None:  # cantools says they overlap, wherever they are
        starts = ", ".join(str(signal.start) for signal in message.signals if signal.name == twice)
        return f"{message.name} has two signals named {twice} (start bits {starts}): rename one"
    try:
        message.refresh(strict=True)
    except CantoolsError as exc:
        return str(exc)
    return None


def load_database_bytes(data: bytes, source: str) -> Database:
    """Load a DBC from the bytes of its file (the file itself, or the copy embedded in a
    recording): in the encoding its byte-order mark declares, else as UTF-8 where it is
    UTF-8 (an editor's default: read as :data:`DBC_ENCODING`, a unit ``bar(ü)`` was
    ``bar(Ã¼)``, ``°`` was ``Â°``), else :data:`DBC_ENCODING`. Text in Windows-1252 with
    any letter beyond ASCII is practically never valid UTF-8 (``°C`` is ``B0 43``)."""
    encoding = next((enc for bom, enc in _BOM_ENCODINGS if data.startswith(bom)), None)
    if encoding is not None:
        text = data.decode(encoding, errors="replace")
    else:
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            text = data.decode(DBC_ENCODING, errors="replace")
    return load_database_string(text, source)


#: cantools' words for a 29-bit ID written without the DBC's extended-ID flag (bit 31).
_NO_EXTENDED_FLAG = re.compile(r"Standard frame id (0x[0-9a-fA-F]+) is more than 11 bits")


#: cantools' words for a statement it could not read from the start of a line: the
#: one before it did not end (a ``VAL_`` or ``BA_`` without its ``;``, by hand).
_AT_A_LINES_START = re.compile(r"Invalid syntax at line (\d+), column 1:")
#: cantools' words for where it could not read on.
_AT_LINE = re.compile(r"Invalid syntax at line (\d+), column \d+:")


#: The statements in which a '"' opens a name, unit or value that closes on the same
#: line (a comment, ``CM_``, may span lines).
_ONE_LINE_STATEMENT = re.compile(r"[ \t]*(?:BO_|SG_|BA_|BA_DEF_|BA_DEF_DEF_|VAL_|VAL_TABLE_)[ \t]")
#: An attribute's definition with its type: ``BA_DEF_ BO_ "GenMsgSendType" ENUM "Cyclic",...;``.
_DEFINED_TYPE = re.compile(
    r'^[ \t]*BA_DEF_[ \t]+(?:(?:BU_|BO_|SG_|EV_)[ \t]+)?"(?P<name>[^"]*)"[ \t]+'
    r"(?P<type>INT|HEX|FLOAT|ENUM)\b(?P<values>[^;]*);",
    re.M,
)


def _hint(reason: str, text: str) -> str:
    """What to change where cantools' ``reason`` alone does not say it (``text``: the
    DBC's)."""
    line = _AT_LINE.search(reason)
    if line is not None:
        before = text.splitlines()[: int(line[1])]
        unclosed = next(
            (
                number
                for number, statement in enumerate(before, 1)
                if _ONE_LINE_STATEMENT.match(statement) and statement.count('"') % 2
            ),
            None,
        )
        if unclosed is not None:
            return f" (line {unclosed} opens a '\"' it does not close)"
    if "ConversionSyntax" in reason:
        return _string_for_a_number(text)
    start = _AT_A_LINES_START.search(reason)
    if start is not None and int(start[1]) > 1:
        return f" (does the statement before line {start[1]} end with its ';'?)"
    match = _NO_EXTENDED_FLAG.search(reason)
    if match is None:
        return ""
    frame_id = int(match[1], 16)
    return (
        f" (a 29-bit ID is written with bit 31 set in a DBC: BO_ {frame_id | 0x80000000}, "
        f"not BO_ {frame_id})"
    )


def _string_for_a_number(text: str) -> str:
    """Where cantools' reason is ``decimal.ConversionSyntax`` alone: the first value given
    in quotes to an attribute defined as a number or an enumeration, and what to write."""
    types = {match["name"]: match for match in _DEFINED_TYPE.finditer(text)}
    for match in _ASSIGNED.finditer(text):
        definition = types.get(match["name"])
        value = match["value"]
        if definition is None or not value.startswith('"') or _is_number(value[1:-1]):
            continue  # cantools reads a number in quotes ("20")
        number = text.count("\n", 0, match.start()) + 1
        statement = match[0].strip()
        if definition["type"] != "ENUM":
            return (
                f" (line {number}: {statement} gives a string to the {definition['type']} "
                "attribute: write a number)"
            )
        names = re.findall(r'"([^"]*)"', definition["values"])
        index = names.index(value[1:-1]) if value[1:-1] in names else None
        which = f", {index} for {value}" if index is not None else f"; {value} is none of them"
        return (
            f" (line {number}: {statement} gives a string to the ENUM attribute: write "
            f"its value's index{which})"
        )
    return ""


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]
