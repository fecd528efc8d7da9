"""Offline replay: a recording through the same decoder and estimator, out to CSV.

Sources:

- the service's MCAP files: the ``/can/raw`` channel (every frame, bad ones
  included) and ``/daq/bus`` (gaps that reset the rolling counters), in file
  order, which is the order the live pipeline processed them. The machine
  configuration and DBC come from the file's attachments unless a config file
  is given. A file cut short by a crash replays up to its last complete chunk.
- python-can logs (candump ``.log``, ``.asc``, ``.blf``, ... via
  ``can.LogReader``): need ``--config``.

The frames go through a fresh :class:`~daq.pipeline.Pipeline`, so the
estimates equal the live ones of the same recording bit for bit.
"""

import csv
import json
import logging
import tomllib
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO

import can
from cantools.database.can import Database

from daq.errors import RecordingError
from daq.frames import BusEvent, RawFrame, from_can_message
from daq.mcap_file import BUS_TOPIC, CONFIG_ATTACHMENT, DBC_ATTACHMENT, RAW_TOPIC
from daq.mcap_reading import RecordedAttachment, RecordedMessage, RecordingStream
from daq.pipeline import Pipeline
from dbc.database import load_database_string
from dbc.errors import ConfigError
from dbc.machine import MachineConfig, load_machine_config, parse_machine_config
from estimator.leg import LegEstimate

logger = logging.getLogger(__name__)

CSV_COLUMNS = (
    "leg",
    "t",
    "force_N",
    "force_raw_N",
    "pressure_Pa",
    "p_piston_Pa",
    "p_rod_Pa",
    "contact",
    "valid",
    "reasons",
)

Machine = tuple[MachineConfig, Database]


def estimates(pipeline: Pipeline, items: Iterable[RawFrame | BusEvent]) -> Iterator[LegEstimate]:
    """Every leg estimate the frames give, in order; bus gaps reset the counters."""
    for item in items:
        if isinstance(item, BusEvent):
            if item.reset_counters:
                pipeline.reset_counters()
            continue
        yield from pipeline.process(item).estimates


def write_csv(rows: Iterable[LegEstimate], out: IO[str]) -> int:
    """One CSV row per estimate (floats in full precision, ``reasons`` joined by ``|``)."""
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    count = 0
    for e in rows:
        writer.writerow(
            (
                e.leg,
                repr(e.t_s),
                repr(e.force_N),
                repr(e.force_raw_N),
                repr(e.pressure_Pa),
                repr(e.p_piston_Pa),
                repr(e.p_rod_Pa),
                int(e.contact),
                int(e.valid),
                "|".join(e.reasons),
            )
        )
        count += 1
    return count


def replay(path: Path, out: IO[str], config_path: Path | None = None) -> int:
    """Replay ``path`` (MCAP or a python-can log) into CSV on ``out``; returns the row count."""
    machine = load_machine_config(config_path) if config_path is not None else None
    if path.suffix.lower() == ".mcap":
        with _open(path) as stream:
            return write_csv(_mcap_estimates(stream, path, machine), out)
    if machine is None:
        raise ConfigError(path, "", "replaying a CAN log needs --config (the machine config)")
    pipeline = Pipeline.from_config(*machine)
    return write_csv(estimates(pipeline, can_log_frames(path)), out)


def can_log_frames(path: Path) -> Iterator[RawFrame]:
    """The frames of a python-can log (candump .log, .asc, .blf, .csv, ...)."""
    try:
        reader = can.LogReader(str(path))
    except (OSError, ValueError) as exc:
        raise RecordingError(path, f"cannot read it as a CAN log: {exc}") from exc
    with reader:
        for message in reader:
            yield from_can_message(message)


def _open(path: Path) -> IO[bytes]:
    try:
        return open(path, "rb")
    except OSError as exc:
        raise RecordingError(path, f"cannot open it: {exc.strerror or exc}") from exc


def _mcap_estimates(
    stream: IO[bytes], path: Path, machine: Machine | None
) -> Iterator[LegEstimate]:
    recording = RecordingStream(stream, str(path))
    attachments: dict[str, bytes] = {}
    pipeline: Pipeline | None = None
    for record in recording:
        if isinstance(record, RecordedAttachment):
            attachments[record.name] = record.data
            continue
        if pipeline is None:
            pipeline = Pipeline.from_config(*(machine or _embedded_machine(attachments, path)))
        item = _item(record)
        if item is not None:
            yield from estimates(pipeline, (item,))


def _item(record: RecordedMessage) -> RawFrame | BusEvent | None:
    if record.topic == RAW_TOPIC:
        raw = json.loads(record.data)
        return RawFrame(
            t_s=raw["t"],
            arbitration_id=raw["id"],
            is_extended_id=raw["extended"],
            data=bytes.fromhex(raw["data"]),
            is_error_frame=raw["error_frame"],
            is_remote_frame=raw["remote_frame"],
            is_fd=raw.get("fd", False),  # recordings made before CAN FD lack it
        )
    if record.topic == BUS_TOPIC:
        event = json.loads(record.data)
        return BusEvent(event["t"], event["state"], event["reason"], event["reset_counters"])
    return None


def _embedded_machine(attachments: dict[str, bytes], path: Path) -> Machine:
    if CONFIG_ATTACHMENT not in attachments or DBC_ATTACHMENT not in attachments:
        raise ConfigError(path, "", "no configuration in the recording; give --config")
    source = f"{path}:{CONFIG_ATTACHMENT}"
    try:
        data = tomllib.loads(attachments[CONFIG_ATTACHMENT].decode())
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(source, "", f"not valid TOML: {exc}") from exc
    database = load_database_string(
        attachments[DBC_ATTACHMENT].decode(), f"{path}:{DBC_ATTACHMENT}"
    )
    return parse_machine_config(data, source, database), database
