"""The service configuration: bus, Zenoh, publishing and recording, next to the machine's.

One TOML file holds both parts (example: ``deploy/portal-daq.example.toml``): the
machine tables read by :mod:`dbc.machine` and the service tables ``[service]``,
``[bus]``, ``[zenoh]``, ``[publish]`` and ``[recording]`` read here. Every service table is
optional; left-out keys take the defaults of the dataclasses below. Relative
paths are relative to the config file. Unknown keys are refused like in the
machine part, naming file and key.

>>> config = load_service_config("deploy/portal-daq.example.toml")  # doctest: +SKIP
>>> config.zenoh.key_prefix, config.bus.channel  # doctest: +SKIP
('portal/pam-proto-1', 'can0')
"""

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, TypeVar

import can
from cantools.database.can import Database

from dbc.machine import MachineConfig, machine_from_toml, read_toml
from dbc.toml_table import TomlTable
from dbc.zenoh_config import not_a_file

#: What Zenoh keys reserve (wildcards ``*``, ``$*``; ``?`` and ``#``, forbidden).
KEY_RESERVED = "*$?#"
ZENOH_MODES = ("peer", "client", "router")
COMPRESSIONS = ("zstd", "lz4", "none")


@dataclass(frozen=True, slots=True)
class ServiceSettings:
    """``[service]``: how the service's work is spread over threads."""

    #: One thread (an event loop) receives, processes and publishes; the recorder has
    #: its own. False: the reader and the publisher each get a thread too, handing
    #: frames and messages on through queues (four threads). The event loop takes less
    #: CPU, most of all at low frame rates where every hand-off wakes a thread (bench/).
    event_loop: bool = True
    #: After a wake-up that took frames, the consumer takes nothing more from the bus
    #: (or the reader's queue) for this long: what arrives meanwhile waits in the
    #: kernel's receive buffer and is processed in one go. Fewer, larger wake-ups cost
    #: less CPU at low frame rates, at the price of up to this much latency; timers
    #: (``/ground``, metrics, the recorder's hand-over) still run on time. 0: every
    #: wake-up is processed at once. At most :data:`POLL_PERIOD_MAX_MS`.
    poll_period_ms: float = 0.0

    @property
    def poll_period_s(self) -> float:
        return self.poll_period_ms / 1000.0


@dataclass(frozen=True, slots=True)
class BusSettings:
    """``[bus]``: the CAN interface, opened with python-can."""

    #: python-can interface name: ``socketcan`` on the machine, ``virtual`` in tests.
    interface: str = "socketcan"
    channel: str = "can0"
    receive_own_messages: bool = False
    #: Install kernel receive filters for the DBC's IDs. Off by default: then every
    #: frame reaches the service, and frames with other IDs are counted
    #: (``unknown_id``) and recorded raw; on, the kernel drops them unseen.
    kernel_filters: bool = False
    #: Frames the reader thread may queue for the consumer; beyond, frames are dropped
    #: and counted (``dropped``).
    queue_size: int = 10_000
    #: Kernel receive buffer of the SocketCAN socket: ~10,000 frames (Linux grants twice
    #: the request, and a CAN frame takes ~800 bytes of it: 768 measured on vcan0), a
    #: second of a saturated bus, so a burst, a stall or a poll period loses nothing.
    #: Forced past ``net.core.rmem_max`` when the service may (CAP_NET_ADMIN); a smaller
    #: buffer granted is warned about once and shown on ``/status`` (``bus.rcvbuf_bytes``).
    receive_buffer_bytes: int = 4 * 1024 * 1024


@dataclass(frozen=True, slots=True)
class ZenohSettings:
    """``[zenoh]``: the session; the explicit keys override the JSON5 file's."""

    #: A Zenoh JSON5 configuration file (e.g. ``deploy/zenoh.json5``); None: defaults.
    config_file: Path | None = None
    #: ``peer``, ``client`` or ``router``; None keeps the file's (or Zenoh's) choice.
    mode: str | None = None
    #: Endpoints to connect to, e.g. ``tcp/192.168.1.10:7447``.
    connect: tuple[str, ...] = ()
    #: Endpoints to listen on, e.g. ``tcp/0.0.0.0:7447``.
    listen: tuple[str, ...] = ()
    #: UDP multicast scouting; None keeps the file's (or Zenoh's) choice.
    multicast_scouting: bool | None = None
    #: Every key the service publishes starts with this.
    key_prefix: str = "portal/machine"


@dataclass(frozen=True, slots=True)
class PublishSettings:
    """``[publish]``: what goes out on Zenoh, and how often."""

    #: Rate of the all-legs ``<prefix>/ground`` message (:data:`GROUND_RATE_MAX_HZ` at most).
    ground_rate_hz: float = 10.0
    #: Publish decoded messages on ``<prefix>/signals/<MESSAGE>``.
    signals: bool = True
    #: ... each message at most this often (by frame time); 0: every frame. 10 Hz is
    #: what a dashboard or monitor shows (a screen refreshes no faster than a person
    #: reads; the leg estimates go out with every frame regardless); every frame of a
    #: saturated bus would cost the service about a third of its CPU (bench/).
    signals_max_rate_hz: float = 10.0
    #: Period of ``<prefix>/status``, ``<prefix>/metrics`` and systemd's STATUS=
    #: (:data:`STATUS_PERIOD_MIN_S` .. :data:`STATUS_PERIOD_MAX_S`).
    status_period_s: float = 1.0
    #: Messages waiting for the Zenoh thread; beyond, they are dropped and counted.
    queue_size: int = 10_000


@dataclass(frozen=True, slots=True)
class RecordingSettings:
    """``[recording]``: MCAP files; no ``directory``, no recording."""

    directory: Path | None = None
    #: A file is closed and the next one begun at this size ...
    max_bytes: int = 512 * 1024 * 1024
    #: ... or after this long (frame time).
    max_duration_s: float = 3600.0
    compression: str = "zstd"
    #: Uncompressed bytes per chunk. A crash loses at most the chunk being built.
    #: 128 KiB: finishing a chunk (index + compression) holds the GIL ~0.7 ms, against
    #: ~3.6 ms for 1 MiB, which set the p99 latency (bench/); files grow ~7 %.
    chunk_size: int = 128 * 1024
    #: The chunk being built is written out at least this often, so that a crash
    #: loses at most this much time of data.
    flush_period_s: float = 1.0
    #: Results waiting for the recorder thread; beyond, they are dropped and counted.
    queue_size: int = 20_000
    #: Also record the simulator bridge's ground truth (``<prefix>/sim/truth`` on
    #: Zenoh) on the ``/sim/truth`` channel, whenever a bridge publishes it. Off by
    #: default: on the machine nobody else may write into the recording.
    truth: bool = False
    #: Also record the decoded signals of every frame (``/signals/<MESSAGE>``, JSON).
    #: Off: they are derivable from ``/can/raw`` (replay and report do), and writing
    #: them costs about as much as everything else the recorder does (bench/).
    signals: bool = False
    #: Write the files in a process of its own (:mod:`daq.recorder_process`), off the
    #: GIL of the thread that processes frames: writing MCAP in a thread held it up to
    #: ~0.7 ms at a time, the tail of the frame -> subscriber latency (bench/).
    process: bool = True


@dataclass(frozen=True)
class ServiceConfig:
    """The whole configuration of the service: machine and service parts."""

    #: The file this was read from, for messages.
    source: str
    machine: MachineConfig
    database: Database
    service: ServiceSettings
    bus: BusSettings
    zenoh: ZenohSettings
    publish: PublishSettings
    recording: RecordingSettings


def load_service_config(path: str | Path) -> ServiceConfig:
    """Read and check the whole configuration file and the DBC it names.

    Raises :class:`~daq.errors.ConfigError` (file, key, reason) or
    :class:`~daq.errors.DbcError`.
    """
    source = str(path)
    data = read_toml(path)
    config_dir = Path(path).parent
    machine, database = machine_from_toml(data, source, config_dir)
    root = TomlTable(data, source)
    return ServiceConfig(
        source=source,
        machine=machine,
        database=database,
        service=_service(root.table("service", required=False)),
        bus=_bus(root.table("bus", required=False)),
        zenoh=_zenoh(root.table("zenoh", required=False), config_dir, machine.machine_id),
        publish=_publish(root.table("publish", required=False)),
        recording=_recording(root.table("recording", required=False), config_dir),
    )


def _keys(settings: type) -> list[str]:
    return [field.name for field in fields(settings)]


def _not_negative(table: TomlTable, name: str, default: float) -> float:
    value = table.number(name, default)
    if value < 0:
        raise table.error(name, f"must be >= 0, got {value}")
    return value


def _positive_int(table: TomlTable, name: str, default: int) -> int:
    value = table.integer(name, default)
    if value <= 0:
        raise table.error(name, f"must be > 0, got {value}")
    return value


N = TypeVar("N", int, float)


def _between(table: TomlTable, name: str, value: N, low: N, high: N, why: str = "") -> N:
    """``value`` of ``name``, checked to be ``low`` .. ``high``; ``why`` ends the refusal."""
    if not low <= value <= high:
        raise table.error(
            name, f"must be between {_shown(low)} and {_shown(high)}, got {_shown(value)}{why}"
        )
    return value


def _at_least(table: TomlTable, name: str, default: float, low: float, why: str) -> float:
    """The number ``name``, at least ``low``; ``why`` ends the refusal."""
    value = table.number(name, default)
    if not value >= low:
        raise table.error(name, f"must be at least {low:g}, got {value:g}{why}")
    return value


def _shown(value: float) -> str:
    return str(value) if isinstance(value, int) else f"{value:g}"


#: Bounds of ``[publish] ground_rate_hz``: at 1,000 Hz the event loop took a third of a
#: core taking snapshots with no frame coming in, at 1e6 a whole core, and the recorder's
#: and publisher's queues overflowed; the DBC's legs send every 10 ms, so a faster
#: ``/ground`` repeats their estimates. At least one every 100 s.
GROUND_RATE_MIN_HZ, GROUND_RATE_MAX_HZ = 0.01, 100.0
#: Bounds of ``[publish] status_period_s``: a status is built of every counter; at 1e-300
#: the service built nothing else (a third of a core, no frame coming in), at 1e300 the
#: wait for it was an OverflowError traceback. An hour at most: "no frame" is judged
#: once a period, and the viewers call a status stale after three.
STATUS_PERIOD_MIN_S, STATUS_PERIOD_MAX_S = 0.01, 3600.0
#: Shortest ``[recording] flush_period_s``: the recorder's thread waits for items at most
#: this long; at 1e-300 it spun (all of a core), writing out a chunk each time.
FLUSH_PERIOD_MIN_S = 0.01
#: Shortest ``[recording] max_duration_s``: below a second a file is begun at nearly every
#: hand-over (ten a second).
MAX_DURATION_MIN_S = 1.0
#: Largest ``queue_size`` of ``[bus]``, ``[publish]`` and ``[recording]``: what bounds the
#: memory a stall takes (a million frames are ~2 minutes of a saturated bus); the
#: recorder's process queue takes at most 2**31 - 1 (a larger one was an OverflowError
#: traceback at start).
QUEUE_SIZE_MAX = 1_000_000


def _queue_size(table: TomlTable, default: int) -> int:
    return _between(table, "queue_size", table.integer("queue_size", default), 1, QUEUE_SIZE_MAX)


def _choice(table: TomlTable, name: str, choices: tuple[str, ...], default: Any) -> Any:
    if name not in table and default is None:
        return None
    value = table.string(name, default)
    if value not in choices:
        raise table.error(name, f"must be one of {list(choices)}, got {value!r}")
    return value


#: Longest ``[service] poll_period_ms``: frames held longer would near the consumer's
#: lag tolerance (0.5 s, :data:`daq.consumer.LAG_TOLERANCE_S`), past which fresh legs
#: look stale on ``/ground``; and a saturated bus's 9,000 frames/s stay well under a
#: wake-up's 4,096 frames (:data:`daq.can_batch.MAX_FRAMES`).
POLL_PERIOD_MAX_MS = 250.0


def _service(table: TomlTable) -> ServiceSettings:
    defaults = ServiceSettings()
    table.reject_unknown(_keys(ServiceSettings))
    return ServiceSettings(
        event_loop=table.boolean("event_loop", defaults.event_loop),
        poll_period_ms=_between(
            table,
            "poll_period_ms",
            table.number("poll_period_ms", defaults.poll_period_ms),
            0.0,
            POLL_PERIOD_MAX_MS,
        ),
    )


def _bus(table: TomlTable) -> BusSettings:
    defaults = BusSettings()
    table.reject_unknown(_keys(BusSettings))
    interface = table.string("interface", defaults.interface)
    if interface not in can.VALID_INTERFACES:
        raise table.error(
            "interface", f"unknown python-can interface {interface!r}; e.g. socketcan, virtual"
        )
    return BusSettings(
        interface=interface,
        channel=table.string("channel", defaults.channel),
        receive_own_messages=table.boolean("receive_own_messages", False),
        kernel_filters=table.boolean("kernel_filters", False),
        queue_size=_queue_size(table, defaults.queue_size),
        receive_buffer_bytes=_receive_buffer(table, defaults.receive_buffer_bytes),
    )


#: Bounds of ``[bus] receive_buffer_bytes``: a few frames, and what setsockopt takes.
RECEIVE_BUFFER_MIN_BYTES = 1024
RECEIVE_BUFFER_MAX_BYTES = 1024 * 1024 * 1024


def _receive_buffer(table: TomlTable, default: int) -> int:
    value = table.integer("receive_buffer_bytes", default)
    return _between(
        table, "receive_buffer_bytes", value, RECEIVE_BUFFER_MIN_BYTES, RECEIVE_BUFFER_MAX_BYTES
    )


def _zenoh(table: TomlTable, config_dir: Path, machine_id: str) -> ZenohSettings:
    table.reject_unknown(_keys(ZenohSettings))
    config_file = None
    if "config_file" in table:
        config_file = table.file("config_file", config_dir)
        reason = not_a_file(config_file)
        if reason is not None:
            raise table.error("config_file", f"{reason}: {config_file}")
    multicast = table.boolean("multicast_scouting") if "multicast_scouting" in table else None
    return ZenohSettings(
        config_file=config_file,
        mode=_choice(table, "mode", ZENOH_MODES, None),
        connect=table.strings("connect", ()),
        listen=table.strings("listen", ()),
        multicast_scouting=multicast,
        key_prefix=_key_prefix(table, f"portal/{machine_id}"),
    )


def _key_prefix(table: TomlTable, default: str) -> str:
    prefix = table.string("key_prefix", default)
    problem = key_prefix_problem(prefix)
    if problem is not None:
        raise table.error("key_prefix", f"{prefix!r} {problem}")
    return prefix


def key_prefix_problem(prefix: str) -> str | None:
    """Why ``prefix`` cannot start a service's keys (``[zenoh] key_prefix``, a fleet
    view's ``--root``); None when it can: a Zenoh key without wildcards, its chunks
    joined by ``/``.

    A chunk that starts with ``@`` is one of Zenoh's verbatim chunks, which no wildcard
    matches: the access control's ``portal/**`` let puts under ``portal/@m1`` pass,
    and the fleet views' ``portal/*`` never found it.

    >>> key_prefix_problem("portal/pam-1") is None
    True
    >>> key_prefix_problem("portal/*")
    "has '*' (wildcards, '?', '#' and spaces are no part of a key prefix)"
    >>> key_prefix_problem("portal/")
    'has an empty chunk (a leading, trailing or double /)'
    >>> key_prefix_problem("portal/@m1")[:48]
    "has the chunk '@m1', which starts with '@': Zeno"
    """
    for chunk in prefix.split("/"):
        if not chunk:
            return "has an empty chunk (a leading, trailing or double /)"
        reserved = [c for c in chunk if c in KEY_RESERVED or c.isspace()]
        if reserved:
            reason = "wildcards, '?', '#' and spaces are no part of a key prefix"
            return f"has {reserved[0]!r} ({reason})"
        if chunk.startswith("@"):
            return (
                f"has the chunk {chunk!r}, which starts with '@': Zenoh's verbatim chunks "
                "are matched by no wildcard (the access control's portal/** nor the fleet "
                "views' portal/*)"
            )
    return None


def _publish(table: TomlTable) -> PublishSettings:
    defaults = PublishSettings()
    table.reject_unknown(_keys(PublishSettings))
    return PublishSettings(
        ground_rate_hz=_between(
            table,
            "ground_rate_hz",
            table.number("ground_rate_hz", defaults.ground_rate_hz),
            GROUND_RATE_MIN_HZ,
            GROUND_RATE_MAX_HZ,
            " (the legs' estimates go out with every frame; /ground is their summary)",
        ),
        signals=table.boolean("signals", defaults.signals),
        signals_max_rate_hz=_not_negative(
            table, "signals_max_rate_hz", defaults.signals_max_rate_hz
        ),
        status_period_s=_between(
            table,
            "status_period_s",
            table.number("status_period_s", defaults.status_period_s),
            STATUS_PERIOD_MIN_S,
            STATUS_PERIOD_MAX_S,
        ),
        queue_size=_queue_size(table, defaults.queue_size),
    )


def _recording(table: TomlTable, config_dir: Path) -> RecordingSettings:
    defaults = RecordingSettings()
    table.reject_unknown(_keys(RecordingSettings))
    directory = table.file("directory", config_dir) if "directory" in table else None
    if directory is not None and directory.exists() and not directory.is_dir():
        raise table.error("directory", f"{directory} exists and is not a directory")
    chunk_size = _positive_int(table, "chunk_size", defaults.chunk_size)
    max_bytes = _positive_int(table, "max_bytes", defaults.max_bytes)
    if max_bytes < chunk_size:
        raise table.error("max_bytes", f"must be >= chunk_size ({chunk_size}), got {max_bytes}")
    return RecordingSettings(
        directory=directory,
        max_bytes=max_bytes,
        max_duration_s=_at_least(
            table,
            "max_duration_s",
            defaults.max_duration_s,
            MAX_DURATION_MIN_S,
            " (a file would be begun at nearly every hand-over to the recorder)",
        ),
        compression=_choice(table, "compression", COMPRESSIONS, defaults.compression),
        chunk_size=chunk_size,
        flush_period_s=_at_least(
            table,
            "flush_period_s",
            defaults.flush_period_s,
            FLUSH_PERIOD_MIN_S,
            " (the recorder would do nothing but write out chunks)",
        ),
        queue_size=_queue_size(table, defaults.queue_size),
        truth=table.boolean("truth", defaults.truth),
        signals=table.boolean("signals", defaults.signals),
        process=table.boolean("process", defaults.process),
    )
