"""What the report's pictures and page show: lifted legs without soil pressure, the
machine's time in cycle on the time axis (wall time only in the header)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from daq.report.content import ReportContent, analyse
from daq.report.figures import comparison_figure, time_series_figure
from daq.report.page import header_rows, metrics_rows, render_page
from daq.report.tracks import RecordingCollector

T0_S = 1_750_000_000.0
LEGS = ("SB1_F1", "SB2_F1")
#: A 10 s cycle played at half speed: 20 s of wall time, a frame every 20 ms.
CYCLE_S, SPEED, STEP_S = 10.0, 0.5, 0.02


def add(collector: RecordingCollector, topic: str, payload: dict) -> None:  # type: ignore[type-arg]
    collector.add(topic, json.dumps(payload).encode())


def played_cycle(
    machine_state: bool = True, truth_legs: dict[str, str] | None = None
) -> ReportContent:
    """SB1_F1 loaded with a peak at cycle time 6 s; SB2_F1 lifted (contact false, eq. 5
    negative: -13 kPa) from cycle time 3 s to 7 s, in contact otherwise. ``truth_legs``:
    the truth's name of each leg it has (default: every leg, by its own name)."""
    collector = RecordingCollector()
    for i in range(int(CYCLE_S / SPEED / STEP_S) + 1):
        t = T0_S + i * STEP_S
        cycle_t = (t - T0_S) * SPEED
        sb1 = 60e3 + 30e3 * np.exp(-((cycle_t - 6.0) ** 2))
        lifted = 3.0 <= cycle_t < 7.0
        sb2 = -13e3 * 0.33 if lifted else 20e3
        for leg, force, contact in (("SB1_F1", sb1, True), ("SB2_F1", sb2, not lifted)):
            add(collector, f"/leg/{leg}/ground", {
                "leg": leg, "t": t, "force_N": force, "force_raw_N": force,
                "pressure_Pa": force / 0.33, "p_piston_Pa": 1.0, "p_rod_Pa": 1.0,
                "contact": contact, "valid": True, "reasons": []})  # fmt: skip
        if machine_state and i % 5 == 0:  # MACHINE_STATE every 100 ms of wall time
            phase = "idle" if cycle_t < 3.0 else "fold" if cycle_t < 7.0 else "unfold"
            add(collector, "/signals/MACHINE_STATE", {"t": t, "crc_ok": True, "signals": {
                "Machine_Phase": phase, "Machine_CycleCount": 0,
                "Machine_CycleTime": round(cycle_t, 2)}})  # fmt: skip
        truth = {"SB1_F1": sb1, "SB2_F1": 0.0 if lifted else sb2}
        names = truth_legs if truth_legs is not None else {leg: leg for leg in LEGS}
        legs = {names[leg]: {"force_true_N": f} for leg, f in truth.items() if leg in names}
        add(collector, "/sim/truth", {"t_unix_s": t, "legs": legs})
    return analyse(collector.recording("run.mcap", None, machine_id="m"))


def lines(content: ReportContent, quantity: str) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    axes = time_series_figure(content, quantity).axes[0]
    return {
        str(line.get_label()): (np.asarray(line.get_xdata()), np.asarray(line.get_ydata()))
        for line in axes.get_lines()
        if str(line.get_label()) in LEGS
    }


def test_a_lifted_leg_has_no_negative_contact_pressure() -> None:
    content = played_cycle()
    x, kPa = lines(content, "pressure")["SB2_F1"]
    lifted = (x >= 3.0) & (x < 7.0)
    assert lifted.sum() > 100
    assert np.nanmin(kPa) == 0.0  # not -13 kPa
    assert np.all(kPa[lifted] == 0.0)
    assert np.all(kPa[(x < 2.9) | (x > 7.1)] == pytest.approx(20e3 / 0.33 / 1e3))
    figure = time_series_figure(content, "pressure")
    legend_texts = [text.get_text() for legend in figure.legends for text in legend.get_texts()]
    assert "not in contact: 0 kPa" in legend_texts
    # the force picture (Figure 8) keeps the cylinder-derived force, negative or not
    _, kN = lines(content, "force")["SB2_F1"]
    assert np.nanmin(kN) == pytest.approx(-13e3 * 0.33 / 1e3)


def test_with_machine_state_times_are_times_in_cycle() -> None:
    """Played at half speed, the 10 s cycle spans 20 s on the wall clock: the pictures and
    tables show the machine's 0..10 s; the header keeps the wall clock."""
    content = played_cycle()
    assert content.time.in_cycle
    x, _ = lines(content, "pressure")["SB1_F1"]
    assert np.nanmin(x) == pytest.approx(0.0) and np.nanmax(x) == pytest.approx(CYCLE_S)
    axes = time_series_figure(content, "pressure").axes[0]
    assert axes.get_xlabel() == "time in cycle / s (MACHINE_STATE)"
    assert axes.get_xlim()[1] == pytest.approx(CYCLE_S, abs=0.05)
    peak = next(row for row in metrics_rows(content) if row[1] == "SB1_F1")
    assert float(peak[3]) == pytest.approx(6.0, abs=0.02)  # not 12 s of wall time
    header = dict(header_rows(content))
    assert header["duration"] == f"{CYCLE_S / SPEED:.2f} s"
    comparison_axes = comparison_figure(content).axes[-1]
    assert comparison_axes.get_xlabel() == "time in cycle / s (MACHINE_STATE)"


def test_without_machine_state_times_are_since_the_first_frame() -> None:
    content = played_cycle(machine_state=False)
    assert not content.time.in_cycle
    x, _ = lines(content, "pressure")["SB1_F1"]
    assert np.nanmax(x) == pytest.approx(CYCLE_S / SPEED)
    peak = next(row for row in metrics_rows(content) if row[1] == "SB1_F1")
    assert float(peak[3]) == pytest.approx(12.0, abs=0.04)
    axes = time_series_figure(content, "pressure").axes[0]
    assert axes.get_xlabel().startswith("time since ")


def test_two_cycles_are_laid_over_one_another_not_joined() -> None:
    collector = RecordingCollector()
    for i in range(400):  # two 2 s cycles at full speed, 10 ms frames
        t, count, cycle_t = T0_S + 0.01 * i, i // 200, 0.01 * (i % 200)
        add(collector, "/leg/SB1_F1/ground", {
            "leg": "SB1_F1", "t": t, "force_N": 1e4 * (1 + count), "force_raw_N": 0.0,
            "pressure_Pa": 1e4 * (1 + count) / 0.33, "p_piston_Pa": 1.0, "p_rod_Pa": 1.0,
            "contact": True, "valid": True, "reasons": []})  # fmt: skip
        if i % 10 == 0:
            add(collector, "/signals/MACHINE_STATE", {"t": t, "crc_ok": True, "signals": {
                "Machine_Phase": "idle", "Machine_CycleCount": count,
                "Machine_CycleTime": cycle_t}})  # fmt: skip
    content = analyse(collector.recording("run.mcap", None, machine_id="m"))
    x, kPa = lines(content, "pressure")["SB1_F1"]
    assert np.nanmax(x) == pytest.approx(1.99) and np.nanmin(x) == 0.0
    gap = np.flatnonzero(np.isnan(x))
    assert gap.size == 1  # one break between the cycles, no line drawn back to 0
    assert kPa[gap[0] - 1] == pytest.approx(1e4 / 0.33 / 1e3)
    assert kPa[gap[0] + 1] == pytest.approx(2e4 / 0.33 / 1e3)


def test_the_page_says_which_legs_the_truth_leaves_out() -> None:
    """Truth of other leg names (recorded with another machine config) was told "No
    simulation truth in this recording" under a header counting its samples; a leg the
    truth does not name was left out of the table unsaid."""
    assert "No simulation truth" not in render_page(played_cycle(), {})
    renamed = render_page(played_cycle(truth_legs={"SB1_F1": "FL", "SB2_F1": "FR"}), {})
    assert "No simulation truth (/sim/truth) in this recording" not in renamed
    assert (
        "The simulation truth (/sim/truth, 1001 samples) is of the legs FL, FR, none of them "
        "a leg of this recording (SB1_F1, SB2_F1): nothing to compare" in renamed
    )
    partial = played_cycle(truth_legs={"SB1_F1": "SB1_F1"})
    assert list(partial.deviations) == ["SB1_F1"]
    assert "No simulation truth for SB2_F1: not compared." in render_page(partial, {})
