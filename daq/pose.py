"""The bridge's pose from the bus, for the stability margin: rotation and fold angles.

Pure: fed the decoded frames by :class:`daq.pipeline.Pipeline`. Keeps the latest
rotation and fold angle of frames whose CRC and counter were fine; the pose is unknown
before both arrived and once either is older than ``stale_after_cycles`` cycle times of
its message (judged on frame time), so the margin is never computed from an old pose.
Which base stands (the plan frame) follows the legs' contact at each snapshot
(:class:`estimator.stance.StanceTracker`).
"""

import math
from collections.abc import Mapping

from dbc.decoding import DecodedFrame
from dbc.machine import SignalRef
from dbc.stability_config import StabilityConfig
from estimator.kinematics import Point
from estimator.leg import LegEstimate
from estimator.stance import BridgePose, StanceTracker


class PoseTracker:
    """Latest bridge angles and the legs' contact -> every foot's plan position."""

    def __init__(self, config: StabilityConfig, max_age_s: Mapping[str, float]) -> None:
        """``max_age_s``: per message name, how old its latest frame may be."""
        self.config = config
        # Message name -> the (name, signal) pairs it carries: one look-up per frame.
        self._by_message: dict[str, list[tuple[str, str]]] = {}
        for name, ref in (("rotation", config.rotation), ("fold", config.fold)):
            self._by_message.setdefault(ref.message, []).append((name, ref.signal))
        self._rad_per_unit = {
            "rotation": config.rotation_rad_per_unit,
            "fold": config.fold_rad_per_unit,
        }
        self._max_age_s = dict(max_age_s)
        #: name -> (frame time, angle in the DBC signal's unit)
        self._latest: dict[str, tuple[float, float]] = {}
        #: Which base stands, and the pose held while both bases are down.
        self.stance = StanceTracker(config.layout)

    def observe(self, frame: DecodedFrame) -> None:
        """Take the angles a decoded frame carries, if it is trusted."""
        refs = self._by_message.get(frame.message)
        if refs is None or not (frame.crc_ok and frame.counter_ok):
            return
        for name, signal in refs:
            value = frame.signals.get(signal)
            if isinstance(value, int | float) and math.isfinite(value):
                self._latest[name] = (frame.t_s, float(value))

    def _angle_rad(self, name: str, ref: SignalRef, now_s: float) -> float | None:
        latest = self._latest.get(name)
        if latest is None or now_s - latest[0] > self._max_age_s[ref.message]:
            return None
        return latest[1] * self._rad_per_unit[name]

    def feet_m(self, now_s: float, legs: Mapping[str, LegEstimate]) -> dict[str, Point] | None:
        """Every foot's position at ``now_s``, in the frame of the base that stands as
        the legs' estimates ``legs`` tell; None while the pose is unknown or old."""
        rotation = self._angle_rad("rotation", self.config.rotation, now_s)
        fold = self._angle_rad("fold", self.config.fold, now_s)
        pose = None if rotation is None or fold is None else BridgePose(rotation, fold)
        self.stance.observe(legs, pose)
        return None if pose is None else self.stance.feet_m(pose)
