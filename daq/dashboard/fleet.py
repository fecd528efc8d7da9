"""The fleet dashboard: every machine under a root key, from a site router.

Routes (GET): ``/`` the fleet page (``static/fleet.html``), ``/api/fleet``
(:func:`daq.live.fleet.fleet_document`), and per machine the single-machine
dashboard under ``/machine/<id>/`` (the same page and ``api/latest``,
``api/history`` as :class:`~daq.dashboard.server.Dashboard` serves for one
service). Machines are discovered from their liveliness tokens; the feed is a
:class:`~daq.live.feed.LiveFeed` on ``<root>/*`` (see :mod:`daq.live.fleet`).
"""

import time
from collections.abc import Callable, Iterable
from urllib.parse import unquote

import zenoh

from daq.dashboard.api import history_document, latest_document
from daq.dashboard.history import PressureHistory
from daq.dashboard.server import (
    PAGE,
    HubServer,
    Response,
    history_query,
    html,
    json_response,
    not_found,
    page,
)
from daq.live.feed import Item, LiveFeed
from daq.live.fleet import FleetSettings, FleetState, fleet_document
from daq.payloads import JsonObject

FLEET_PAGE = "static/fleet.html"
#: The single-machine views live under ``/machine/<id>/``.
MACHINE_PATH = "/machine/"


class FleetDashboard(HubServer):
    """Serves the fleet under ``settings.root`` on ``address`` (host, port)."""

    def __init__(
        self,
        session: zenoh.Session,
        settings: FleetSettings,
        address: tuple[str, int],
        *,
        allowed_hosts: Iterable[str] = (),
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        feed = LiveFeed(session, settings.prefix, clock=clock, liveliness=True)
        super().__init__(feed, address, allowed_hosts=allowed_hosts, clock=clock)
        self.settings = settings
        self._fleet = FleetState(settings)
        self._histories: dict[str, PressureHistory] = {}
        self._pages: dict[str, bytes] = {}

    def start(self) -> None:
        self._pages = {FLEET_PAGE: page(FLEET_PAGE), PAGE: page(PAGE)}
        super().start()

    def fleet(self) -> JsonObject:
        linked = self.feed.linked()
        with self._lock:
            self._fleet.linked = linked
            return fleet_document(self._fleet, self._clock(), dropped=self.feed.dropped)

    def respond(self, path: str, query: dict[str, list[str]]) -> Response:
        if path in ("/", "/index.html"):
            return html(self._pages[FLEET_PAGE])
        if path == "/api/fleet":
            return json_response(self.fleet())
        if not path.startswith(MACHINE_PATH):
            return not_found(path)
        machine_id, _, rest = path[len(MACHINE_PATH) :].partition("/")
        prefix = f"{self.settings.root}/{unquote(machine_id)}"
        if rest in ("", "index.html"):
            return html(self._pages[PAGE])
        with self._lock:
            viewer = self._fleet.viewer(prefix)
            if viewer is None:
                return not_found(path)
            if rest == "api/latest":
                state = self._fleet.machines[prefix].state
                document = latest_document(viewer, state, self._clock(), dropped=self.feed.dropped)
                return json_response(document)
            if rest == "api/history":
                history = self._histories.get(prefix)
                if history is None:  # no ground yet: an empty plot
                    history = PressureHistory(viewer.legs)
                return json_response(history_document(history, *history_query(query)))
        return not_found(path)

    def _apply(self, item: Item) -> None:
        prefix = item.key.rpartition("/")[0]
        entry = self._fleet.machines.get(prefix)
        before = entry.state.ground if entry is not None else None
        self._fleet.apply(item)
        entry = self._fleet.machines.get(prefix)
        ground = entry.state.ground if entry is not None else None
        if ground is None or ground is before:
            return
        legs = tuple(ground.value.legs)
        history = self._histories.get(prefix)
        history = PressureHistory(legs) if history is None else history.with_legs(legs)
        self._histories[prefix] = history
        history.add(ground.value)
