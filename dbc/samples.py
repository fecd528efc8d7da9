"""From decoded frames to the estimator's leg samples, by the config's signal mapping.

A leg's two chamber pressures may come in one frame (one sensor hub) or in two
(one transducer per chamber, e.g. J1939 nodes with their own source addresses; or
two multiplexer values of one message). A frame of a multiplexed message makes the
samples of the legs whose signals it carries.
The sampler holds the latest value of each chamber, with what its own frame's
checks found (CRC, counter, the chamber's status). **Timing rule:** a leg sample is
made when a new value of the leg's trigger chamber arrives (default: piston); it
uses the other chamber's latest value if that is at most ``max_skew_s`` older
(default: one cycle time of the other chamber's message), else the sample is
invalid with ``rod_stale`` (or ``piston_stale``). The sample's time is the trigger
frame's. Both chambers in one frame: skew 0, one sample per frame.

"Older" is measured on *bus time*, as the estimator judges staleness
(:class:`estimator.machine.BusClock`): the sum of the forward steps between successive
frame times of these messages. Frame times follow the wall clock, which NTP may step back:
a rod value from before a step back of an hour would otherwise look an hour *younger*
than every piston value after it, and pair with them for that hour although its
transducer fell silent. A step back adds nothing, so chambers that keep sending stay
fresh across it, and a silent one still ages.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass

from dbc.decoding import DecodedFrame, SignalValue
from dbc.machine import TRIGGERS, ChamberSignal, LegConfig, StatusCheck
from estimator.leg import LegSample
from estimator.machine import BusClock

#: What a difference of two frame times (microseconds, at Unix times ~1.8e9 s: doubles
#: 0.24 us apart) may be off by: a value exactly ``max_skew_s`` older is not stale.
SKEW_ROUNDING_S = 1e-6


@dataclass(frozen=True, slots=True)
class _Paired:
    """A leg whose two chambers come in one frame: every such frame is one sample."""

    leg: str
    #: The two chambers' signal names (looked up in every frame).
    piston: str
    rod: str
    #: The J1939 sender whose frames are the leg's (:func:`_sender`); None: any.
    source_address: int | None
    statuses: tuple[StatusCheck, ...]
    #: The two chambers, for how their values are read (:func:`_pressure_Pa`).
    piston_chamber: ChamberSignal
    rod_chamber: ChamberSignal


@dataclass(frozen=True, slots=True)
class _Route:
    """One chamber of one leg, as found in frames of its message."""

    leg: LegConfig
    chamber: str
    signal: ChamberSignal
    #: The leg's sample is made when this chamber's value arrives.
    triggers: bool
    #: The chamber's page (:attr:`~dbc.machine.ChamberSignal.page`); None: any frame.
    page: tuple[str, frozenset[int | str]] | None
    #: The J1939 sender whose frames are the chamber's (:func:`_sender`); None: any.
    source_address: int | None


@dataclass(frozen=True, slots=True)
class _Reading:
    """The latest value of one chamber and what its frame's checks said."""

    t_s: float
    #: The sampler's bus time when it came (what its age is measured on).
    bus_s: float
    p_Pa: float
    faults: tuple[str, ...]


class LegSampler:
    """Picks each leg's chamber pressures and status out of its messages' frames."""

    def __init__(self, legs: Mapping[str, LegConfig]) -> None:
        #: The legs sampled, by name.
        self.legs = legs
        # The usual case, both chambers in one frame, needs no state (the hot path).
        self._paired: dict[str, list[_Paired]] = {}
        self._routes: dict[str, list[_Route]] = {}
        for leg in legs.values():
            piston, rod = leg.piston, leg.rod
            # A chamber on one page of a signal sent on several (an I/O module's channels)
            # goes by route, which looks at the page; the usual pairs need not.
            if (piston.message, _sender(piston), piston.mux_ids, None, None) == (
                rod.message,
                _sender(rod),
                rod.mux_ids,
                piston.page,
                rod.page,
            ):
                statuses = tuple(
                    dict.fromkeys(s for s in (piston.status, rod.status) if s is not None)
                )
                self._paired.setdefault(piston.message, []).append(
                    _Paired(
                        leg.name,
                        piston.signal,
                        rod.signal,
                        _sender(piston),
                        statuses,
                        piston,
                        rod,
                    )
                )
                continue
            for chamber in TRIGGERS:
                signal: ChamberSignal = getattr(leg, chamber)
                self._routes.setdefault(signal.message, []).append(
                    _Route(
                        leg, chamber, signal, chamber == leg.trigger, signal.page, _sender(signal)
                    )
                )
        self._latest: dict[tuple[str, str], _Reading] = {}
        #: Bus time of the chambers' frames (module docstring).
        self._clock = BusClock()

    def samples(self, frame: DecodedFrame) -> list[tuple[str, LegSample]] | None:
        """The (leg name, sample) pairs that ``frame`` makes; empty for other messages.

        None when the frame's message carries chambers but none from its source
        address: a J1939 frame of a known PGN from an unmapped transducer.
        """
        paired = self._paired.get(frame.message, ())
        routes = self._routes.get(frame.message, ())
        if not paired and not routes:
            return []
        source_address = frame.source_address
        signals = frame.signals
        t_s, faults = frame.t_s, frame.faults
        senders = [
            leg
            for leg in paired
            if leg.source_address is None or leg.source_address == source_address
        ]
        samples = [
            (
                leg.leg,
                LegSample(
                    t_s,
                    _pressure_Pa(signals[leg.piston], leg.piston_chamber),
                    _pressure_Pa(signals[leg.rod], leg.rod_chamber),
                    _with_status(faults, leg.statuses, signals) if leg.statuses else faults,
                ),
            )
            for leg in senders
            if leg.piston in signals  # a multiplexed message's frame may carry other legs
        ]
        if not routes:  # the usual case: both chambers in the frame, no state
            return samples if senders else None
        by_sender = [
            route
            for route in routes
            if route.source_address is None or route.source_address == source_address
        ]
        if not senders and not by_sender:
            return None
        bus_s = self._clock.observe(t_s)
        matched = [
            route
            for route in by_sender
            if route.signal.signal in signals
            and (route.page is None or signals.get(route.page[0]) in route.page[1])
        ]
        for route in matched:
            status = route.signal.status
            chamber_faults = _with_status(faults, (status,) if status else (), signals)
            self._latest[(route.leg.name, route.chamber)] = _Reading(
                t_s,
                bus_s,
                _pressure_Pa(signals[route.signal.signal], route.signal),
                chamber_faults,
            )
        return samples + [self._sample(route.leg) for route in matched if route.triggers]

    def _sample(self, leg: LegConfig) -> tuple[str, LegSample]:
        other_chamber = "rod" if leg.trigger == "piston" else "piston"
        trigger = self._latest[(leg.name, leg.trigger)]
        other = self._latest.get((leg.name, other_chamber))
        faults = list(trigger.faults)
        if other is None or trigger.bus_s - other.bus_s > leg.max_skew_s + SKEW_ROUNDING_S:
            faults.append(f"{other_chamber}_stale")
            other_p_Pa = other.p_Pa if other is not None else float("nan")
        else:
            faults += [fault for fault in other.faults if fault not in faults]
            other_p_Pa = other.p_Pa
        p_piston_Pa, p_rod_Pa = (
            (trigger.p_Pa, other_p_Pa) if leg.trigger == "piston" else (other_p_Pa, trigger.p_Pa)
        )
        return leg.name, LegSample(trigger.t_s, p_piston_Pa, p_rod_Pa, tuple(faults))

    def reset(self) -> None:
        """Forget the latest chamber values (after a gap in reception)."""
        self._latest.clear()


def _sender(chamber: ChamberSignal) -> int | None:
    """The J1939 source address whose frames are ``chamber``'s: its ``source_address``,
    else the one its message's DBC ID gives (``dbc_source_address``); None: any sender."""
    if chamber.source_address is not None:
        return chamber.source_address
    return chamber.dbc_source_address


def _pressure_Pa(value: SignalValue, chamber: ChamberSignal) -> float:
    """A decoded value of ``chamber`` as gauge pressure (less its ``atmosphere_Pa``, for an
    absolute transducer); NaN, which the estimator judges out of range, for a code the DBC
    says is no pressure: a value-table name in its place (a transducer's "not available"
    or "error") other than one naming a pressure in the signal's range (``named_Pa``: ``0
    "Zero"`` is 0 Pa), or a value outside ``range_Pa`` or inside ``codes_Pa`` (a code
    unnamed)."""
    if isinstance(value, str):
        return chamber.named_Pa.get(value, math.nan)
    p_Pa = float(value) - chamber.atmosphere_Pa
    low_Pa, high_Pa = chamber.range_Pa
    code_low_Pa, code_high_Pa = chamber.codes_Pa
    if low_Pa <= p_Pa <= high_Pa and not code_low_Pa <= p_Pa <= code_high_Pa:
        return p_Pa
    return math.nan


def _with_status(
    faults: tuple[str, ...], statuses: tuple[StatusCheck, ...], signals: Mapping[str, object]
) -> tuple[str, ...]:
    """The frame's faults and those of its status signals."""
    for status in statuses:
        value = signals[status.signal]
        if value in status.ok:  # the usual case, without a call
            continue
        fault = status.fault(value)
        if fault is not None and fault not in faults:
            faults = (*faults, fault)
    return faults
