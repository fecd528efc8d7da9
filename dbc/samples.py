"""From decoded frames to the estimator's leg samples, by the config's signal mapping."""

from collections.abc import Mapping

from dbc.decoding import DecodedFrame
from dbc.machine import LegConfig
from estimator.leg import LegSample


class LegSampler:
    """Picks each leg's chamber pressures and status out of its message's frames."""

    def __init__(self, legs: Mapping[str, LegConfig]) -> None:
        self._legs_by_message: dict[str, list[LegConfig]] = {}
        for leg in legs.values():
            self._legs_by_message.setdefault(leg.message, []).append(leg)

    def samples(self, frame: DecodedFrame) -> list[tuple[str, LegSample]]:
        """The (leg name, sample) pairs that ``frame`` carries; empty for other messages."""
        signals = frame.signals
        return [
            (
                leg.name,
                LegSample(
                    t_s=frame.t_s,
                    p_piston_Pa=float(signals[leg.piston.signal]),
                    p_rod_Pa=float(signals[leg.rod.signal]),
                    status=str(signals[leg.status.signal]) if leg.status else "ok",
                    crc_ok=frame.crc_ok,
                    counter_ok=frame.counter_ok,
                ),
            )
            for leg in self._legs_by_message.get(frame.message, ())
        ]
