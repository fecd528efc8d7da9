"""Rendering the monitor: the viewer's state to lines of text. Pure: no terminal, no clock.

One row per leg: filtered force (kN), contact pressure (kPa), a bar against the
pressure limit, contact, the soil metrics (peak, time above the limit) and
validity with the estimator's reasons. Above them the service's status line
and the weight check, below them the stability margin (``STABILITY WARNING`` under
``[stability] warning_margin_m``); "waiting for ..." until something arrived, "STALE ..."
once it stops arriving. :func:`render` is the curses screen, :func:`plain_line`
one line for logs (``--plain``).

The bar spans 0 .. 1.5 x limit in :data:`BAR_CELLS` cells: ``#`` below the
limit, ``!`` above it, ``|`` marks the limit, ``.`` is empty::

    [##########..........|.........]   50%      100 kPa, limit 200 kPa
    [####################!!!!!.....]  125%      250 kPa
"""

import time
from collections.abc import Iterable
from dataclasses import dataclass

from daq.live.state import GROUND, STATUS, LegMetrics, LegReading, LiveState, StatusReading
from daq.live.viewer import ViewerConfig

#: Cells of the pressure bar, and the pressure (in limits) a full bar stands for.
BAR_CELLS = 30
BAR_FULL_SCALE = 1.5
#: Above this fraction of the limit a leg's row is a warning.
WARN_FRACTION = 0.8

#: Tones of a line (the curses loop colours them): title, normal, ok, warn, alarm, dim.
TITLE, NORMAL, OK, WARN, ALARM, DIM = "title", "normal", "ok", "warn", "alarm", "dim"

HEADER = (
    f"{'LEG':<8} {'FORCE kN':>9} {'PRESSURE kPa':>12}  {'vs LIMIT':<{BAR_CELLS + 2}} {'':>5}  "
    f"{'CONTACT':<7} {'PEAK kPa':>9} {'ABOVE s':>8}  VALIDITY"
)


@dataclass(frozen=True, slots=True)
class Line:
    text: str
    tone: str = NORMAL


def render(viewer: ViewerConfig, state: LiveState, now_s: float) -> list[Line]:
    """The monitor's screen at ``now_s`` (the monotonic clock the state was stamped with)."""
    limit_Pa = viewer.pressure_limit_Pa
    lines = [
        Line(
            f"portal-daq monitor  {viewer.prefix}  pressure limit {_kPa(limit_Pa)} kPa  (q: quit)",
            TITLE,
        ),
        status_line(viewer, state, now_s),
        ground_line(viewer, state, now_s),
        Line(""),
        Line(HEADER, TITLE),
    ]
    ground = state.ground
    stale = ground is not None and ground.age_s(now_s) > viewer.ground_stale_s
    metrics = state.metrics.value.legs if state.metrics is not None else {}
    for leg in leg_names(viewer, state):
        reading = ground.value.legs.get(leg) if ground is not None else None
        text, tone = leg_row(leg, reading, metrics.get(leg), limit_Pa)
        lines.append(Line(text, DIM if stale or ground is None else tone))
    stability = stability_line(viewer, state)
    lines += [
        Line(""),
        Line(stability.text, DIM if stale else stability.tone),
        Line(
            f"bar: 0 .. {_kPa(BAR_FULL_SCALE * limit_Pa)} kPa, '|' the limit "
            f"{_kPa(limit_Pa)} kPa, '!' above it",
            DIM,
        ),
    ]
    return lines


def render_text(viewer: ViewerConfig, state: LiveState, now_s: float) -> list[str]:
    return [line.text for line in render(viewer, state, now_s)]


def status_line(viewer: ViewerConfig, state: LiveState, now_s: float) -> Line:
    received = state.status
    if received is None:
        return Line(state.waiting_for(STATUS), WARN)
    age_s = received.age_s(now_s)
    summary = status_summary(received.value)
    if age_s > viewer.status_stale_s:
        return Line(f"STALE: no status for {age_s:.1f} s; last: {summary}", ALARM)
    status = received.value
    tone = OK if status.bus_state == "up" and status.healthy is not False else ALARM
    return Line(f"{summary}, status {age_s:.1f} s ago", tone)


def status_summary(status: StatusReading) -> str:
    """E.g. ``bus up (socketcan can0), 600 frames/s, 0 bad, 0 dropped, healthy``."""
    where = " ".join(part for part in (status.bus_interface, status.bus_channel) if part)
    bus = f"bus {status.bus_state}" + (f" ({where})" if where else "")
    if status.bus_reason and status.bus_state != "up":
        bus += f": {status.bus_reason}"
    return (
        f"{bus}, {_number(status.frames_per_s, 0)} frames/s, {status.frames_bad} bad, "
        f"{status.dropped} dropped, {health_text(status)}"
    )


def health_text(status: StatusReading) -> str:
    """``healthy``, or ``UNHEALTHY: `` and the status's problems (a recording stopped,
    an unreached endpoint: nothing else on the screen says so), or ``health unknown``."""
    if status.healthy is False and status.problems:
        return "UNHEALTHY: " + "; ".join(status.problems)
    return {True: "healthy", False: "UNHEALTHY", None: "health unknown"}[status.healthy]


def ground_line(viewer: ViewerConfig, state: LiveState, now_s: float) -> Line:
    received = state.ground
    if received is None:
        return Line(state.waiting_for(GROUND), WARN)
    ground = received.value
    text = (
        f"weight check: {_kN(ground.total_force_N)} kN on the feet of "
        f"{_kN(ground.weight_N)} kN, residual {_kN(ground.residual_N, signed=True)} kN, "
        f"{_number(ground.legs_in_contact, 0)} legs in contact, "
        + ("complete" if ground.complete else "incomplete (a leg is invalid)")
    )
    age_s = received.age_s(now_s)
    if age_s > viewer.ground_stale_s:
        return Line(f"STALE: no ground for {age_s:.1f} s; last values shown. {text}", ALARM)
    return Line(text, OK if ground.complete else WARN)


def stability_line(viewer: ViewerConfig, state: LiveState) -> Line:
    """The stability margin against ``[stability] warning_margin_m``."""
    warning_m = viewer.warning_margin_m
    if warning_m is None:
        return Line("stability: not configured ([stability] in the machine config)", DIM)
    ground = state.ground
    margin = ground.value.stability if ground is not None else None
    if margin is None:
        return Line(
            "stability: - (fewer than three feet down, an invalid leg or no bridge pose)", DIM
        )
    cop = margin.cop_m
    text = (
        f"stability margin {margin.margin_m:.2f} m (warning below {warning_m:.2f} m), "
        + (f"centre of pressure ({cop[0]:.2f}, {cop[1]:.2f}) m, " if cop else "")
        + f"feet {' '.join(margin.legs)}"
    )
    if margin.margin_m < warning_m:
        return Line("STABILITY WARNING: " + text, ALARM)
    return Line(text, OK)


def leg_row(
    leg: str, reading: LegReading | None, metrics: LegMetrics | None, limit_Pa: float
) -> tuple[str, str]:
    """One leg's row and its tone."""
    pressure_Pa = reading.pressure_Pa if reading is not None else None
    contact = "-" if reading is None else ("ground" if reading.contact else "air")
    validity = "-" if reading is None else _validity(reading)
    text = (
        f"{leg:<8} {_kN(reading.force_N if reading else None):>9} {_kPa(pressure_Pa):>12}  "
        f"{pressure_bar(pressure_Pa, limit_Pa)} {_percent(pressure_Pa, limit_Pa):>5}  "
        f"{contact:<7} {_kPa(metrics.peak_pressure_Pa if metrics else None):>9} "
        f"{_number(metrics.time_above_limit_s if metrics else None, 1):>8}  {validity}"
    )
    if reading is None:
        return text, DIM
    if not reading.valid or (pressure_Pa is not None and pressure_Pa > limit_Pa):
        return text, ALARM
    if pressure_Pa is not None and pressure_Pa > WARN_FRACTION * limit_Pa:
        return text, WARN
    return text, OK


def pressure_bar(pressure_Pa: float | None, limit_Pa: float, cells: int = BAR_CELLS) -> str:
    """``[####....|...]``: the pressure against the limit (see the module docstring).

    >>> pressure_bar(100e3, 200e3, cells=15)
    '[#####.....|....]'
    >>> pressure_bar(None, 200e3, cells=15)
    '[               ]'
    """
    if pressure_Pa is None:
        return "[" + " " * cells + "]"
    limit_cell = round(cells / BAR_FULL_SCALE)
    filled = min(cells, max(0, round(pressure_Pa / (BAR_FULL_SCALE * limit_Pa) * cells)))
    marks = []
    for cell in range(cells):
        if cell < filled:
            marks.append("#" if cell < limit_cell else "!")
        else:
            marks.append("|" if cell == limit_cell else ".")
    return "[" + "".join(marks) + "]"


def plain_line(viewer: ViewerConfig, state: LiveState, now_s: float, wall_s: float) -> str:
    """One line for ``--plain``: local time, status, the weight check, then every leg with
    its soil metrics (peak pressure, time above the limit), as the full screen has them.

    E.g. ``12:00:01 bus up 600 frames/s 0 bad 0 dropped healthy | weight 184.1 of 184.4 kN
    residual -0.3 kN 6 in contact complete | SB1_F1 61.2 kN 185.5 kPa ground ok peak
    312.3 kPa above 4.2 s | ...`` (one line).
    """
    parts = [time.strftime("%H:%M:%S", time.localtime(wall_s))]
    status = state.status
    if status is None:
        parts.append(state.waiting_for(STATUS))
    else:
        s = status.value
        age_s = status.age_s(now_s)
        stale = f"STALE status {age_s:.1f} s: " if age_s > viewer.status_stale_s else ""
        parts.append(
            f"{stale}bus {s.bus_state} {_number(s.frames_per_s, 0)} frames/s "
            f"{s.frames_bad} bad {s.dropped} dropped {health_text(s)}"
        )
    received = state.ground
    if received is None:
        return " ".join(parts) + f" | {state.waiting_for(GROUND)}"
    line = " ".join(parts)
    age_s = received.age_s(now_s)
    if age_s > viewer.ground_stale_s:
        line += f" | STALE ground {age_s:.1f} s"
    ground = received.value
    line += (
        f" | weight {_kN(ground.total_force_N)} of {_kN(ground.weight_N)} kN residual "
        f"{_kN(ground.residual_N, signed=True)} kN {_number(ground.legs_in_contact, 0)} in "
        f"contact {'complete' if ground.complete else 'incomplete'}"
    )
    metrics = state.metrics.value.legs if state.metrics is not None else {}
    for leg in leg_names(viewer, state):
        reading = ground.legs.get(leg)
        if reading is None:
            line += f" | {leg} -"
            continue
        line += (
            f" | {leg} {_kN(reading.force_N)} kN {_kPa(reading.pressure_Pa)} kPa "
            f"{'ground' if reading.contact else 'air'} {_validity(reading).replace(' ', ':')}"
        )
        leg_metrics = metrics.get(leg)
        if leg_metrics is not None:
            line += (
                f" peak {_kPa(leg_metrics.peak_pressure_Pa)} kPa above "
                f"{_number(leg_metrics.time_above_limit_s, 1)} s"
            )
    margin = ground.stability
    if viewer.warning_margin_m is not None:
        if margin is None:
            line += " | margin -"
        else:
            low = "MARGIN WARNING " if margin.margin_m < viewer.warning_margin_m else ""
            line += f" | {low}margin {margin.margin_m:.2f} m"
    return line


def leg_names(viewer: ViewerConfig, state: LiveState) -> list[str]:
    """The configured legs in order, then any other leg the service reports."""
    extra: Iterable[str] = state.ground.value.legs if state.ground is not None else ()
    return list(dict.fromkeys([*viewer.legs, *extra]))


def _validity(reading: LegReading) -> str:
    if reading.valid:
        return "ok"
    return "INVALID " + (",".join(reading.reasons) or "?")


def _kN(value_N: float | None, signed: bool = False) -> str:
    if value_N is None:
        return "-"
    return f"{value_N / 1e3:+.1f}" if signed else f"{value_N / 1e3:.1f}"


def _kPa(value_Pa: float | None) -> str:
    return "-" if value_Pa is None else f"{value_Pa / 1e3:.1f}"


def _percent(pressure_Pa: float | None, limit_Pa: float) -> str:
    return "-" if pressure_Pa is None else f"{pressure_Pa / limit_Pa * 100:.0f}%"


def _number(value: float | None, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"
