"""The monitor's loops: curses full screen, or one plain line per second. Thin I/O only.

Both drain the :class:`~daq.live.feed.LiveFeed` into a view's state and draw it:
:class:`MachineView` (one service: :class:`~daq.live.state.LiveState`,
:mod:`daq.monitor.view`) or :class:`FleetView` (every machine on a router:
:class:`~daq.live.fleet.FleetState`, :mod:`daq.monitor.fleet_view`). They end
when ``stop`` is set (SIGINT/SIGTERM), after ``duration_s``, or on ``q`` in the
curses screen.
"""

import curses
import locale
import os
import time
from collections.abc import Callable
from typing import Protocol, TextIO

from daq.live.feed import LiveFeed
from daq.live.fleet import FleetSettings, FleetState
from daq.live.state import LiveState
from daq.live.viewer import ViewerConfig
from daq.monitor.fleet_view import fleet_plain_line, fleet_render
from daq.monitor.view import ALARM, DIM, OK, TITLE, WARN, Line, plain_line, render
from daq.stop_signal import Stop

#: The curses screen is redrawn this often.
REFRESH_S = 0.25
#: ``--plain`` writes a line this often.
PLAIN_PERIOD_S = 1.0


class View(Protocol):
    """What the loops draw: a state fed from the feed, as a screen or one line."""

    def drain(self) -> None: ...
    def render(self, now_s: float) -> list[Line]: ...
    def plain(self, now_s: float, wall_s: float) -> str: ...


class MachineView:
    """One service's view (``portal-daq monitor --config FILE``)."""

    def __init__(self, viewer: ViewerConfig, feed: LiveFeed) -> None:
        self.viewer = viewer
        self.feed = feed
        self.state = LiveState(viewer.prefix)

    def drain(self) -> None:
        self.feed.drain(self.state)

    def render(self, now_s: float) -> list[Line]:
        return render(self.viewer, self.state, now_s)

    def plain(self, now_s: float, wall_s: float) -> str:
        return plain_line(self.viewer, self.state, now_s, wall_s)


class FleetView:
    """Every machine's view (``portal-daq monitor --fleet``); the feed follows liveliness."""

    def __init__(self, settings: FleetSettings, feed: LiveFeed) -> None:
        self.settings = settings
        self.feed = feed
        self.fleet = FleetState(settings)

    def drain(self) -> None:
        self.fleet.linked = self.feed.linked()
        while (item := self.feed.wait(0.0)) is not None:
            self.fleet.apply(item)

    def render(self, now_s: float) -> list[Line]:
        return fleet_render(self.settings, self.fleet.summaries(now_s), self.fleet.waiting())

    def plain(self, now_s: float, wall_s: float) -> str:
        return fleet_plain_line(self.fleet.summaries(now_s), wall_s, self.fleet.waiting())


def run_curses(
    view: View,
    stop: Stop,
    *,
    duration_s: float | None = None,
) -> None:
    """Full-screen view until stopped; the terminal is restored on every way out."""
    locale.setlocale(locale.LC_ALL, "")
    # ncurses would take an exported LINES/COLUMNS over the terminal's real (and
    # changing) size; Python's curses has no use_tioctl(), so drop them.
    for name in ("LINES", "COLUMNS"):
        os.environ.pop(name, None)
    deadline = None if duration_s is None else time.monotonic() + duration_s

    def loop(screen: "curses.window") -> None:
        _hide_cursor()
        tones = _tones()
        screen.timeout(int(REFRESH_S * 1000))
        while not stop.is_set() and (deadline is None or time.monotonic() < deadline):
            view.drain()
            _draw(screen, view.render(time.monotonic()), tones)
            if screen.getch() in (ord("q"), ord("Q")):
                break

    curses.wrapper(loop)


def run_plain(
    view: View,
    stop: Stop,
    out: TextIO,
    *,
    duration_s: float | None = None,
    period_s: float = PLAIN_PERIOD_S,
    clock: Callable[[], float] = time.monotonic,
    wall: Callable[[], float] = time.time,
) -> None:
    """One line every ``period_s`` (due times from the start, no drift) until stopped.

    With ``duration_s`` it returns at ``start + duration_s``: ``--duration 3`` writes
    three lines, ``--duration 2.5`` two.
    """
    start = clock()
    deadline = None if duration_s is None else start + duration_s
    tick = 0
    while True:
        tick += 1
        due = start + tick * period_s
        if deadline is not None and due > deadline:
            stop.wait(max(0.0, deadline - clock()))
            return
        if stop.wait(max(0.0, due - clock())):
            return
        view.drain()
        out.write(view.plain(clock(), wall()) + "\n")
        out.flush()


def _draw(screen: "curses.window", lines: list[Line], tones: dict[str, int]) -> None:
    screen.erase()
    height, width = screen.getmaxyx()
    for row, line in enumerate(lines[:height]):
        try:
            screen.addnstr(row, 0, line.text, max(0, width - 1), tones.get(line.tone, 0))
        except curses.error:  # a terminal too small for the line: skip it
            pass
    screen.refresh()


def _tones() -> dict[str, int]:
    tones = {TITLE: curses.A_BOLD, DIM: curses.A_DIM}
    if not curses.has_colors():
        return tones | {ALARM: curses.A_REVERSE}
    curses.start_color()
    curses.use_default_colors()
    for pair, (tone, colour) in enumerate(
        ((OK, curses.COLOR_GREEN), (WARN, curses.COLOR_YELLOW), (ALARM, curses.COLOR_RED)),
        start=1,
    ):
        curses.init_pair(pair, colour, -1)
        tones[tone] = curses.color_pair(pair) | (curses.A_BOLD if tone == ALARM else 0)
    return tones


def _hide_cursor() -> None:
    try:
        curses.curs_set(0)
    except curses.error:  # some terminals cannot
        pass
