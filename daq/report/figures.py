"""The report's pictures, drawn from a :class:`~daq.report.content.ReportContent`.

matplotlib's object API on the Agg canvas (no pyplot state, no display); each function
returns a :class:`~matplotlib.figure.Figure`, :func:`png_bytes` renders one. Legs of
the usual ``<BASE>_<FOOT>`` names keep one colour per foot and one line style per base
(SB1 solid, SB2 dashed), as in ``python -m sim_bridge plot``; other names get a colour
each. Times are seconds since the recording's first frame.
"""

import io
import math
import re
from collections.abc import Sequence
from datetime import UTC, datetime

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from daq.report.content import ReportContent, with_gaps

FOOT_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")
BASE_STYLES = ("-", "--", ":", "-.")
OTHER_COLOURS = (*FOOT_COLOURS, "tab:pink", "tab:gray", "tab:olive", "tab:cyan")
#: The paper's bounds for the stance legs (section 3.4): 50 % within 1 kN, 95 % within 3.6 kN.
PAPER_ABS50_N = 1000.0
PAPER_ABS95_N = 3600.0
DPI = 120
_LEG_NAME = re.compile(r"(?P<base>.+?)_F?(?P<foot>\d+)$")


def leg_styles(legs: Sequence[str]) -> dict[str, dict[str, str]]:
    """Colour and line style per leg.

    >>> leg_styles(["SB1_F1", "SB2_F1"])["SB2_F1"]
    {'color': 'tab:blue', 'linestyle': '--'}
    """
    parsed = [_LEG_NAME.match(leg) for leg in legs]
    if all(parsed):
        bases = sorted({m.group("base") for m in parsed if m})
        feet = sorted({int(m.group("foot")) for m in parsed if m})
        return {
            leg: {
                "color": FOOT_COLOURS[feet.index(int(m.group("foot"))) % len(FOOT_COLOURS)],
                "linestyle": BASE_STYLES[bases.index(m.group("base")) % len(BASE_STYLES)],
            }
            for leg, m in zip(legs, parsed, strict=True)
            if m
        }
    return {
        leg: {"color": OTHER_COLOURS[i % len(OTHER_COLOURS)], "linestyle": "-"}
        for i, leg in enumerate(legs)
    }


def time_label(content: ReportContent) -> str:
    start = datetime.fromtimestamp(content.recording.start_t_s, UTC)
    return f"time since {start:%Y-%m-%d %H:%M:%S} UTC / s"


def _figure(width_in: float = 11.0, height_in: float = 5.5) -> Figure:
    figure = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def png_bytes(figure: Figure) -> bytes:
    """The figure as PNG."""
    out = io.BytesIO()
    figure.savefig(out, format="png", dpi=DPI)
    return out.getvalue()


def _phases(axes: Axes, content: ReportContent, labels: bool) -> None:
    """Shade every other movement phase; name them above the axes; mark cycle starts."""
    t0 = content.recording.start_t_s
    transform = axes.get_xaxis_transform()
    for index, span in enumerate(content.phases):
        if index % 2:
            axes.axvspan(span.start_s - t0, span.end_s - t0, color="0.93", zorder=0)
        if labels and span.end_s - span.start_s > 0.03 * max(content.recording.duration_s, 1e-9):
            axes.text(
                (span.start_s + span.end_s) / 2 - t0,
                1.01,
                span.phase.replace("_", " "),
                transform=transform,
                ha="center",
                va="bottom",
                fontsize="x-small",
            )
    for cycle in content.cycles[1:]:
        axes.axvline(cycle.start_s - t0, color="0.4", linewidth=0.8, linestyle=":")


def _legend_below(figure: Figure, axes: Axes, columns: int = 6) -> None:
    handles, labels = axes.get_legend_handles_labels()
    if handles:
        figure.legend(handles, labels, loc="outside lower center", ncol=columns, fontsize="small")


def time_series_figure(content: ReportContent, quantity: str) -> Figure:
    """Per foot over time (filtered, invalid samples as gaps): ``quantity`` is
    ``"pressure"`` (kPa, Figure 7) or ``"force"`` (kN, Figure 8)."""
    if quantity not in ("pressure", "force"):
        raise ValueError(f"quantity must be 'pressure' or 'force', got {quantity!r}")
    recording = content.recording
    figure = _figure()
    axes = figure.subplots()
    styles = leg_styles(list(recording.legs))
    t0 = recording.start_t_s
    for leg, track in recording.legs.items():
        values = track.pressure_Pa if quantity == "pressure" else track.force_N
        t_s, shown = with_gaps(track.t_s, values, track.valid, content.gap_after_s[leg])
        style = styles[leg]
        axes.plot(
            t_s - t0,
            shown / 1e3,
            color=style["color"],
            linestyle=style["linestyle"],
            linewidth=1.1,
            label=leg,
        )
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
        what = "Contact pressure per foot"
    else:
        axes.set_ylabel("vertical foot force / kN")
        what = "Ground force per foot"
    axes.set_xlabel(time_label(content))
    axes.set_xlim(0.0, max(recording.duration_s, 1e-3))
    axes.grid(True, alpha=0.3)
    figure.suptitle(f"{recording.machine_id}: {what} (filtered; gaps: invalid or missing)")
    _legend_below(figure, axes)
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


def comparison_figure(content: ReportContent) -> Figure:
    """Figure 5: calculated and true force of the most loaded leg, and their difference."""
    leg = content.most_loaded
    if leg is None:
        raise ValueError("no leg with matched truth: nothing to compare")
    comparison = content.comparisons[leg]
    t0 = content.recording.start_t_s
    gap_s = content.gap_after_s.get(leg, math.inf)
    figure = _figure(11.0, 6.5)
    force_axes, difference_axes = figure.subplots(
        2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]}
    )
    for values, label, colour, line in (
        (comparison.true_N, "true (simulation)", "black", "-"),
        (comparison.calculated_N, "calculated: eq. (4), median-filtered", "tab:blue", "--"),
    ):
        t_s, shown = with_gaps(comparison.t_s, values, None, gap_s)
        force_axes.plot(
            t_s - t0, shown / 1e3, label=label, color=colour, linestyle=line, linewidth=1.0
        )
    t_s, difference = with_gaps(comparison.t_s, comparison.deviation_N, None, gap_s)
    difference_axes.plot(t_s - t0, difference / 1e3, color="tab:red", linewidth=0.9)
    for bound_N, dashes in ((PAPER_ABS50_N, ":"), (PAPER_ABS95_N, "--")):
        for sign in (1, -1):
            difference_axes.axhline(
                sign * bound_N / 1e3, color="0.5", linewidth=0.7, linestyle=dashes
            )
    difference_axes.axhline(0.0, color="0.2", linewidth=0.6)
    for axes in (force_axes, difference_axes):
        _phases(axes, content, labels=axes is force_axes)
        axes.grid(True, alpha=0.3)
    force_axes.set_ylabel("vertical foot force / kN")
    difference_axes.set_ylabel("calculated - true / kN")
    difference_axes.set_xlabel(time_label(content))
    difference_axes.set_xlim(0.0, max(content.recording.duration_s, 1e-3))
    stats = content.deviations[leg]
    figure.suptitle(
        f"{content.recording.machine_id}: calculated vs. true ground force of {leg}, "
        f"the most loaded leg\n|difference|: 50 % <= {stats.abs50_N / 1e3:.2f} kN, "
        f"95 % <= {stats.abs95_N / 1e3:.2f} kN (grey lines: ±1 and ±3.6 kN, the paper's bounds)"
    )
    force_axes.legend(loc="upper left", fontsize="small")
    return figure


def deviation_boxplot_figure(content: ReportContent) -> Figure:
    """Figure 6: box plots of the deviation (calculated - true) per foot, kN."""
    legs = [leg for leg, c in content.comparisons.items() if c.t_s.size]
    if not legs:
        raise ValueError("no leg with matched truth: nothing to compare")
    figure = _figure(11.0, 5.5)
    axes = figure.subplots()
    data = [content.comparisons[leg].deviation_N / 1e3 for leg in legs]
    axes.boxplot(
        data,
        tick_labels=legs,
        whis=1.5,
        widths=0.5,
        flierprops={"marker": ".", "markersize": 2, "alpha": 0.4},
        medianprops={"color": "tab:red"},
    )
    for bound_N, dashes in ((PAPER_ABS50_N, ":"), (PAPER_ABS95_N, "--")):
        for sign in (1, -1):
            axes.axhline(sign * bound_N / 1e3, color="0.5", linewidth=0.7, linestyle=dashes)
    axes.axhline(0.0, color="0.2", linewidth=0.6)
    axes.set_ylabel("calculated - true foot force / kN")
    axes.grid(True, axis="y", alpha=0.3)
    count = min(len(content.comparisons[leg].t_s) for leg in legs)
    figure.suptitle(
        f"{content.recording.machine_id}: deviation of the calculated from the true ground "
        f"force per foot\n(>= {count} matched samples each; box: quartiles, whiskers: "
        f"1.5 IQR; grey lines: ±1 and ±3.6 kN, the paper's bounds)"
    )
    return figure
