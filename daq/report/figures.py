"""The report's pictures, drawn from a :class:`~daq.report.content.ReportContent`.

matplotlib's object API on the Agg canvas (no pyplot state, no display); each function
returns a :class:`~matplotlib.figure.Figure`, :func:`png_bytes` renders one. Legs of
the usual ``<BASE>_<FOOT>`` names keep one colour and marker per foot and one line
style per base (SB1 solid, SB2 dashed), as in ``python -m sim_bridge plot``; the
markers are staggered and later feet drawn thinner, so legs with equal values (SB1_F2
and SB1_F3 while the bridge is between them) stay apart. Other names get a colour
each. Times are as :class:`~daq.report.content.TimeAxis` shows them: time in cycle
when the recording has ``MACHINE_STATE``, else seconds since its first frame.
"""

import io
import math
import re
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from daq.report.content import ReportContent, on_axis

FOOT_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")
FOOT_MARKERS = ("o", "s", "^", "D", "v", "P")
BASE_STYLES = ("-", "--", ":", "-.")
OTHER_COLOURS = (*FOOT_COLOURS, "tab:pink", "tab:gray", "tab:olive", "tab:cyan")
#: The paper's bounds for the stance legs (section 3.4): 50 % within 1 kN, 95 % within 3.6 kN.
PAPER_ABS50_N = 1000.0
PAPER_ABS95_N = 3600.0
DPI = 120
_LEG_NAME = re.compile(r"(?P<base>.+?)_F?(?P<foot>\d+)$")
#: Marker spacing along a line, as a fraction of the axes' diagonal; each leg's markers
#: start a little further on, so that legs on top of one another show both.
MARK_STEP = 0.1


def leg_styles(legs: Sequence[str]) -> dict[str, dict[str, Any]]:
    """Colour, line style, marker and line width per leg (``Axes.plot`` keywords).

    >>> style = leg_styles(["SB1_F1", "SB2_F1"])["SB2_F1"]
    >>> style["color"], style["linestyle"], style["marker"]
    ('tab:blue', '--', 'o')
    """
    parsed = [_LEG_NAME.match(leg) for leg in legs]
    styles: dict[str, dict[str, Any]] = {}
    for index, (leg, match) in enumerate(zip(legs, parsed, strict=True)):
        if all(parsed) and match:
            bases = sorted({m.group("base") for m in parsed if m})
            feet = sorted({int(m.group("foot")) for m in parsed if m})
            foot = feet.index(int(match.group("foot")))
            colour = FOOT_COLOURS[foot % len(FOOT_COLOURS)]
            line = BASE_STYLES[bases.index(match.group("base")) % len(BASE_STYLES)]
        else:
            foot, colour, line = index, OTHER_COLOURS[index % len(OTHER_COLOURS)], "-"
        styles[leg] = {
            "color": colour,
            "linestyle": line,
            "marker": FOOT_MARKERS[foot % len(FOOT_MARKERS)],
            "markersize": 4,
            "markevery": (MARK_STEP * (index / max(len(legs), 1)), MARK_STEP),
            "linewidth": max(2.0 - 0.4 * (foot % 4), 0.8),
        }
    return styles


def _figure(width_in: float = 11.0, height_in: float = 5.5) -> Figure:
    figure = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def png_bytes(figure: Figure) -> bytes:
    """The figure as PNG."""
    out = io.BytesIO()
    figure.savefig(out, format="png", dpi=DPI)
    return out.getvalue()


def _set_time_axis(axes: Axes, content: ReportContent) -> None:
    axes.set_xlabel(content.time.label)
    end = content.time.at(content.recording.end_t_s)
    if content.time.in_cycle:  # the longest cycle's end
        end = max(content.time.before(c.end_s) for c in content.cycles)
    start = min(0.0, content.time.at(content.recording.start_t_s))
    # NaN: a cycle of no duration (every frame of one time stamp) has no time just before its end
    start, end = (t if math.isfinite(t) else 0.0 for t in (start, end))
    axes.set_xlim(start, max(end, start + 1e-3))


def _phases(axes: Axes, content: ReportContent, labels: bool) -> None:
    """Shade every other movement phase and name them above the axes. On time in cycle,
    each cycle's phases are laid over one another, named once (from the longest cycle);
    on wall time, dotted lines mark the cycle starts."""
    time = content.time
    longest = max(content.cycles, key=lambda c: c.duration_s)
    width_s = max(time.before(longest.end_s) - time.at(longest.start_s), 1e-9)
    transform = axes.get_xaxis_transform()
    for cycle in content.cycles if time.in_cycle else content.cycles[:1]:
        spans = [
            (max(span.start_s, cycle.start_s), min(span.end_s, cycle.end_s), span.phase)
            for span in content.phases
            if not time.in_cycle or (span.end_s > cycle.start_s and span.start_s < cycle.end_s)
        ]
        for index, (start_s, end_s, phase) in enumerate(spans):
            x0, x1 = time.at(start_s), time.at(end_s)
            if index % 2:
                axes.axvspan(x0, x1, color="0.93", zorder=0)
            if labels and cycle is longest and x1 - x0 > 0.03 * width_s:
                axes.text(
                    (x0 + x1) / 2,
                    1.01,
                    phase.replace("_", " "),
                    transform=transform,
                    ha="center",
                    va="bottom",
                    fontsize="x-small",
                )
    if not time.in_cycle:
        for cycle in content.cycles[1:]:
            axes.axvline(time.at(cycle.start_s), color="0.4", linewidth=0.8, linestyle=":")


def _legend_below(figure: Figure, axes: Axes, columns: int = 6) -> None:
    handles, labels = axes.get_legend_handles_labels()
    if handles:
        figure.legend(handles, labels, loc="outside lower center", ncol=columns, fontsize="small")


def time_series_figure(content: ReportContent, quantity: str) -> Figure:
    """Per foot over time (filtered, invalid samples as gaps): ``quantity`` is
    ``"pressure"`` (kPa, Figure 7; a foot not in contact is drawn at 0 kPa, it has no
    soil pressure) or ``"force"`` (kN, Figure 8; the cylinder-derived force throughout)."""
    if quantity not in ("pressure", "force"):
        raise ValueError(f"quantity must be 'pressure' or 'force', got {quantity!r}")
    recording = content.recording
    figure = _figure()
    axes = figure.subplots()
    styles = leg_styles(list(recording.legs))
    for leg, track in recording.legs.items():
        if quantity == "pressure":
            values = np.where(track.contact, track.pressure_Pa, 0.0)
        else:
            values = track.force_N
        x, shown = on_axis(content.time, track.t_s, values, track.valid, content.gap_after_s[leg])
        style = styles[leg]
        if not np.isfinite(shown).any():  # all gap: matplotlib cannot space markers on it
            style = {**style, "markevery": None}
        axes.plot(x, shown / 1e3, label=leg, **style)
    _phases(axes, content, labels=True)
    if quantity == "pressure":
        limit_kPa = content.settings.pressure_limit_Pa / 1e3
        axes.axhline(limit_kPa, color="tab:red", linewidth=0.8, linestyle=(0, (4, 3)))
        axes.annotate(
            f"limit {limit_kPa:g} kPa",
            (1.0, limit_kPa),
            xycoords=("axes fraction", "data"),
            xytext=(-4, 3),
            textcoords="offset points",
            ha="right",
            fontsize="x-small",
            color="tab:red",
        )
        axes.set_ylabel("contact pressure / kPa")
        axes.set_ylim(bottom=min(0.0, axes.get_ylim()[0]))
        # A legend entry without a line: what 0 kPa means here.
        axes.plot([], [], linestyle="none", label="not in contact: 0 kPa")
        what = "Contact pressure per foot"
    else:
        axes.set_ylabel("vertical foot force / kN")
        what = "Ground force per foot"
    _set_time_axis(axes, content)
    axes.grid(True, alpha=0.3)
    figure.suptitle(f"{recording.machine_id}: {what} (filtered; gaps: invalid or missing)")
    _legend_below(figure, axes, columns=7)
    return figure


def cycle_metrics_figure(content: ReportContent) -> Figure:
    """Bars per foot, one per cycle: the peak and the near-constant pressure, kPa."""
    legs = list(content.recording.legs)
    cycles = content.cycles
    figure = _figure(11.0, 6.5)
    peak_axes, near_axes = figure.subplots(2, 1, sharex=True)
    width = 0.8 / max(len(cycles), 1)
    x = np.arange(len(legs), dtype=np.float64)
    values = {(m.cycle, m.leg): m.metrics for m in content.metrics}
    colours = [f"C{i % 10}" for i in range(len(cycles))]
    for index, cycle in enumerate(cycles):
        offset = (index - (len(cycles) - 1) / 2) * width
        peak = [values[cycle, leg].peak_pressure_Pa / 1e3 for leg in legs]
        near = [values[cycle, leg].near_constant_pressure_Pa / 1e3 for leg in legs]
        for axes, heights in ((peak_axes, peak), (near_axes, near)):
            bars = axes.bar(
                x + offset, np.nan_to_num(heights), width, color=colours[index], label=cycle.label
            )
            if len(cycles) <= 3:
                axes.bar_label(
                    bars, [f"{h:.0f}" if math.isfinite(h) else "n/a" for h in heights], fontsize=7
                )
    window_s = content.settings.near_constant_window_s
    limit_kPa = content.settings.pressure_limit_Pa / 1e3
    for axes in (peak_axes, near_axes):
        axes.axhline(limit_kPa, color="tab:red", linewidth=0.8, linestyle=(0, (4, 3)))
        axes.grid(True, axis="y", alpha=0.3)
        axes.margins(y=0.15)
    peak_axes.set_ylabel("peak / kPa")
    near_axes.set_ylabel(f"near-constant / kPa\n(best {window_s:g} s mean)")
    near_axes.set_xticks(x, legs)
    figure.suptitle(
        f"{content.recording.machine_id}: peak and near-constant contact pressure per cycle "
        f"(dashed: limit {limit_kPa:g} kPa)"
    )
    _legend_below(figure, peak_axes, columns=min(len(cycles), 8))
    return figure


def _paper_bounds(axes: Axes) -> None:
    for bound_N, dashes in ((PAPER_ABS50_N, ":"), (PAPER_ABS95_N, "--")):
        for sign in (1, -1):
            axes.axhline(sign * bound_N / 1e3, color="0.5", linewidth=0.7, linestyle=dashes)
    axes.axhline(0.0, color="0.2", linewidth=0.6)


def comparison_figure(content: ReportContent) -> Figure:
    """Figure 5: calculated and true force of the most loaded leg, and their difference
    (stance samples red, swing samples grey)."""
    leg = content.most_loaded
    if leg is None:
        raise ValueError("no leg with matched truth: nothing to compare")
    comparison = content.comparisons[leg]
    gap_s = content.gap_after_s.get(leg, math.inf)
    figure = _figure(11.0, 6.5)
    force_axes, difference_axes = figure.subplots(
        2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]}
    )
    for values, label, colour, line in (
        (comparison.true_N, "true (simulation)", "black", "-"),
        (comparison.calculated_N, "calculated: eq. (4), median-filtered", "tab:blue", "--"),
    ):
        x, shown = on_axis(content.time, comparison.t_s, values, None, gap_s)
        force_axes.plot(x, shown / 1e3, label=label, color=colour, linestyle=line, linewidth=1.0)
    for part, colour, label in (
        (comparison.stance, "tab:red", "on the ground"),
        (~comparison.stance, "0.6", "lifted"),
    ):
        x, difference = on_axis(content.time, comparison.t_s, comparison.deviation_N, part, gap_s)
        difference_axes.plot(x, difference / 1e3, color=colour, linewidth=0.9, label=label)
    _paper_bounds(difference_axes)
    for axes in (force_axes, difference_axes):
        _phases(axes, content, labels=axes is force_axes)
        axes.grid(True, alpha=0.3)
    force_axes.set_ylabel("vertical foot force / kN")
    difference_axes.set_ylabel("calculated - true / kN")
    _set_time_axis(difference_axes, content)
    stats = content.deviations[leg]
    figure.suptitle(
        f"{content.recording.machine_id}: calculated vs. true ground force of {leg}, "
        f"the most loaded leg\n|difference| on the ground: 50 % <= {stats.abs50_N / 1e3:.2f} "
        f"kN, 95 % <= {stats.abs95_N / 1e3:.2f} kN (grey lines: ±1 and ±3.6 kN, the paper's "
        "bounds)"
    )
    force_axes.legend(loc="upper left", fontsize="small")
    difference_axes.legend(loc="upper left", fontsize="x-small", ncol=2)
    return figure


def deviation_boxplot_figure(content: ReportContent) -> Figure:
    """Figure 6: box plots of the deviation (calculated - true) per foot, kN: the stance
    samples (foot on the ground, what the paper compares) and, grey beside them, the
    swing samples (leg lifted), with the number of samples of each under the foot."""
    legs = [leg for leg, c in content.comparisons.items() if c.t_s.size]
    if not legs:
        raise ValueError("no leg with matched truth: nothing to compare")
    figure = _figure(11.0, 5.5)
    axes = figure.subplots()
    x = np.arange(1, len(legs) + 1, dtype=np.float64)
    contact_kN = content.settings.contact_on_N / 1e3
    for part, offset, colour, label in (
        (True, -0.18, "black", f"on the ground (true force > {contact_kN:g} kN)"),
        (False, 0.18, "0.6", "lifted"),
    ):
        comparisons = [content.comparisons[leg] for leg in legs]
        data = [c.deviation_N[c.stance if part else ~c.stance] / 1e3 for c in comparisons]
        shown = [i for i, values in enumerate(data) if values.size]
        if not shown:
            continue
        boxes = axes.boxplot(
            [data[i] for i in shown],
            positions=x[shown] + offset,
            whis=1.5,
            widths=0.3,
            manage_ticks=False,
            flierprops={"marker": ".", "markersize": 2, "alpha": 0.4, "markeredgecolor": colour},
            medianprops={"color": "tab:red"},
            boxprops={"color": colour},
            whiskerprops={"color": colour},
            capprops={"color": colour},
        )
        boxes["boxes"][0].set_label(label)
    counts = {
        leg: (content.deviations[leg].samples, content.swing_deviations[leg].samples)
        for leg in legs
    }
    axes.set_xticks(x, [f"{leg}\n{counts[leg][0]} / {counts[leg][1]}" for leg in legs])
    _paper_bounds(axes)
    axes.set_ylabel("calculated - true foot force / kN")
    axes.set_xlabel("foot; samples on the ground / lifted")
    axes.grid(True, axis="y", alpha=0.3)
    axes.legend(loc="upper right", fontsize="small")
    figure.suptitle(
        f"{content.recording.machine_id}: deviation of the calculated from the true ground "
        "force per foot\n(black: on the ground, against the paper's bounds ±1 and ±3.6 kN; "
        "grey: lifted; box: quartiles, whiskers: 1.5 IQR)"
    )
    return figure
