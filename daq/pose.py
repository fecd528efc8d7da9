"""The bridge's pose from the bus, for the stability margin: rotation and fold angles.

Pure: fed the decoded frames by :class:`daq.pipeline.Pipeline`. Keeps the latest
rotation and fold angle of frames whose CRC and counter were fine; the pose is unknown
before both arrived and once either is older than ``stale_after_cycles`` cycle times of
its message (judged on bus time, :class:`estimator.machine.BusClock`, as the legs' are:
on frame times, a pose sender silent across a clock step back stayed fresh for as long
as the step), so the margin is never computed from an old pose.
A frame whose angle is no angle (a value-table name, NaN, or a value outside the
signal's range: :func:`dbc.signal_range.value_range`, e.g. J1939's "not available")
makes it unknown until the next frame that brings one.
Which base stands (the plan frame) follows the legs' contact at each snapshot
(:class:`estimator.stance.StanceTracker`).
"""

from collections.abc import Mapping

from dbc.decoding import DecodedFrame
from dbc.machine import SignalRef
from dbc.stability_config import StabilityConfig
from estimator.kinematics import Point
from estimator.leg import LegEstimate
from estimator.stance import BridgePose, StanceTracker


class PoseTracker:
    """Latest bridge angles and the legs' contact -> every foot's plan position."""

    def __init__(
        self,
        config: StabilityConfig,
        max_age_s: Mapping[str, float],
        ranges: Mapping[str, tuple[float, float]],
    ) -> None:
        """``max_age_s``: per message name, how old its latest frame may be;
        ``ranges``: per angle (``rotation``, ``fold``), the values it may take, in
        its DBC signal's unit."""
        self.config = config
        # Message name -> the (name, signal, range) it carries: one look-up per frame.
        self._by_message: dict[str, list[tuple[str, str, tuple[float, float]]]] = {}
        for name, ref in (("rotation", config.rotation), ("fold", config.fold)):
            entry = (name, ref.signal, ranges[name])
            self._by_message.setdefault(ref.message, []).append(entry)
        self._rad_per_unit = {
            "rotation": config.rotation_rad_per_unit,
            "fold": config.fold_rad_per_unit,
        }
        self._max_age_s = dict(max_age_s)
        #: name -> (bus time of its frame, angle in the DBC signal's unit)
        self._latest: dict[str, tuple[float, float]] = {}
        #: Which base stands, and the pose held while both bases are down.
        self.stance = StanceTracker(config.layout)

    def observe(self, frame: DecodedFrame, bus_s: float) -> None:
        """Take the angles a decoded frame carries, if it is trusted; ``bus_s`` is the bus
        time at it."""
        refs = self._by_message.get(frame.message)
        if refs is None or not (frame.crc_ok and frame.counter_ok):
            return
        for name, signal, (low, high) in refs:
            value = frame.signals.get(signal)
            if isinstance(value, int | float) and low <= value <= high:  # NaN is not
                self._latest[name] = (bus_s, float(value))
            elif signal in frame.signals:  # a code: the angle is unknown, not the last one
                self._latest.pop(name, None)

    def _angle_rad(self, name: str, ref: SignalRef, bus_s: float) -> float | None:
        latest = self._latest.get(name)
        if latest is None or bus_s - latest[0] > self._max_age_s[ref.message]:
            return None
        return latest[1] * self._rad_per_unit[name]

    def feet_m(self, bus_s: float, legs: Mapping[str, LegEstimate]) -> dict[str, Point] | None:
        """Every foot's position at bus time ``bus_s``, in the frame of the base that
        stands as the legs' estimates ``legs`` tell; None while the pose is unknown or old."""
        rotation = self._angle_rad("rotation", self.config.rotation, bus_s)
        fold = self._angle_rad("fold", self.config.fold, bus_s)
        pose = None if rotation is None or fold is None else BridgePose(rotation, fold)
        self.stance.observe(legs, pose)
        return None if pose is None else self.stance.feet_m(pose)
