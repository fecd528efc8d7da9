"""Rendering ``portal-daq monitor --fleet``: every machine's summary as text. Pure.

One row per machine (:class:`~daq.live.fleet.MachineSummary`): state (``live``,
``waiting``, ``STALE``, ``GONE n s``), health, bus, legs in contact, the highest
contact pressure and its leg, the stability margin when published, the age of
the data. :func:`fleet_render` is the curses screen, :func:`fleet_plain_line`
one line for logs (``--plain``).
"""

import time
from collections.abc import Sequence

from daq.live.fleet import GONE, LIVE, STALE, WAITING, FleetSettings, MachineSummary
from daq.monitor.view import ALARM, DIM, OK, TITLE, WARN, WARN_FRACTION, Line, _kPa, _number

HEADER = (
    f"{'MACHINE':<16} {'STATE':<9} {'HEALTH':<9} {'BUS':<8} {'CONTACT':>7} "
    f"{'MAX kPa':>8} {'AT':<8} {'MARGIN m':>8} {'AGE s':>6}"
)


def state_text(summary: MachineSummary) -> str:
    if summary.state == GONE and summary.gone_for_s is not None:
        return f"GONE {summary.gone_for_s:.0f} s"
    return summary.state.upper() if summary.state == STALE else summary.state


def machine_row(summary: MachineSummary, limit_Pa: float) -> Line:
    s = summary
    health = "?" if s.healthy is None else "healthy" if s.healthy else "UNHEALTHY"
    contact = "-" if s.legs_in_contact is None else f"{s.legs_in_contact}/{s.legs}"
    text = (
        f"{s.machine_id:<16} {state_text(s):<9} {health:<9} {s.bus_state or '-':<8} "
        f"{contact:>7} {_kPa(s.max_pressure_Pa):>8} {s.max_pressure_leg or '-':<8} "
        f"{_number(s.stability_margin_m, 2):>8} {_number(s.data_age_s, 1):>6}"
    )
    return Line(text, _tone(s, limit_Pa))


def fleet_render(
    settings: FleetSettings, summaries: Sequence[MachineSummary], waiting: str
) -> list[Line]:
    """The curses screen: a title, the header, one row per machine (none: ``waiting``,
    :meth:`FleetState.waiting <daq.live.fleet.FleetState.waiting>`)."""
    present = sum(1 for s in summaries if s.state != GONE)
    lines = [
        Line(
            f"portal-daq monitor --fleet  {settings.prefix}  {present} of {len(summaries)} "
            f"machines present  limit {_kPa(settings.pressure_limit_Pa)} kPa  (q: quit)",
            TITLE,
        ),
        Line(""),
        Line(HEADER, TITLE),
    ]
    lines += [machine_row(s, settings.pressure_limit_Pa) for s in summaries]
    if not summaries:
        lines.append(Line(waiting, DIM))
    return lines


def fleet_plain_line(summaries: Sequence[MachineSummary], wall_s: float, waiting: str) -> str:
    """One line: local time, then per machine its state, contact, max pressure, margin, age.

    E.g. ``12:00:01 pam-1 live healthy 6/6 185.5 kPa SB1_F1 margin 0.42 m age 0.1 s |
    pam-2 GONE 3 s`` (one line).
    """
    parts = [time.strftime("%H:%M:%S", time.localtime(wall_s))]
    if not summaries:
        return f"{parts[0]} no machine yet: {waiting}"
    for s in summaries:
        if s.state in (GONE, WAITING):
            parts.append(f"{s.machine_id} {state_text(s)}")
            continue
        health = "?" if s.healthy is None else "healthy" if s.healthy else "UNHEALTHY"
        contact = "-" if s.legs_in_contact is None else f"{s.legs_in_contact}/{s.legs}"
        parts.append(
            f"{s.machine_id} {state_text(s)} {health} {contact} {_kPa(s.max_pressure_Pa)} kPa "
            f"{s.max_pressure_leg or '-'} margin {_number(s.stability_margin_m, 2)} m "
            f"age {_number(s.data_age_s, 1)} s"
        )
    return parts[0] + " " + " | ".join(parts[1:])


def _tone(summary: MachineSummary, limit_Pa: float) -> str:
    if summary.state == GONE:
        return DIM
    if summary.state == STALE or summary.healthy is False:
        return ALARM
    if summary.state != LIVE:
        return DIM
    pressure_Pa = summary.max_pressure_Pa or 0.0
    margin_m = summary.stability_margin_m
    if pressure_Pa > limit_Pa or (margin_m is not None and margin_m < 0):
        return ALARM
    return WARN if pressure_Pa > WARN_FRACTION * limit_Pa else OK
