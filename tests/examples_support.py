"""The shipped machine examples, and an independent reading of the frames sent with them.

:class:`SentFrames` decodes sent frames with cantools alone (J1939 messages by their
PGN), converts pressures to Pa with its own unit table (each chamber's unit as the
config gives it: a transducer may send in another unit than the DBC's), pairs each leg's trigger
chamber with the other chamber's latest value (the README's timing rule) and computes
eq. (4) itself: what the service must publish for those frames.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from cantools.database.can import Database, Message

from dbc.machine import MachineConfig
from dbc.samples import SKEW_ROUNDING_S
from estimator.geometry import LegGeometry
from tests.helpers import ROOT

#: Every example shipped (daq/examples/, deploy/examples/ links to it): the default
#: service config and the other machines.
EXAMPLE_CONFIGS = tuple(sorted((ROOT / "daq" / "examples").glob("*/portal-daq.toml")))

#: Pa per unit, written out here rather than taken from dbc.units (psi: 1 lbf per in2).
PA_PER_UNIT = {"Pa": 1.0, "kPa": 1.0e3, "MPa": 1.0e6, "bar": 1.0e5}
PA_PER_UNIT["psi"] = 0.45359237 * 9.80665 / 0.0254**2

#: Tables of the service config (the rest is the machine's).
SERVICE_TABLES = ("bus", "zenoh", "publish", "recording")


def example_id(path: Path) -> str:
    """The example's folder name (``default``: deploy/portal-daq.example.toml)."""
    return path.parent.name


def eq4_N(p_piston_Pa: float, p_rod_Pa: float, leg: LegGeometry) -> float:
    """Eq. (4) of the paper, written out: F_cyl (l_r sin a - l_z cos a) / l_b + l_gb/l_b F_gLeg."""
    a = leg.alpha_cyl_rad
    lever = (leg.l_r_m * math.sin(a) - leg.l_z_m * math.cos(a)) / leg.l_b_m
    f_cyl_N = p_piston_Pa * leg.A_piston_m2 - p_rod_Pa * leg.A_rod_m2
    return f_cyl_N * lever + leg.l_gb_m / leg.l_b_m * leg.F_gLeg_N


def j1939_pgn(frame_id: int) -> int:
    """The PGN of a 29-bit ID: PDU2 (PF >= 240) keeps the PS byte, PDU1 drops it."""
    pgn = (frame_id >> 8) & 0x3FFFF
    return pgn if (pgn >> 8) & 0xFF >= 240 else pgn & 0x3FF00


@dataclass(frozen=True)
class Expected:
    """One leg sample the sent frames make: its pressures (Pa) and eq. (4)."""

    leg: str
    t_s: float
    p_piston_Pa: float
    p_rod_Pa: float
    force_raw_N: float
    #: The other chamber's value was there and fresh enough.
    complete: bool


@dataclass(frozen=True)
class _Chamber:
    leg: str
    chamber: str
    signal: str
    source_address: int | None
    #: The unit the transducer sends in (the config's, else the DBC's).
    unit: str


class SentFrames:
    """The leg samples that a stream of sent frames makes, computed independently."""

    def __init__(self, config: MachineConfig, database: Database) -> None:
        self._config = config
        self._database = database
        self._by_id: dict[tuple[int, bool], Message] = {}
        self._by_pgn: dict[int, Message] = {}
        for message in database.messages:
            if message.protocol == "j1939":
                self._by_pgn[j1939_pgn(message.frame_id)] = message
            else:
                self._by_id[(message.frame_id, bool(message.is_extended_frame))] = message
        self._chambers: dict[str, list[_Chamber]] = defaultdict(list)
        for leg in config.legs.values():
            for chamber in ("piston", "rod"):
                mapped = getattr(leg, chamber)
                self._chambers[mapped.message].append(
                    _Chamber(leg.name, chamber, mapped.signal, mapped.source_address, mapped.unit)
                )
        self._latest: dict[tuple[str, str], tuple[float, float]] = {}
        #: Every sample so far, by leg, in order.
        self.samples: dict[str, list[Expected]] = defaultdict(list)
        #: Frames read, by message name.
        self.frames: dict[str, int] = defaultdict(int)

    def message_of(self, arbitration_id: int, is_extended_id: bool) -> Message:
        message = self._by_id.get((arbitration_id, is_extended_id))
        if message is None and is_extended_id:
            message = self._by_pgn.get(j1939_pgn(arbitration_id))
        assert message is not None, f"frame ID {arbitration_id:#x} is not in the DBC"
        return message

    def add(
        self, t_s: float, arbitration_id: int, is_extended_id: bool, data: bytes
    ) -> list[Expected]:
        """Read one sent frame; the samples it makes (one per leg it triggers)."""
        message = self.message_of(arbitration_id, is_extended_id)
        self.frames[message.name] += 1
        source_address = arbitration_id & 0xFF if message.protocol == "j1939" else None
        values = message.decode(bytes(data), decode_choices=False, scaling=True)
        chambers = [
            chamber
            for chamber in self._chambers.get(message.name, ())
            if chamber.source_address in (None, source_address)
        ]
        for chamber in chambers:  # a frame with both chambers pairs them: update both first
            p_Pa = float(values[chamber.signal]) * PA_PER_UNIT[chamber.unit]  # type: ignore[arg-type]
            self._latest[(chamber.leg, chamber.chamber)] = (t_s, p_Pa)
        return [
            self._sample(chamber.leg, t_s)
            for chamber in chambers
            if chamber.chamber == self._config.legs[chamber.leg].trigger
        ]

    def _sample(self, leg_name: str, t_s: float) -> Expected:
        leg = self._config.legs[leg_name]
        other = self._latest.get((leg_name, "rod" if leg.trigger == "piston" else "piston"))
        complete = other is not None and t_s - other[0] <= leg.max_skew_s + SKEW_ROUNDING_S
        other_Pa = other[1] if other is not None else math.nan
        trigger_Pa = self._latest[(leg_name, leg.trigger)][1]
        p_piston_Pa, p_rod_Pa = (
            (trigger_Pa, other_Pa) if leg.trigger == "piston" else (other_Pa, trigger_Pa)
        )
        sample = Expected(
            leg_name,
            t_s,
            p_piston_Pa,
            p_rod_Pa,
            eq4_N(p_piston_Pa, p_rod_Pa, leg.geometry),
            complete,
        )
        self.samples[leg_name].append(sample)
        return sample

    def half_step_Pa(self, leg: str, chamber: str) -> float:
        """Half a DBC step of a chamber's pressure signal, in Pa: the most rounding moves it."""
        mapped = getattr(self._config.legs[leg], chamber)
        message = self._database.get_message_by_name(mapped.message)
        signal = message.get_signal_by_name(mapped.signal)
        return float(signal.scale) * PA_PER_UNIT[mapped.unit] / 2


def machine_part(example: Path) -> Iterator[str]:
    """The example's lines without its service tables, ``machine.dbc`` made absolute."""
    table = ""
    for line in example.read_text().splitlines():
        stripped = line.strip()
        if stripped.startswith("[") and not stripped.startswith("[["):
            table = stripped.strip("[]").split(".")[0].strip()
        if table in SERVICE_TABLES:
            continue
        if table == "machine" and stripped.startswith("dbc ="):
            relative = stripped.split("=", 1)[1].strip().strip('"')
            line = f'dbc = "{(example.parent / relative).resolve()}"'
        yield line
