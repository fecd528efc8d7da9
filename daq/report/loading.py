"""Reading a service recording (MCAP) for the report: the file-touching edge.

The messages are read in file order with :class:`~daq.mcap_reading.RecordingStream`
(so a file cut short by a crash reads up to its last complete chunk) and handed to
the pure :class:`~daq.report.tracks.RecordingCollector`. A recording rotated into
several files is given as its files or their directory; the files of one run are
read in the order of the run (:mod:`daq.recording_run`).

A file that is not MCAP, or a recording that holds neither CAN frames nor leg estimates
(e.g. only the simulator's truth), has nothing to report:
:class:`~daq.errors.RecordingError`.

The machine configuration comes from ``config_path`` when given, else from the first
file's embedded attachments; without either, the report still draws what was recorded (with
the estimator's default settings). A recording without leg estimates but with
``/can/raw`` is replayed through :mod:`daq.replay`'s pipeline, which gives the
estimates the live service would have recorded, bit for bit. So is a recording whose
``/can/raw`` holds batches (:mod:`daq.can_batch`): they store the frames only, and the
signals (machine state, message counts) and bad frames come from the replay, unless
signals were recorded (``[recording] signals = true``).

CAN logs of other tools (candump ``.log``, ``.asc``, ``.blf``, ...: anything not
``.mcap``) need ``config_path``: their frames are chained as replay chains them
(:func:`daq.replay.chained_log_frames`) and everything is derived from them.
"""

import logging
import re
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import IO

from daq.can_batch import ENCODING as BATCH_ENCODING
from daq.can_batch import recorded_frames
from daq.errors import EmptyRecordingError, RecordingError
from daq.mcap_file import RAW_TOPIC
from daq.mcap_reading import RecordedAttachment, RecordedMessage, RecordingStream
from daq.pipeline import UNMAPPED_SOURCE, Pipeline
from daq.recording_run import expand, run_files
from daq.replay import (
    Machine,
    embedded_machine,
    is_can_log,
    no_channel_of_recordings,
    of_one_kind,
    recording_results,
    run_results,
)
from daq.report.tracks import Recording, RecordingCollector, StateSignals
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


def load_recording(
    paths: Path | Sequence[Path], config_path: Path | None = None, channel: str | None = None
) -> Recording:
    """Read a recording (a file, or the files or directory of one run) into a
    :class:`Recording`; of CAN logs, only ``channel``'s frames when it is given.

    Raises :class:`~daq.errors.RecordingError` (unreadable, several runs), or
    :class:`~daq.errors.ConfigError` / :class:`~daq.errors.DbcError` (a bad
    ``config_path``, or estimates to recompute without any configuration).
    """
    given = [paths] if isinstance(paths, Path) else paths
    logs = expand(given)
    of_one_kind(logs)
    if any(is_can_log(path) for path in logs):
        return _log_recording(logs, config_path, channel)
    no_channel_of_recordings(channel)
    files = run_files(given)
    first = files[0]
    machine: Machine | None = load_machine_config(config_path) if config_path else None
    collector = RecordingCollector(StateSignals.of(machine[0] if machine else None))
    attachments: dict[str, bytes] = {}
    embedded = False
    complete = True
    batches = False
    for path in files:
        with _open(path) as stream:
            reader = RecordingStream(stream, str(path))
            for record in reader:
                if isinstance(record, RecordedAttachment):
                    attachments.setdefault(record.name, record.data)  # the first file's
                    continue
                if not isinstance(record, RecordedMessage):
                    continue
                if machine is None and attachments and not embedded:
                    # The recorder writes its config before the messages: where the
                    # machine state is, before the first of them.
                    embedded = True
                    machine = _embedded(attachments, first)
                    collector.state_signals = StateSignals.of(machine[0] if machine else None)
                if record.topic == RAW_TOPIC and record.encoding == BATCH_ENCODING:
                    batches = True
                    try:
                        collector.add_frames(recorded_frames(record.encoding, record.data))
                    except ValueError as exc:
                        raise RecordingError(
                            path, f"a {RAW_TOPIC} batch is unreadable: {exc}"
                        ) from exc
                else:
                    collector.add(record.topic, record.data)
        complete = complete and reader.complete
    if collector.frames == 0 and not collector.has_estimates:
        truth = f" ({collector.truth_samples} simulation truth samples only)"
        raise EmptyRecordingError(
            first if len(files) == 1 else first.parent,
            "holds no CAN frames (/can/raw) and no leg estimates: nothing to report"
            + (truth if collector.truth_samples else ""),
        )
    if machine is None and attachments and not embedded:
        machine = _embedded(attachments, first)
    recomputed = not collector.has_estimates and collector.frames > 0
    derive_signals = batches and not collector.has_signals
    if recomputed or batches:
        if machine is None:
            what = "leg estimates recorded; recomputing" if recomputed else "signals; deriving"
            raise ConfigError(first, "", f"no {what} them needs --config")
        logger.info("%s: deriving what was not recorded from /can/raw", first)
        pipeline = Pipeline.from_config(*machine)
        # The files were read above, and what was cut or damaged said so there.
        for result in run_results(files, machine, pipeline, warn=False):
            collector.derive(result, bad=batches, signals=derive_signals, estimates=recomputed)
        if batches:
            collector.count_bad(UNMAPPED_SOURCE, pipeline.bad[UNMAPPED_SOURCE])
    config: MachineConfig | None = machine[0] if machine is not None else None
    machine_id = config.machine_id if config else machine_id_from_name(first) or first.stem
    return collector.recording(
        recording_name(files),
        config,
        machine_id=machine_id,
        recomputed=recomputed,
        complete=complete,
    )


def _embedded(attachments: dict[str, bytes], path: Path) -> Machine | None:
    """The configuration embedded in the recording ``path``; None (and a warning line)
    where it is unusable."""
    try:
        return embedded_machine(attachments, path)
    except (ConfigError, DbcError) as exc:
        logger.warning("the configuration embedded in %s is unusable: %s", path, exc)
        return None


def _log_recording(
    files: Sequence[Path], config_path: Path | None, channel: str | None
) -> Recording:
    """CAN logs of other tools (candump, ASC, BLF, ...), chained as replay chains them,
    through the pipeline of ``config_path``: everything derived from their frames."""
    if config_path is None:
        raise ConfigError(files[0], "", "reporting a CAN log needs --config (the machine config)")
    machine = load_machine_config(config_path)
    config = machine[0]
    collector = RecordingCollector(StateSignals.of(config))
    pipeline = Pipeline.from_config(*machine)
    lost: Counter[str] = Counter()
    for result in recording_results(files, machine, pipeline, channel, lost):
        collector.add_frames((result.frame,))
        collector.derive(result, bad=True, signals=True, estimates=True)
    collector.count_bad(UNMAPPED_SOURCE, pipeline.bad[UNMAPPED_SOURCE])
    collector.count_lost(lost)
    if collector.frames == 0:
        raise EmptyRecordingError(files[0], "holds no CAN frames: nothing to report")
    return collector.recording(
        recording_name(files), config, machine_id=config.machine_id, recomputed=True
    )


def recording_name(files: Sequence[Path], base: Path | None = None) -> str:
    """The name a report gives the files of one run: the first file's name (its path from
    ``base``, when given), and the last's for a rotated run.

    >>> recording_name([Path("/d/day1/a_1.mcap"), Path("/d/day1/a_2.mcap")], Path("/d"))
    'day1/a_1.mcap .. a_2.mcap (2 files)'
    """
    first = files[0]
    name = first.name if base is None else str(first.relative_to(base))
    return name if len(files) == 1 else f"{name} .. {files[-1].name} ({len(files)} files)"
