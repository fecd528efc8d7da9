"""Where the service's resources are built: CAN bus factory, Zenoh session, recorder, notifier.

The only module that opens things for the live service; everything it builds is
passed into :class:`~daq.service.Service`.
"""

import logging
from pathlib import Path

import can
from can.typechecking import CanFilter

from daq.bus_reader import BusFactory, FrameSource, PythonCanSource, sysfs_link_probe
from daq.errors import RecordingError
from daq.mcap_file import CONFIG_ATTACHMENT, DBC_ATTACHMENT
from daq.recorder import Recorder
from daq.recorder_process import RecorderProcess
from daq.sd_notify import SdNotifier
from daq.service import Service
from daq.service_config import BusSettings, ServiceConfig
from daq.socketcan import SocketCanSource
from daq.stop_signal import Stop
from daq.zenoh_session import open_session
from dbc.decoding import FrameDecoder, ReceiveFilter

logger = logging.getLogger(__name__)

#: The most receive filters a SocketCAN socket takes (the kernel's CAN_RAW_FILTER_MAX).
SOCKETCAN_MAX_FILTERS = 512


def kernel_filters(filters: list[ReceiveFilter]) -> list[CanFilter]:
    """python-can ``can_filters`` of the given receive filters."""
    return [
        {"can_id": can_id, "can_mask": can_mask, "extended": extended}
        for can_id, can_mask, extended in filters
    ]


def bus_factory(settings: BusSettings, filters: list[ReceiveFilter]) -> BusFactory:
    """Opens the configured bus; kernel receive ``filters`` if ``kernel_filters``.

    SocketCAN is read through the service's own socket (:mod:`daq.socketcan`: FD
    frames, forced receive buffer, kernel drop counter); any other interface
    through python-can. A receive buffer clamped below ``receive_buffer_bytes``
    is warned about once.
    """
    ids = filters if settings.kernel_filters else None
    if ids is not None and settings.interface == "socketcan" and len(ids) > SOCKETCAN_MAX_FILTERS:
        logger.warning(
            "[bus] kernel_filters: the DBC needs %d kernel filters, SocketCAN takes %d: "
            "frames are filtered in the service instead (other IDs counted as unknown_id)",
            len(ids),
            SOCKETCAN_MAX_FILTERS,
        )
        ids = None  # setting them fails (EINVAL): the bus would never open
    warned = False

    def open_socketcan() -> FrameSource:
        nonlocal warned
        source = SocketCanSource(
            settings.channel,
            receive_buffer_bytes=settings.receive_buffer_bytes,
            receive_own_messages=settings.receive_own_messages,
            receive_filters=ids,
        )
        source.open()
        granted = source.rcvbuf_bytes or 0
        # Linux grants twice what is asked (the other half is for its bookkeeping):
        # less means the request was clamped to net.core.rmem_max.
        if granted < 2 * settings.receive_buffer_bytes and not warned:
            warned = True
            logger.warning(
                "the CAN socket's receive buffer was clamped to %d bytes (%d asked for in "
                "[bus] receive_buffer_bytes, which Linux grants as twice that): a stall may "
                "drop frames (counted on /status as dropped.kernel); give the service "
                "CAP_NET_ADMIN or raise net.core.rmem_max (deploy/sysctl/)",
                granted,
                settings.receive_buffer_bytes,
            )
        return source

    def open_python_can() -> FrameSource:
        bus = can.Bus(
            interface=settings.interface,
            channel=settings.channel,
            receive_own_messages=settings.receive_own_messages,
            can_filters=kernel_filters(ids) if ids is not None else None,
        )
        return PythonCanSource(bus)

    return open_socketcan if settings.interface == "socketcan" else open_python_can


def recording_attachments(config: ServiceConfig) -> dict[str, bytes]:
    """The config file and the DBC, embedded in every recording for replay."""
    try:
        return {
            CONFIG_ATTACHMENT: Path(config.source).read_bytes(),
            DBC_ATTACHMENT: config.machine.dbc_path.read_bytes(),
        }
    except OSError as exc:
        raise RecordingError(exc.filename or config.source, f"cannot read: {exc.strerror}") from exc


def build_recorder(config: ServiceConfig) -> Recorder | RecorderProcess | None:
    """The recorder ``[recording]`` asks for (in a process of its own by default); None
    without a directory. Opens nothing."""
    settings = config.recording
    if settings.directory is None:
        return None
    kind = RecorderProcess if settings.process else Recorder
    return kind(
        settings,
        config.database,
        machine_id=config.machine.machine_id,
        attachments=recording_attachments(config),
        decoded_units=config.machine.decoded_units,
    )


def run_service(config: ServiceConfig, stop: Stop) -> None:
    """Open everything, run until ``stop`` is set, close everything.

    Raises ZenohError, RecordingError (or ConfigError for a bad Zenoh file) at start.
    """
    filters = FrameDecoder(config.database, config.machine.protection).receive_filters
    recorder = build_recorder(config)
    if recorder is None:
        logger.info("no [recording] directory: not recording")
    link_up = sysfs_link_probe(config.bus.channel) if config.bus.interface == "socketcan" else None
    with (
        open_session(config.zenoh, config.source) as session,
        SdNotifier.from_environment() as notifier,
    ):
        service = Service(
            config,
            open_bus=bus_factory(config.bus, filters),
            session=session,
            recorder=recorder,
            notifier=notifier,
            link_up=link_up,
        )
        service.run(stop)
