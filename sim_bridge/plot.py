"""A picture of one cycle, like the paper's Figures 7 and 8: pressure and force per foot.

Two panels over the cycle time: the contact pressure of each foot in kPa (force / foot
area) and the vertical ground force of each foot in kN, SB1's feet solid, SB2's dashed,
one colour and marker per foot (markers staggered, later feet thinner, so feet with
equal loads stay visible), the movement phases shaded. The values are the simulation's
true foot forces; a leg without them (an external input without a force column) is
drawn from its chamber pressures through eq. (4) instead, and its label says so.

Drawn with matplotlib's object API on the Agg canvas (no pyplot state, no display).
"""

from collections.abc import Mapping
from pathlib import Path
from typing import IO

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from estimator.equations import foot_force_N
from estimator.geometry import LegGeometry
from sim_bridge.result import LEGS, PHASES, FloatArray, SimulationResult, leg_column

COLOURS = ("tab:blue", "tab:orange", "tab:green")
MARKERS = ("o", "s", "^")


def foot_forces_N(
    result: SimulationResult,
    geometries: Mapping[str, LegGeometry],
    columns: Mapping[str, int] | None = None,
) -> dict[str, tuple[FloatArray, bool]]:
    """Leg -> (force per row, True if the true force, False if from eq. (4)); ``columns``:
    each config leg's column (see :func:`~sim_bridge.result.leg_column`)."""
    forces: dict[str, tuple[FloatArray, bool]] = {}
    for leg, geometry in geometries.items():
        column = leg_column(leg, columns)
        true_N = result.force_true_N[:, column]
        if np.all(np.isnan(true_N)):
            estimate = foot_force_N(
                result.p_piston_Pa[:, column], result.p_rod_Pa[:, column], geometry
            )
            forces[leg] = (np.asarray(estimate, dtype=np.float64), False)
        else:
            forces[leg] = (true_N, True)
    return forces


def cycle_figure(
    result: SimulationResult,
    geometries: Mapping[str, LegGeometry],
    title: str = "",
    columns: Mapping[str, int] | None = None,
) -> Figure:
    """The two-panel figure (pressure in kPa above, force in kN below), one line per leg
    of ``geometries``, styled by its simulated leg's base and foot."""
    figure = Figure(figsize=(10, 7), layout="constrained")
    FigureCanvasAgg(figure)
    pressure_axes, force_axes = figure.subplots(2, 1, sharex=True)
    t_s = result.t_s
    for leg, (force_N, is_true) in foot_forces_N(result, geometries, columns).items():
        column = leg_column(leg, columns)
        style = {
            "color": COLOURS[column % 3],
            "linestyle": "-" if column < 3 else "--",
            "linewidth": 1.8 - 0.4 * (column % 3),
            "marker": MARKERS[column % 3],
            "markersize": 4,
            "markevery": (0.1 * column / len(LEGS), 0.1),
            "label": leg if is_true else f"{leg} (eq. 4)",
        }
        pressure_axes.plot(t_s, force_N / geometries[leg].A_foot_m2 / 1e3, **style)
        force_axes.plot(t_s, force_N / 1e3, **style)
    for axes in (pressure_axes, force_axes):
        _shade_phases(axes, result)
        axes.grid(True, alpha=0.3)
    pressure_axes.set_ylabel("contact pressure / kPa")
    force_axes.set_ylabel("foot force / kN")
    force_axes.set_xlabel("time in cycle / s")
    force_axes.set_xlim(float(t_s[0]), float(t_s[-1]))
    handles, labels = force_axes.get_legend_handles_labels()
    figure.legend(handles, labels, loc="outside lower center", ncol=6, fontsize="small")
    _label_phases(pressure_axes, result)
    if title:
        figure.suptitle(title)
    return figure


def write_cycle_plot(
    result: SimulationResult,
    geometries: Mapping[str, LegGeometry],
    out: str | Path | IO[bytes],
    title: str = "",
    columns: Mapping[str, int] | None = None,
) -> None:
    """Draws :func:`cycle_figure` into a PNG file (a path or a binary stream)."""
    cycle_figure(result, geometries, title, columns).savefig(out, format="png", dpi=120)


def phase_spans(result: SimulationResult) -> list[tuple[float, float, int]]:
    """(start_s, end_s, phase) of each run of one phase."""
    phase = result.phase
    edges = np.flatnonzero(np.diff(phase)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [phase.size - 1]])
    return [
        (float(result.t_s[a]), float(result.t_s[b]), int(phase[a]))
        for a, b in zip(starts, ends, strict=True)
    ]


def _shade_phases(axes: Axes, result: SimulationResult) -> None:
    for index, (start_s, end_s, _) in enumerate(phase_spans(result)):
        if index % 2:
            axes.axvspan(start_s, end_s, color="0.92", zorder=0)


def _label_phases(axes: Axes, result: SimulationResult) -> None:
    transform = axes.get_xaxis_transform()
    spans = phase_spans(result)
    width_s = spans[-1][1] - spans[0][0]
    for start_s, end_s, phase in spans:
        if end_s - start_s < 0.04 * width_s:  # too narrow to name
            continue
        name = PHASES[phase] if 0 <= phase < len(PHASES) else str(phase)
        axes.text(
            (start_s + end_s) / 2, 1.01, name, transform=transform, ha="center", fontsize="x-small"
        )
