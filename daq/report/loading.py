"""Reading a service recording (MCAP) for the report: the file-touching edge.

The messages are read in file order with :class:`~daq.mcap_reading.RecordingStream`
(so a file cut short by a crash reads up to its last complete chunk) and handed to
the pure :class:`~daq.report.tracks.RecordingCollector`.

The machine configuration comes from ``config_path`` when given, else from the file's
embedded attachments; without either, the report still draws what was recorded (with
the estimator's default settings). A recording without leg estimates but with
``/can/raw`` is replayed through :mod:`daq.replay`'s pipeline, which gives the
estimates the live service would have recorded, bit for bit. So is a recording whose
``/can/raw`` holds batches (:mod:`daq.can_batch`): they store the frames only, and the
signals (machine state, message counts) and bad frames come from the replay, unless
signals were recorded (``[recording] signals = true``).
"""

import logging
import re
from pathlib import Path
from typing import IO

from daq.can_batch import ENCODING as BATCH_ENCODING
from daq.can_batch import recorded_frames
from daq.errors import RecordingError
from daq.mcap_file import RAW_TOPIC
from daq.mcap_reading import RecordedAttachment, RecordingStream
from daq.replay import Machine, _embedded_machine, mcap_results
from daq.report.tracks import Recording, RecordingCollector
from dbc.errors import ConfigError, DbcError
from dbc.machine import MachineConfig, load_machine_config

logger = logging.getLogger(__name__)

#: ``<machine>_<UTC stamp>[_n].mcap``, as :func:`daq.recorder.file_name` names files.
_FILE_NAME = re.compile(r"(?P<machine>.+)_\d{8}T\d{6}\.\d{3}Z(_\d+)?$")


def machine_id_from_name(path: Path) -> str | None:
    """The machine id in a recorder file name, if it is one.

    >>> machine_id_from_name(Path("rec/pam-1_20250101T120000.000Z.mcap"))
    'pam-1'
    """
    match = _FILE_NAME.match(path.stem)
    return match.group("machine") if match else None


def _open(path: Path) -> IO[bytes]:
    try:
        return open(path, "rb")
    except OSError as exc:
        raise RecordingError(path, f"cannot open it: {exc.strerror or exc}") from exc


def load_recording(path: Path, config_path: Path | None = None) -> Recording:
    """Read ``path`` into a :class:`Recording`.

    Raises :class:`~daq.errors.RecordingError` (unreadable), or
    :class:`~daq.errors.ConfigError` / :class:`~daq.errors.DbcError` (a bad
    ``config_path``, or estimates to recompute without any configuration).
    """
    machine: Machine | None = load_machine_config(config_path) if config_path else None
    collector = RecordingCollector()
    attachments: dict[str, bytes] = {}
    batches = False
    with _open(path) as stream:
        reader = RecordingStream(stream, str(path))
        for record in reader:
            if isinstance(record, RecordedAttachment):
                attachments[record.name] = record.data
            elif record.topic == RAW_TOPIC and record.encoding == BATCH_ENCODING:
                batches = True
                try:
                    collector.add_frames(recorded_frames(record.encoding, record.data))
                except ValueError as exc:
                    raise RecordingError(path, f"a {RAW_TOPIC} batch is unreadable: {exc}") from exc
            else:
                collector.add(record.topic, record.data)
    if collector.frames == 0 and not collector.has_estimates and not attachments:
        logger.warning("%s holds no frames and no estimates of the service", path)
    if machine is None and attachments:
        try:
            machine = _embedded_machine(attachments, path)
        except (ConfigError, DbcError) as exc:
            logger.warning("the configuration embedded in %s is unusable: %s", path, exc)
    recomputed = not collector.has_estimates and collector.frames > 0
    derive_signals = batches and not collector.has_signals
    if recomputed or batches:
        if machine is None:
            what = "leg estimates recorded; recomputing" if recomputed else "signals; deriving"
            raise ConfigError(path, "", f"no {what} them needs --config")
        logger.info("%s: deriving what was not recorded from /can/raw", path)
        with _open(path) as stream:
            for result in mcap_results(stream, path, machine):
                collector.derive(result, bad=batches, signals=derive_signals, estimates=recomputed)
    config: MachineConfig | None = machine[0] if machine is not None else None
    machine_id = config.machine_id if config else machine_id_from_name(path) or path.stem
    return collector.recording(
        path.name,
        config,
        machine_id=machine_id,
        recomputed=recomputed,
        complete=reader.complete,
    )
