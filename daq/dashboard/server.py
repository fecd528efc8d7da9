"""The dashboard: a Zenoh subscription feeding one hub thread, and a small HTTP server.

Routes (GET): ``/`` the page (``static/index.html``, everything inline: no
external assets), ``/api/latest`` and ``/api/history?since=T&generation=G``
(see :mod:`daq.dashboard.api`). The page polls both four times a second: plain
requests that complete, unlike a Server-Sent Events stream, so headless
browsers (``--virtual-time-budget``) and proxies handle it, and ``since``
makes sure no snapshot is missed.

DNS rebinding: a web page on another site can make a browser resolve its own name
to this host and then read the dashboard through it. Every request whose ``Host``
header does not name the dashboard (``localhost``, ``127.0.0.1``, ``::1``, the bound
address unless it is a wildcard, and the names given in ``allowed_hosts``, e.g.
``--allow-host pam-1.local``) is refused with 403 (:func:`host_allowed`).

Threads: Zenoh's callbacks only enqueue (:class:`~daq.live.feed.LiveFeed`);
the hub thread applies each payload to the state and the history under a
lock; the HTTP threads (stdlib ``ThreadingHTTPServer``) read them under the
same lock. The session is passed in; :meth:`Dashboard.start` binds the HTTP
address and declares the subscribers; :meth:`Dashboard.close` undoes both.

:class:`HubServer` is that machinery (feed, hub thread, HTTP server, lifecycle);
:class:`Dashboard` (one service) and :class:`~daq.dashboard.fleet.FleetDashboard`
(every machine on a router) say what an item does and what a route returns.
"""

import logging
import math
import socket
import threading
import time
from collections.abc import Callable, Iterable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any, Self, cast
from urllib.parse import parse_qs, urlsplit

import zenoh

from daq.dashboard.api import history_document, latest_document
from daq.dashboard.history import PressureHistory
from daq.live.feed import Item, LiveFeed, apply_item
from daq.live.state import LiveState
from daq.live.viewer import ViewerConfig
from daq.payloads import JsonObject, json_bytes
from dbc.errors import PortalDaqError

logger = logging.getLogger(__name__)

PAGE = "static/index.html"
#: The hub thread checks for ``close`` this often while no payload comes.
HUB_WAIT_S = 0.1
#: Host names always accepted in the ``Host`` header.
LOCAL_HOSTS = ("localhost", "127.0.0.1", "::1")
_WILDCARDS = ("", "0.0.0.0", "::")


#: (HTTP status, content type, body) of a GET.
Response = tuple[int, str, bytes]


class HubServer:
    """What every dashboard shares: a feed drained by one hub thread, an HTTP server.

    Subclasses say what an item does (:meth:`_apply`, called under :attr:`_lock`)
    and what a GET returns (:meth:`respond`, which takes the lock itself).
    """

    def __init__(
        self,
        feed: LiveFeed,
        address: tuple[str, int],
        *,
        allowed_hosts: Iterable[str] = (),
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.address = address
        #: Host names accepted in a request's ``Host`` header (lower case).
        self.allowed_hosts = frozenset(
            name.lower()
            for name in (*LOCAL_HOSTS, *allowed_hosts, address[0])
            if name not in _WILDCARDS
        )
        self.feed = feed
        self._clock = clock
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._server: _Server | None = None
        self._threads: list[threading.Thread] = []
        self._closed = False

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def url(self) -> str:
        """``http://host:port/`` as bound (the real port when 0 was asked for)."""
        if self._server is None:
            raise RuntimeError("the dashboard is not started")
        host, port = self._server.server_address[:2]
        host = host.decode() if isinstance(host, bytes) else host
        return f"http://{f'[{host}]' if ':' in host else host}:{port}/"

    def start(self) -> None:
        """Bind the HTTP address, subscribe, start the threads; PortalDaqError when it cannot."""
        if self._server is not None:
            return
        host, port = self.address
        try:
            self._server = _Server((host, port), _Handler, self)
        except OSError as exc:
            raise PortalDaqError(
                f"HTTP: cannot listen on {host}:{port}: {exc.strerror or exc} "
                "(is another dashboard running? choose another --http)"
            ) from exc
        self.feed.start()
        self._threads = [
            threading.Thread(target=self._hub, name="dashboard-hub", daemon=True),
            threading.Thread(
                target=self._server.serve_forever,
                kwargs={"poll_interval": 0.2},
                name="dashboard-http",
                daemon=True,
            ),
        ]
        for thread in self._threads:
            thread.start()

    def close(self) -> None:
        """Stop serving, undeclare the subscribers (the session stays open). Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
        for thread in self._threads:
            thread.join()
        self.feed.close()

    def respond(self, path: str, query: dict[str, list[str]]) -> Response:
        """The answer to ``GET path?query`` (HTTP threads)."""
        raise NotImplementedError

    def _apply(self, item: Item) -> None:
        """Apply one feed item (hub thread, under the lock)."""
        raise NotImplementedError

    def _hub(self) -> None:
        while not self._stop.is_set():
            item = self.feed.wait(HUB_WAIT_S)
            if item is None:
                continue
            with self._lock:
                self._apply(item)


def page(name: str) -> bytes:
    """A page of ``static/``; PortalDaqError when the installation lacks it."""
    try:
        return resources.files("daq.dashboard").joinpath(name).read_bytes()
    except OSError as exc:
        raise PortalDaqError(f"dashboard page {name} missing: reinstall portal-daq") from exc


def html(body: bytes) -> Response:
    return 200, "text/html; charset=utf-8", body


def json_response(document: JsonObject, code: int = 200) -> Response:
    return code, "application/json", json_bytes(document)


def not_found(path: str) -> Response:
    return json_response({"error": f"no route {path}"}, 404)


def history_query(query: dict[str, list[str]]) -> tuple[float | None, int | None]:
    """``since`` and ``generation`` of ``/api/history``; None when missing or malformed."""
    return _number(query, "since", float), _number(query, "generation", int)


class Dashboard(HubServer):
    """Serves ``viewer``'s service on ``address`` (host, port; port 0: any free one)."""

    def __init__(
        self,
        session: zenoh.Session,
        viewer: ViewerConfig,
        address: tuple[str, int],
        *,
        allowed_hosts: Iterable[str] = (),
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        feed = LiveFeed(session, viewer.prefix, clock=clock)
        super().__init__(feed, address, allowed_hosts=allowed_hosts, clock=clock)
        self.viewer = viewer
        self._state = LiveState(viewer.prefix)
        self._history = PressureHistory(viewer.legs)
        self._page = b""

    def start(self) -> None:
        self._page = page(PAGE)
        super().start()

    def latest(self) -> JsonObject:
        linked = self.feed.linked()
        with self._lock:
            self._state.linked = linked
            return latest_document(
                self.viewer,
                self._state,
                self._clock(),
                dropped=self.feed.dropped,
                missed=self.feed.missed,
            )

    def history(self, since_s: float | None, generation: int | None) -> JsonObject:
        with self._lock:
            return history_document(self._history, since_s, generation)

    def respond(self, path: str, query: dict[str, list[str]]) -> Response:
        if path in ("/", "/index.html"):
            return html(self._page)
        if path == "/api/latest":
            return json_response(self.latest())
        if path == "/api/history":
            return json_response(self.history(*history_query(query)))
        return not_found(path)

    def _apply(self, item: Item) -> None:
        before = self._state.ground
        apply_item(self._state, item)
        ground = self._state.ground
        if ground is not None and ground is not before:
            self._history.add(ground.value)


class _Server(ThreadingHTTPServer):
    daemon_threads = True

    def __init__(
        self, address: tuple[str, int], handler: type[BaseHTTPRequestHandler], hub: HubServer
    ) -> None:
        self.hub = hub
        if ":" in address[0]:
            self.address_family = socket.AF_INET6
        super().__init__(address, handler)


class _Handler(BaseHTTPRequestHandler):
    server_version = "portal-daq-dashboard"

    def do_GET(self) -> None:
        hub = cast(_Server, self.server).hub
        url = urlsplit(self.path)
        if not host_allowed(self.headers.get("Host"), hub.allowed_hosts):
            error = "Host not allowed (see portal-daq dashboard --allow-host)"
            self._send(*json_response({"error": error}, 403))
        else:
            self._send(*hub.respond(url.path, parse_qs(url.query)))

    def _send(self, code: int, content_type: str, body: bytes) -> None:
        self.send_response(code)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        try:
            self.wfile.write(body)
        except (BrokenPipeError, ConnectionResetError):  # the browser went away
            pass

    def log_message(self, fmt: str, *args: Any) -> None:
        logger.debug("%s %s", self.address_string(), fmt % args)


def host_allowed(header: str | None, allowed: frozenset[str]) -> bool:
    """Whether a ``Host`` header (``name``, ``name:port``, ``[v6]:port``) names an allowed host.

    >>> allowed = frozenset({"localhost", "::1"})
    >>> host_allowed("localhost:8080", allowed), host_allowed("[::1]:80", allowed)
    (True, True)
    >>> host_allowed("evil.example:8080", allowed), host_allowed(None, allowed)
    (False, False)
    """
    if not header:
        return False
    try:
        name = urlsplit(f"//{header.strip()}").hostname
    except ValueError:
        return False
    return name is not None and name in allowed


def _number(query: dict[str, list[str]], name: str, kind: Callable[[str], Any]) -> Any:
    """``kind(query[name])``, or None when missing, malformed or not finite."""
    try:
        value = kind(query[name][0])
    except (KeyError, IndexError, ValueError):
        return None
    return value if math.isfinite(value) else None
