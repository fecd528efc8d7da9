"""Every machine under a root key, as a fleet view received them: pure, no I/O.

Machines are found by their services' liveliness tokens (``<root>/<id>/alive``)
and their data (``<root>/<id>/ground``, ``/status``, ``/metrics``), fed as
:class:`~daq.live.feed.Item` s by a :class:`~daq.live.feed.LiveFeed` on the
prefix ``<root>/*`` with ``liveliness=True``. Each machine keeps its own
:class:`~daq.live.state.LiveState`.

A machine is **gone** as soon as its token goes (the service stopped, or the
router's lease on its session expired); that is not the same as **stale**
(the token is there but data stopped coming, judged on the viewer's clock as in
the single-machine views). A machine that comes back is live again.

>>> from daq.live.feed import Item
>>> fleet = FleetState(FleetSettings("portal"))
>>> fleet.apply(Item("portal/m1/alive", b"", 1.0, True))
True
>>> fleet.apply(Item("portal/m1/status", b'{"healthy": true}', 1.0))
True
>>> [(m.machine_id, m.state) for m in fleet.summaries(now_s=1.5)]
[('m1', 'waiting')]
>>> fleet.apply(Item("portal/m1/alive", b"", 2.0, False))
True
>>> [(m.machine_id, m.state, m.gone_for_s) for m in fleet.summaries(now_s=2.5)]
[('m1', 'gone', 0.5)]
"""

from dataclasses import asdict, dataclass

from daq.live.feed import Item, apply_item
from daq.live.state import NO_LINK, LiveState
from daq.live.viewer import GROUND_STALE_MIN_S, STATUS_STALE_PERIODS, ViewerConfig
from daq.payloads import JsonObject
from estimator.settings import EstimatorSettings

#: The root of the services' default key prefix ``portal/<machine id>``.
DEFAULT_ROOT = "portal"
#: The estimator's default soil-pressure limit, when no config says otherwise.
DEFAULT_LIMIT_PA = EstimatorSettings().pressure_limit_Pa

#: Machine states, worst last.
LIVE, WAITING, STALE, GONE = "live", "waiting", "stale", "gone"


@dataclass(frozen=True, slots=True)
class FleetSettings:
    """What a fleet view needs: the root key and how to judge every machine."""

    #: Machines are ``<root>/<id>``: the services' ``key_prefix`` without the id.
    root: str
    #: Drawn on every machine's bars and plots (a fleet shares one limit).
    pressure_limit_Pa: float = DEFAULT_LIMIT_PA
    #: No ``/status`` for this long: stale (3 of the service's default 1 s periods).
    status_stale_s: float = STATUS_STALE_PERIODS * 1.0
    #: No ``/ground`` for this long: stale.
    ground_stale_s: float = GROUND_STALE_MIN_S

    @property
    def prefix(self) -> str:
        """The key prefix matching every machine, for :class:`~daq.live.feed.LiveFeed`."""
        return f"{self.root}/*"


@dataclass(frozen=True, slots=True)
class MachineSummary:
    """One row of the fleet page / monitor."""

    machine_id: str
    prefix: str
    #: :data:`LIVE`, :data:`WAITING` (no status or ground yet), :data:`STALE`, :data:`GONE`.
    state: str
    #: Seconds since the liveliness token went; None while it is there.
    gone_for_s: float | None
    healthy: bool | None
    bus_state: str | None
    frames_per_s: float | None
    legs_in_contact: int | None
    legs: int
    #: The highest contact pressure among the valid legs, and that leg.
    max_pressure_Pa: float | None
    max_pressure_leg: str | None
    #: ``stability.margin_m`` of the latest ground, when the service publishes it.
    stability_margin_m: float | None
    #: Age of the latest ground (else status) on the viewer's clock; None: nothing yet.
    data_age_s: float | None


@dataclass
class MachineEntry:
    """A machine as the fleet holds it (one thread applies, see :class:`FleetState`)."""

    prefix: str
    state: LiveState
    #: The liveliness token is there; None: data seen, but no token (yet).
    alive: bool | None = None
    #: When ``alive`` last changed, viewer clock.
    changed_s: float = 0.0

    @property
    def machine_id(self) -> str:
        return self.prefix.rpartition("/")[2]


class FleetState:
    """Every machine seen under ``settings.root``, by prefix."""

    def __init__(self, settings: FleetSettings) -> None:
        self.settings = settings
        self.machines: dict[str, MachineEntry] = {}
        #: Items on keys not of the form ``<root>/<id>/<suffix>``.
        self.ignored = 0
        #: Whether the viewer's session has a Zenoh link (as :attr:`LiveState.linked
        #: <daq.live.state.LiveState.linked>`); None: not known.
        self.linked: bool | None = None

    def waiting(self) -> str:
        """What a fleet view without machines says: waiting for their liveliness tokens,
        and that it has no Zenoh link at all when so (a wrong ``--connect`` said "no
        machine yet" for ever, as if no service were up)."""
        text = f"waiting for liveliness tokens {self.settings.prefix}/alive"
        if self.linked is False:
            text += f": {NO_LINK}"
        return text

    def apply(self, item: Item) -> bool:
        """Take one feed item; False when it changed nothing (or was not usable)."""
        prefix, _, _ = item.key.rpartition("/")
        root, _, machine_id = prefix.rpartition("/")
        if root != self.settings.root or not machine_id:
            self.ignored += 1
            return False
        entry = self.machines.get(prefix)
        if entry is None:
            entry = self.machines[prefix] = MachineEntry(prefix, LiveState(prefix))
        if item.alive is not None:
            if entry.alive == item.alive:
                return False
            entry.alive, entry.changed_s = item.alive, item.received_s
            return True
        return bool(apply_item(entry.state, item))

    def viewer(self, prefix: str) -> ViewerConfig | None:
        """The single-machine view's settings for a machine seen; None for an unknown one.

        Its legs are those of the latest ground (in the service's order), as the
        fleet view has no machine config.
        """
        entry = self.machines.get(prefix)
        if entry is None:
            return None
        ground = entry.state.ground
        return ViewerConfig(
            source=f"fleet {self.settings.root}",
            machine_id=entry.machine_id,
            prefix=prefix,
            legs=tuple(ground.value.legs) if ground is not None else (),
            pressure_limit_Pa=self.settings.pressure_limit_Pa,
            status_stale_s=self.settings.status_stale_s,
            ground_stale_s=self.settings.ground_stale_s,
        )

    def summaries(self, now_s: float) -> list[MachineSummary]:
        """One summary per machine, by machine id."""
        return [
            summarize(entry, self.settings, now_s)
            for _, entry in sorted(self.machines.items(), key=lambda kv: kv[1].machine_id)
        ]


def summarize(entry: MachineEntry, settings: FleetSettings, now_s: float) -> MachineSummary:
    status = entry.state.status
    ground = entry.state.ground
    latest = ground or status
    if entry.alive is False:
        state = GONE
    elif status is None or ground is None:
        state = WAITING
    elif (
        status.age_s(now_s) > settings.status_stale_s
        or ground.age_s(now_s) > settings.ground_stale_s
    ):
        state = STALE
    else:
        state = LIVE
    max_leg = None
    max_Pa = None
    if ground is not None:
        valid = [
            leg for leg in ground.value.legs.values() if leg.valid and leg.pressure_Pa is not None
        ]
        if valid:
            top = max(valid, key=lambda leg: leg.pressure_Pa or 0.0)
            max_leg, max_Pa = top.leg, top.pressure_Pa
    return MachineSummary(
        machine_id=entry.machine_id,
        prefix=entry.prefix,
        state=state,
        gone_for_s=max(0.0, now_s - entry.changed_s) if entry.alive is False else None,
        healthy=None if status is None else status.value.healthy,
        bus_state=None if status is None else status.value.bus_state,
        frames_per_s=None if status is None else status.value.frames_per_s,
        legs_in_contact=None if ground is None else ground.value.legs_in_contact,
        legs=0 if ground is None else len(ground.value.legs),
        max_pressure_Pa=max_Pa,
        max_pressure_leg=max_leg,
        stability_margin_m=None if ground is None else ground.value.stability_margin_m,
        data_age_s=None if latest is None else latest.age_s(now_s),
    )


def fleet_document(fleet: FleetState, now_s: float, *, dropped: int = 0) -> JsonObject:
    """``/api/fleet``: ``{"root", "pressure_limit_Pa", "machines": [summary...], "waiting",
    "viewer"}``."""
    return {
        "root": fleet.settings.root,
        "pressure_limit_Pa": fleet.settings.pressure_limit_Pa,
        "machines": [asdict(summary) for summary in fleet.summaries(now_s)],
        "waiting": fleet.waiting(),
        "viewer": {"dropped": dropped, "ignored": fleet.ignored, "zenoh_linked": fleet.linked},
    }
