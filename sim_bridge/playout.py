"""What goes on the bus at each instant of the schedule: built, faulted, encoded frames.

Pure computation (no bus, no clock): combines the :class:`~sim_bridge.frames.Timeline`,
the :class:`~sim_bridge.frames.FrameBuilder`, the :class:`~sim_bridge.faults.FaultInjector`
and the :class:`~dbc.encoding.FrameEncoder`. The emitter only times and sends the result.

The rolling counter of each message (per J1939 sender; shared by the pages of a
multiplexed message that carry it) is kept here and handed to the encoder explicitly,
so a frozen counter can repeat the last value sent.
"""

from collections import Counter
from dataclasses import dataclass, field

from dbc.encoding import EncodedFrame, FrameEncoder
from sim_bridge.faults import FaultConfig, FaultInjector, FaultTargets
from sim_bridge.frames import FrameBuilder, Position, Timeline
from sim_bridge.result import SimulationResult
from sim_bridge.schedule import Instant, MessageCycle


@dataclass(frozen=True, slots=True)
class OutgoingFrame:
    """One encoded frame to send, and the message it belongs to."""

    message: str
    frame: EncodedFrame


@dataclass
class PlayoutCounts:
    """How many frames each fault touched, per message."""

    built: Counter[str] = field(default_factory=Counter)
    dropped: Counter[str] = field(default_factory=Counter)
    bad_crc: Counter[str] = field(default_factory=Counter)
    frozen_counter: Counter[str] = field(default_factory=Counter)
    silent: Counter[str] = field(default_factory=Counter)
    paused: Counter[str] = field(default_factory=Counter)


def fault_targets(builder: FrameBuilder) -> FaultTargets:
    """What faults may name, as ``builder`` sends it."""
    return FaultTargets(
        messages=tuple(builder.messages),
        leg_messages=dict(builder.leg_messages),
        leg_status_names=builder.leg_status_names(),
        simulated_legs={
            leg: simulated
            for leg, simulated in builder.leg_map.simulated.items()
            if leg != simulated
        },
    )


class Playout:
    """Turns schedule instants into encoded frames of one looping simulation result."""

    def __init__(
        self,
        result: SimulationResult,
        builder: FrameBuilder,
        encoder: FrameEncoder,
        injector: FaultInjector | None = None,
    ) -> None:
        self.result = result
        self.timeline = Timeline.of(result)
        self._builder = builder
        self._encoder = encoder
        self._injector = injector or FaultInjector(FaultConfig(), fault_targets(builder))
        self._next_counter: dict[tuple[str, int | None], int] = {}
        self.counts = PlayoutCounts()
        #: Config leg -> its column in ``result`` (its simulated leg).
        self.leg_columns = builder.leg_map.columns

    @property
    def cycles(self) -> list[MessageCycle]:
        """The messages this playout sends, with their cycle times, in DBC order."""
        return self._builder.cycles

    def frames(self, instant: Instant) -> tuple[Position, list[OutgoingFrame]]:
        """Where ``instant`` falls in the result, and the frames to send for it."""
        position = self.timeline.position(instant.sim_t_ns)
        injector, counts = self._injector, self.counts
        if injector.paused(instant.sim_t_ns):
            counts.paused.update(instant.messages)
            return position, []
        overrides = injector.overrides(
            self.result, position.row, instant.sim_t_ns, self.leg_columns
        )
        outgoing: list[OutgoingFrame] = []
        for message in instant.messages:
            if injector.silent(message, instant.sim_t_ns):
                counts.silent[message] += 1
                continue
            fate = injector.fate(message, instant.sim_t_ns)
            counter = None
            key = self._builder.counter_key(message)
            if key is not None:  # (the pages of a multiplexed message may share one)
                next_counter = self._next_counter.get(key, 0)
                if fate.freeze_counter and next_counter > 0:
                    counter = next_counter - 1  # the last one sent, again
                    counts.frozen_counter[message] += 1
                else:  # (a freeze from the very first frame starts by sending counter 0)
                    counter = next_counter
                    self._next_counter[key] = next_counter + 1
            signals = self._builder.signals(
                message, self.result, position.row, position.cycle, overrides
            )
            dbc_message, source_address = self._builder.target(message)
            # a message without a CRC has none to corrupt: sent as it is, not counted
            corrupt_crc = fate.corrupt_crc and self._builder.has_crc(message)
            frame = self._encoder.encode(
                dbc_message,
                signals,
                counter=counter,
                corrupt_crc=corrupt_crc,
                source_address=source_address,
            )
            counts.built[message] += 1
            if not fate.send:
                counts.dropped[message] += 1
                continue
            if corrupt_crc:
                counts.bad_crc[message] += 1
            outgoing.append(OutgoingFrame(message, frame))
        return position, outgoing
