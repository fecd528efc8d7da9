"""Which simulated leg the bridge plays onto each leg of the machine configuration.

Pure computation. The simulation has six legs, :data:`~sim_bridge.result.LEGS`
(``SB1_F1`` .. ``SB2_F3``); a machine configuration may call its legs anything
(``left_front``). Each config leg gets the chamber pressures, stroke and true force of
one simulated leg, and the ground truth names it as the config does, so the service's
estimates and the truth line up. The rules, in this order:

1. **Stated**: ``simulated_leg = "SB1_F1"`` in the leg's ``[legs.<LEG>]`` table (checked
   when the config is loaded: a simulated leg, none twice).
2. **By name**: a leg named like a simulated leg (and not stated by another) is that one.
   In a machine of more than six legs, the legs left over (``SB1_F4`` beside
   ``SB1_F1`` .. ``SB2_F3``) take the simulated legs no leg plays, then the six again, in
   their order in the config.
3. **Derived**, only when neither rule maps any leg:

   - from ``[stability.bases.*]``: the first base (it stands first, as SB1 does) is SB1,
     the second SB2; within a base of three feet, each foot by its angle about the
     centre of the base's feet, where the simulation puts F1 at 0 deg, F2 at 120 deg and
     F3 at 240 deg (:data:`~sim_bridge.params.FOOT_ANGLES_DEG`) when every foot is
     within :data:`ANGLE_TOLERANCE_DEG` of a different one of them; else, and in a base
     of other than three feet (two, four), by the feet's order in ``feet_m``, a fourth
     foot playing F1 again;
   - without ``[stability]``: the legs' order in the config, the first three SB1_F1..F3,
     the next three SB2_F1..F3, a seventh SB1_F1 again.

   A machine of more than six legs plays some simulated legs twice: their frames carry
   the same pressures, and the truth gives each config leg its simulated leg's.

Anything else (legs left over after rules 1 and 2) is a :class:`~dbc.errors.ConfigError`
naming the leg and what to add. Derived maps only matter for the stability margin (which
foot stands where); the truth lines up with the estimates under any of them.

>>> from types import SimpleNamespace as Leg
>>> config = Leg(source="m.toml", stability=None, legs={
...     name: Leg(simulated_leg=None) for name in ("FL", "ML", "RL", "FR", "MR", "RR")})
>>> leg_map(config).simulated["FR"], leg_map(config).rule
('SB2_F1', "the legs' order in the config")
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from dbc.errors import ConfigError
from dbc.machine import MachineConfig
from estimator.kinematics import BaseLayout, Point
from sim_bridge.params import FOOT_ANGLES_DEG
from sim_bridge.result import LEGS

#: A foot matches a simulated foot's angle if it is at most this far from it.
ANGLE_TOLERANCE_DEG = 20.0


@dataclass(frozen=True)
class LegMap:
    """Config leg -> simulated leg, and by which rule."""

    #: Config leg -> simulated leg (one of LEGS), in the config's leg order.
    simulated: Mapping[str, str]
    #: How the map was found, for the log.
    rule: str

    @property
    def columns(self) -> dict[str, int]:
        """Config leg -> its column in a result's per-leg arrays."""
        return {leg: LEGS.index(simulated) for leg, simulated in self.simulated.items()}

    def __str__(self) -> str:
        return ", ".join(
            leg if leg == simulated else f"{leg}={simulated}"
            for leg, simulated in self.simulated.items()
        )


def leg_map(config: MachineConfig) -> LegMap:
    """The simulated leg of each of ``config``'s legs (see the module docstring)."""
    stated = {
        name: leg.simulated_leg
        for name, leg in config.legs.items()
        if leg.simulated_leg is not None
    }
    taken = set(stated.values())
    named = {
        name: name
        for name in config.legs
        if name in LEGS and name not in stated and name not in taken
    }
    left = [name for name in config.legs if name not in stated and name not in named]
    rules = [what for what, used in (("simulated_leg", stated), ("leg names", named)) if used]
    if not left:
        simulated = {name: stated.get(name) or named[name] for name in config.legs}
        return LegMap(simulated, " and ".join(rules))
    free = [leg for leg in LEGS if leg not in taken and leg not in named.values()]
    if (stated or named) and len(config.legs) > len(LEGS):
        # More legs than the simulation's (SB1_F4, SB2_F4 beside the six): the others
        # take the free simulated legs, then the six over again.
        again = free + [leg for leg in LEGS if leg not in free]
        extra = {name: again[i % len(again)] for i, name in enumerate(left)}
        simulated = {
            name: stated.get(name) or named.get(name) or extra[name] for name in config.legs
        }
        return LegMap(simulated, " and ".join([*rules, "the other legs' order"]))
    if stated or named:
        name = left[0]
        why = (
            f"{name} is legs.{_stater(stated, name)}'s simulated_leg"
            if name in LEGS
            else f"the simulation has no leg {name!r}"
        )
        hint = f"add simulated_leg = one of {', '.join(free)}" if free else "remove the leg"
        raise ConfigError(config.source, f"legs.{name}", f"{why}; {hint}")
    derived = _by_bases(config.stability.layout.bases) if config.stability else None
    if derived is None or set(derived[0]) != set(config.legs):
        return LegMap(
            {leg: LEGS[i % len(LEGS)] for i, leg in enumerate(config.legs)},
            "the legs' order in the config",
        )
    simulated, rule = derived
    return LegMap({leg: simulated[leg] for leg in config.legs}, rule)


def _stater(stated: Mapping[str, str], simulated: str) -> str:
    return next(name for name, leg in stated.items() if leg == simulated)


def _by_bases(bases: Sequence[BaseLayout]) -> tuple[dict[str, str], str] | None:
    """The map from two bases, and its rule; None when they are not two."""
    if len(bases) != 2:
        return None
    simulated: dict[str, str] = {}
    how = []
    for b, base in enumerate(bases):
        feet = list(base.feet_m)
        order = _by_angles([base.feet_m[leg] for leg in feet]) if len(feet) == 3 else None
        how.append(f"{base.name}'s feet by {'order' if order is None else 'angle'}")
        for k, leg in enumerate(feet):
            simulated[leg] = LEGS[3 * b + (k % 3 if order is None else order[k])]
    return simulated, f"[stability.bases] ({', '.join(how)})"


def _by_angles(points: Sequence[Point]) -> list[int] | None:
    """Each foot's index into FOOT_ANGLES_DEG by its angle about the feet's centre, or None
    when a foot is not near one of them or two are near the same."""
    centre_x = sum(x for x, _ in points) / len(points)
    centre_y = sum(y for _, y in points) / len(points)
    order = []
    for x, y in points:
        if math.hypot(x - centre_x, y - centre_y) == 0:
            return None
        angle_deg = math.degrees(math.atan2(y - centre_y, x - centre_x))
        apart = [abs((angle_deg - a + 180.0) % 360.0 - 180.0) for a in FOOT_ANGLES_DEG]
        nearest = min(range(len(apart)), key=apart.__getitem__)
        if apart[nearest] > ANGLE_TOLERANCE_DEG:
            return None
        order.append(nearest)
    return order if len(set(order)) == len(order) else None
