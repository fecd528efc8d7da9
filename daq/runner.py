"""Where the service's resources are built: CAN bus factory, Zenoh session, recorder, notifier.

The only module that opens things for the live service; everything it builds is
passed into :class:`~daq.service.Service`.
"""

import logging
import socket
from pathlib import Path

import can
from can.typechecking import CanFilter

from daq.bus_reader import BusFactory, sysfs_link_probe
from daq.errors import RecordingError
from daq.mcap_file import CONFIG_ATTACHMENT, DBC_ATTACHMENT
from daq.recorder import Recorder
from daq.sd_notify import SdNotifier
from daq.service import Service
from daq.service_config import BusSettings, ServiceConfig
from daq.stop_signal import Stop
from daq.zenoh_session import open_session
from dbc.decoding import FrameDecoder

logger = logging.getLogger(__name__)

CAN_SFF_MASK = 0x7FF
CAN_EFF_MASK = 0x1FFFFFFF


def kernel_filters(frame_ids: list[tuple[int, bool]]) -> list[CanFilter]:
    """python-can ``can_filters`` passing exactly the given (ID, extended) pairs."""
    return [
        {
            "can_id": frame_id,
            "can_mask": CAN_EFF_MASK if extended else CAN_SFF_MASK,
            "extended": extended,
        }
        for frame_id, extended in frame_ids
    ]


def bus_factory(settings: BusSettings, frame_ids: list[tuple[int, bool]]) -> BusFactory:
    """Opens the configured bus; kernel filters for ``frame_ids`` if ``kernel_filters``."""
    filters = kernel_filters(frame_ids) if settings.kernel_filters else None

    def open_bus() -> can.BusABC:
        bus = can.Bus(
            interface=settings.interface,
            channel=settings.channel,
            receive_own_messages=settings.receive_own_messages,
            can_filters=filters,
        )
        _enlarge_receive_buffer(bus)
        return bus

    return open_bus


#: Kernel receive buffer of the CAN socket: ~5,000 frames (a CAN skb takes ~800 bytes),
#: half a second of a saturated bus, so a burst or a slow moment loses nothing.
RECEIVE_BUFFER_BYTES = 4 * 1024 * 1024


def _enlarge_receive_buffer(bus: can.BusABC) -> None:
    sock = getattr(bus, "socket", None)
    if not isinstance(sock, socket.socket):
        return  # not SocketCAN (virtual bus in tests): nothing to size
    # SO_RCVBUFFORCE passes net.core.rmem_max but needs CAP_NET_ADMIN; without it
    # SO_RCVBUF gets as much as rmem_max allows.
    for option in (getattr(socket, "SO_RCVBUFFORCE", None), socket.SO_RCVBUF):
        if option is None:
            continue
        try:
            sock.setsockopt(socket.SOL_SOCKET, option, RECEIVE_BUFFER_BYTES)
            return
        except OSError:
            continue
    logger.warning("could not enlarge the CAN socket's receive buffer")


def recording_attachments(config: ServiceConfig) -> dict[str, bytes]:
    """The config file and the DBC, embedded in every recording for replay."""
    try:
        return {
            CONFIG_ATTACHMENT: Path(config.source).read_bytes(),
            DBC_ATTACHMENT: config.machine.dbc_path.read_bytes(),
        }
    except OSError as exc:
        raise RecordingError(exc.filename or config.source, f"cannot read: {exc.strerror}") from exc


def run_service(config: ServiceConfig, stop: Stop) -> None:
    """Open everything, run until ``stop`` is set, close everything.

    Raises ZenohError, RecordingError (or ConfigError for a bad Zenoh file) at start.
    """
    frame_ids = FrameDecoder(config.database, config.machine.protection).frame_ids
    recorder = None
    if config.recording.directory is not None:
        recorder = Recorder(
            config.recording,
            config.database,
            machine_id=config.machine.machine_id,
            attachments=recording_attachments(config),
        )
    else:
        logger.info("no [recording] directory: not recording")
    link_up = sysfs_link_probe(config.bus.channel) if config.bus.interface == "socketcan" else None
    with (
        open_session(config.zenoh, config.source) as session,
        SdNotifier.from_environment() as notifier,
    ):
        service = Service(
            config,
            open_bus=bus_factory(config.bus, frame_ids),
            session=session,
            recorder=recorder,
            notifier=notifier,
            link_up=link_up,
        )
        service.run(stop)
