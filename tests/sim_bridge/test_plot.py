"""The cycle plot: two panels (kPa, kN) per foot, written as a PNG."""

import io
import math

import pytest

from sim_bridge.plot import cycle_figure, foot_forces_N, phase_spans, write_cycle_plot
from sim_bridge.result import SimulationResult
from tests.sim_bridge.synthetic import CONFIG

GEOMETRIES = {leg: CONFIG.legs[leg].geometry for leg in CONFIG.legs}
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_the_plot_is_a_non_empty_png(result: SimulationResult) -> None:
    out = io.BytesIO()
    write_cycle_plot(result, GEOMETRIES, out, title="synthetic")
    data = out.getvalue()
    assert data.startswith(PNG_MAGIC) and len(data) > 20_000


def test_two_panels_of_pressure_and_force_per_foot(result: SimulationResult) -> None:
    figure = cycle_figure(result, GEOMETRIES)
    pressure, force = figure.axes
    assert pressure.get_ylabel() == "contact pressure / kPa"
    assert force.get_ylabel() == "foot force / kN"
    assert [line.get_label() for line in force.get_lines()] == list(GEOMETRIES)
    sb1_f1 = pressure.get_lines()[0].get_ydata()
    assert sb1_f1[7] == result.force_true_N[7, 0] / 0.33 / 1e3


def test_feet_with_equal_loads_stay_apart(result: SimulationResult) -> None:
    """SB1_F2 and SB1_F3 carry equal loads in the model: marker, marker positions and
    line width differ, so the one drawn later does not hide the other."""
    lines = {
        line.get_label(): line for line in cycle_figure(result, GEOMETRIES).axes[0].get_lines()
    }
    f2, f3 = lines["SB1_F2"], lines["SB1_F3"]
    assert f2.get_marker() != f3.get_marker() and f2.get_markevery() != f3.get_markevery()
    assert f2.get_linewidth() > f3.get_linewidth()
    assert (
        len(
            {(line.get_color(), line.get_linestyle(), line.get_marker()) for line in lines.values()}
        )
        == 6
    )


def test_legs_without_a_true_force_are_drawn_from_eq_4(result: SimulationResult) -> None:
    eq_4_N = result.force_true_N[:, 1].copy()  # the synthetic truth is eq. (4) of the pressures
    result.force_true_N[:, 1] = math.nan
    forces = foot_forces_N(result, GEOMETRIES)
    assert forces["SB1_F1"][1] and not forces["SB1_F2"][1]
    assert forces["SB1_F2"][0] == pytest.approx(eq_4_N)
    labels = [line.get_label() for line in cycle_figure(result, GEOMETRIES).axes[1].get_lines()]
    assert labels[1] == "SB1_F2 (eq. 4)"


def test_phase_spans_cover_the_cycle(result: SimulationResult) -> None:
    spans = phase_spans(result)
    assert [phase for _, _, phase in spans] == [0, 1, 2, 3, 4]
    assert spans[0][0] == 0.0 and spans[-1][1] == result.t_s[-1]
