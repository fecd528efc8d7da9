"""The pure core of the service: raw frame in, decoded frame and leg estimates out.

No threads, sockets, files or clocks: the live service's consumer thread and the
offline replay both feed frames through the same :class:`Pipeline`, so live and
replayed estimates of one recording are identical.
"""

import logging
from collections import Counter, defaultdict
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import partial

from cantools.database.can import Database

from daq.frames import RawFrame, error_frame_kinds
from daq.pose import PoseTracker
from dbc.decoding import DecodedFrame, FrameDecoder, is_j1939
from dbc.errors import ErrorFrameError, FrameError, FrameLengthError, RemoteFrameError
from dbc.machine import MachineConfig
from dbc.protection import COUNTER_JUMP, COUNTER_REPEAT, CRC_FAULT
from dbc.samples import LegSampler
from dbc.signal_range import value_range
from estimator.leg import LegEstimate
from estimator.machine import MachineEstimator, MachineSnapshot
from estimator.metrics import SoilMetrics
from estimator.records import fast_init

logger = logging.getLogger(__name__)

#: Frames of a leg message from a J1939 source address no chamber is mapped to.
UNMAPPED_SOURCE = "unmapped_source"
#: The kinds of :attr:`Pipeline.bad` counted for frames that were decoded (a message of
#: the DBC from a sender it maps: its protection failed); every other kind is a frame
#: refused (see :func:`decoded_frames`).
DECODED_FAULTS = frozenset({CRC_FAULT, COUNTER_JUMP, COUNTER_REPEAT})
#: Frames of one sender in a row whose CRC failed before it is logged: a sender whose
#: every frame fails is configured otherwise than the [protection] table says, where
#: interference corrupts a frame now and then.
CRC_FAILING_LOGGED_AFTER = 20


def decoded_frames(frames: int, bad: Mapping[str, int]) -> int:
    """Of ``frames`` processed, those of the DBC's messages from senders it maps (their
    CRC or counter may have failed), given the pipeline's ``bad`` counts: not the unknown
    IDs, error, remote and FD frames, wrong lengths, unmapped J1939 senders, nor frames
    lost to a bug. Worked out from the counters when asked, nothing per frame.

    >>> decoded_frames(1000, {"error_frame": 900, "unknown_id": 60, "crc": 3})
    40
    """
    return frames - sum(count for kind, count in bad.items() if kind not in DECODED_FAULTS)


@fast_init
@dataclass(frozen=True, slots=True)
class FrameResult:
    """What one frame gave: its decoding (or the error) and the leg estimates it updated."""

    frame: RawFrame
    #: None when the frame could not be decoded (then ``error`` says why).
    decoded: DecodedFrame | None
    error: FrameError | None
    estimates: tuple[LegEstimate, ...] = field(default=())

    @property
    def error_kind(self) -> str | None:
        return self.error.kind if self.error is not None else None


class Pipeline:
    """Decoder, sampler and estimator in a row, with counters of what went by.

    >>> pipeline = Pipeline.from_config(config, database)  # doctest: +SKIP
    >>> pipeline.process(RawFrame(t_s=1.0, arbitration_id=0x100, is_extended_id=False,
    ...                           data=frame_bytes)).estimates[0].force_raw_N  # doctest: +SKIP
    61234.5
    """

    def __init__(
        self,
        decoder: FrameDecoder,
        sampler: LegSampler,
        estimator: MachineEstimator,
        pose: PoseTracker | None = None,
    ) -> None:
        self.decoder = decoder
        self.sampler = sampler
        self.estimator = estimator
        #: The bridge's pose, for the stability margin; None when not configured.
        self.pose = pose
        #: Frames processed.
        self.frames = 0
        #: Frames that could not be used, by :attr:`FrameError.kind`, plus decoded
        #: frames whose protection failed (``crc``, ``counter``, ``counter_repeat``) and
        #: frames of a leg PGN from an unmapped source address (``unmapped_source``).
        self.bad: Counter[str] = Counter()
        #: Invalid leg estimates, by leg and reason (``status_sensor_fault``, ``range`` ...).
        self.leg_faults: defaultdict[str, Counter[str]] = defaultdict(Counter)
        #: Frames lost on the way, as the rolling counters of the frames after them tell.
        self.frames_lost = 0
        #: What the error frames reported (:func:`~daq.frames.error_frame_kinds`: bus off,
        #: rx overflow, ...), by kind.
        self.error_frame_kinds: Counter[str] = Counter()
        # The unmapped senders seen (message, source address): each is logged once.
        self._unmapped: set[tuple[str, int | None]] = set()
        # The messages and lengths of the wrong_dlc frames seen: each is logged once.
        self._wrong_lengths: set[str] = set()
        # Frames in a row whose CRC failed, by sender (message, source address); and the
        # senders logged (once each).
        self._crc_failing: Counter[tuple[str, int | None]] = Counter()
        self._crc_logged: set[tuple[str, int | None]] = set()

    @classmethod
    def from_config(cls, machine: MachineConfig, database: Database) -> "Pipeline":
        return cls(
            FrameDecoder(
                database,
                machine.protection,
                machine.unit_factors,
                sender_to_si=machine.sender_unit_factors,
                senders=machine.pinned_senders,
            ),
            LegSampler(machine.legs),
            MachineEstimator(
                {name: leg.geometry for name, leg in machine.legs.items()},
                machine.estimator,
                machine.weight_N,
                {name: leg.cycle_time_s for name, leg in machine.legs.items()},
            ),
            _pose_tracker(machine, database),
        )

    def process(self, frame: RawFrame) -> FrameResult:
        """Decode one frame and feed the leg samples it carries to the estimator.

        Never raises for a bad frame: the error is counted and returned. Every
        frame, good or bad, advances the estimator's bus time (staleness).
        """
        self.frames += 1
        bus_s = self.estimator.observe(frame.t_s)
        try:
            if frame.is_error_frame:
                self.error_frame_kinds.update(error_frame_kinds(frame))
                raise ErrorFrameError(frame.arbitration_id, "CAN error frame")
            if frame.is_remote_frame:
                raise RemoteFrameError(frame.arbitration_id, "remote frame, no data")
            decoded = self.decoder.decode(
                frame.arbitration_id,
                frame.data,
                frame.t_s,
                frame.is_extended_id,
                frame.is_fd,
                bus_s,
            )
        except FrameError as error:
            self.bad[error.kind] += 1
            if error.kind == FrameLengthError.kind:
                self._log_wrong_length(error)
            return FrameResult(frame, None, error)
        if decoded.faults:
            self.bad.update(decoded.faults)
            if CRC_FAULT in decoded.faults:
                self._crc_failed(decoded)
        elif self._crc_failing:
            self._crc_failing.pop((decoded.message, decoded.source_address), None)
        if decoded.frames_lost:
            self.frames_lost += decoded.frames_lost
        if self.pose is not None:
            self.pose.observe(decoded, bus_s)
        samples = self.sampler.samples(decoded)
        if not samples:  # a frame of no leg's message (None: of none of its senders)
            if samples is None:
                self.bad[UNMAPPED_SOURCE] += 1
                self._log_unmapped(decoded)
            return FrameResult(frame, decoded, None)
        update = self.estimator.update
        estimates = tuple([update(leg, sample) for leg, sample in samples])
        for estimate in estimates:
            if estimate.reasons:
                self.leg_faults[estimate.leg].update(estimate.reasons)
        return FrameResult(frame, decoded, None, estimates)

    def _log_unmapped(self, decoded: DecodedFrame) -> None:
        """One line for the first frame of each unmapped sender: the count alone does not
        say which address a transducer sends from (one set to another address than its
        chamber's ``source_address`` leaves that leg stale)."""
        sender = (decoded.message, decoded.source_address)
        if sender in self._unmapped:
            return
        self._unmapped.add(sender)
        address = "none" if decoded.source_address is None else f"0x{decoded.source_address:02X}"
        logger.warning(
            "%s from source address %s: no chamber has this source_address; its frames "
            "are counted %s and not used",
            decoded.message,
            address,
            UNMAPPED_SOURCE,
        )

    def _crc_failed(self, decoded: DecodedFrame) -> None:
        """One line when a sender's frames fail their CRC :data:`CRC_FAILING_LOGGED_AFTER`
        times in a row: with a wrong data ID, data ID mode or CRC layout in the config, every
        frame fails, the legs it carries are invalid for ever, and only ``bad.crc`` said it."""
        sender = (decoded.message, decoded.source_address)
        self._crc_failing[sender] += 1
        if self._crc_failing[sender] < CRC_FAILING_LOGGED_AFTER or sender in self._crc_logged:
            return
        self._crc_logged.add(sender)
        address = "" if decoded.source_address is None else f" from 0x{decoded.source_address:02X}"
        logger.warning(
            "%s%s: %d frames in a row failed their CRC: check the message's [protection] "
            "table against the sender (profile, data_id, data_id_mode, the CRC and counter "
            "signals); the legs it carries are invalid (%s) meanwhile",
            decoded.message,
            address,
            CRC_FAILING_LOGGED_AFTER,
            CRC_FAULT,
        )

    def _log_wrong_length(self, error: FrameError) -> None:
        """One line for the first frame of each message and length the DBC does not
        give it: a sender and a DBC that disagree on a message's length (a hub sending
        6 bytes of a DBC's 8) left its legs stale with only the count saying why."""
        if error.reason in self._wrong_lengths:
            return
        self._wrong_lengths.add(error.reason)
        logger.warning("%s: its frames are counted %s and not used", error, error.kind)

    def reset_counters(self) -> None:
        """After a gap in reception (bus down, reopened): forget the rolling counters so
        that the first frames after it are not flagged ``counter``, and the chambers'
        latest values, so that none from before the gap is paired with a new one."""
        self.decoder.reset_counters()
        self.sampler.reset()

    @property
    def latest_t_s(self) -> float:
        """Frame time of the latest frame processed (not the largest: the clock may
        step back); NaN before the first."""
        return self.estimator.latest_t_s

    def snapshot(self, now_s: float) -> MachineSnapshot:
        """Every leg judged at ``now_s``, the weight check and the stability margin."""
        pose = self.pose
        place_feet = None if pose is None else partial(pose.feet_m, self.estimator.judged_s(now_s))
        return self.estimator.snapshot(now_s, place_feet)

    def metrics(self) -> Mapping[str, SoilMetrics]:
        return self.estimator.metrics()


def _pose_tracker(machine: MachineConfig, database: Database) -> PoseTracker | None:
    stability = machine.stability
    if stability is None:
        return None
    max_age_s, ranges = {}, {}
    for name, ref in (("rotation", stability.rotation), ("fold", stability.fold)):
        message = database.get_message_by_name(ref.message)
        ranges[name] = value_range(message.get_signal_by_name(ref.signal), is_j1939(message))
        cycle_ms = machine.cycle_times_ms.get(ref.message)
        # Without a cycle time, a pose frame counts as fresh for a second.
        max_age_s[ref.message] = (
            machine.estimator.stale_after_cycles * cycle_ms / 1000.0 if cycle_ms else 1.0
        )
    return PoseTracker(stability, max_age_s, ranges)
