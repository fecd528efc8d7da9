"""All legs together: the weight check and settings validation."""

import pytest

from dbc.machine import G_M_S2
from estimator import EstimatorSettings, LegGeometry, LegSample, MachineEstimator
from tests.estimator.test_equations import DEFAULT
from tests.estimator.test_leg import pressures_for
from tests.helpers import LEGS

MASS_KG = 18_800.0


def machine() -> MachineEstimator:
    leg = LegGeometry(**DEFAULT)
    return MachineEstimator(
        {name: leg for name in LEGS},
        EstimatorSettings(median_window=1),
        MASS_KG * G_M_S2,
        {name: 0.01 for name in LEGS},
    )


def test_weight_residual_sums_the_legs_in_contact() -> None:
    m = machine()
    weight_N = MASS_KG * G_M_S2
    # Three feet carry the machine, three are in the air (200 N on the foot).
    for name in LEGS:
        force = weight_N / 3 + 300.0 if name.startswith("SB1") else 200.0
        m.update(name, LegSample(t_s=1.0, p_piston_Pa=pressures_for(force), p_rod_Pa=1e6))
    check = m.snapshot(1.0).weight
    assert check.legs_in_contact == 3
    assert check.complete is True
    assert check.total_force_N == pytest.approx(weight_N + 900.0)
    assert check.residual_N == pytest.approx(900.0)


def test_weight_check_is_incomplete_when_a_leg_is_invalid_or_stale() -> None:
    m = machine()
    for name in LEGS[:5]:
        m.update(name, LegSample(t_s=1.0, p_piston_Pa=pressures_for(30e3), p_rod_Pa=1e6))
    snapshot = m.snapshot(1.0)
    assert snapshot.legs["SB2_F3"].reasons == ("stale",)
    assert snapshot.weight.complete is False
    assert snapshot.weight.legs_in_contact == 5
    later = m.snapshot(2.0)
    assert all("stale" in e.reasons for e in later.legs.values())
    assert later.weight.total_force_N == 0.0


def test_every_leg_needs_a_cycle_time() -> None:
    with pytest.raises(ValueError, match="SB2_F3"):
        MachineEstimator(
            {name: LegGeometry(**DEFAULT) for name in LEGS},
            EstimatorSettings(),
            1.0,
            {name: 0.01 for name in LEGS[:5]},
        )


@pytest.mark.parametrize(
    ("kw", "word"),
    [
        ({"median_window": 10}, "median_window"),
        ({"contact_off_N": 9000.0}, "contact_off_N"),
        ({"pressure_min_Pa": 5e7}, "pressure_min_Pa"),
        ({"near_constant_window_s": 0.0}, "near_constant_window_s"),
        # Below a frame time's resolution the window lost its own sample: ZeroDivisionError.
        ({"near_constant_window_s": 1e-300}, "near_constant_window_s must be at least 0.01"),
        ({"stale_after_cycles": -1.0}, "stale_after_cycles"),
        # One cycle or less: every next frame would be an outage (median, metrics restart).
        ({"stale_after_cycles": 1.0}, "stale_after_cycles must be > 1"),
        ({"stale_after_cycles": 0.5}, "stale between two of its frames"),
    ],
)
def test_settings_refuse_inconsistent_values(kw: dict[str, object], word: str) -> None:
    with pytest.raises(ValueError, match=word):
        EstimatorSettings(**kw)  # type: ignore[arg-type]


def test_staleness_is_judged_on_bus_time_across_a_clock_step_back() -> None:
    m = machine()
    for name in LEGS:
        m.update(name, LegSample(t_s=100.0, p_piston_Pa=pressures_for(30e3), p_rod_Pa=1e6))
    m.observe(100.02)  # a frame of another message
    for t_s in (95.03, 95.04, 95.05):  # the clock steps back 5 s; SB2_F3 stays silent
        for name in LEGS[:5]:
            m.update(name, LegSample(t_s=t_s, p_piston_Pa=pressures_for(30e3), p_rod_Pa=1e6))
    # Bus time: 20 ms, nothing for the step back, 2 x 10 ms.
    assert m.bus_time_s == pytest.approx(0.04)
    snapshot = m.snapshot(95.05)
    assert [snapshot.legs[name].valid for name in LEGS] == [True] * 5 + [False]
    assert snapshot.legs["SB2_F3"].reasons == ("stale",)
    assert snapshot.t_s == 95.05


def test_a_leg_silent_across_a_clock_step_back_restarts_its_filter() -> None:
    """SB1_F1 is silent for 1 s while the others go on, and NTP steps the clock back an
    hour meanwhile: its frame times say it came back an hour before it went, bus time
    says 1 s later, an outage. Its median restarts: the first force after it is its own
    (it was the median of four forces from before the silence and one after)."""
    leg = LegGeometry(**DEFAULT)
    m = MachineEstimator(
        {name: leg for name in LEGS},
        EstimatorSettings(median_window=5),
        1.0,
        {name: 0.01 for name in LEGS},
    )
    for i in range(200):
        t_s = 100.0 + 0.01 * i - (3600.0 if i >= 50 else 0.0)
        force = 30e3 if i < 100 else 60e3
        for name in LEGS:
            if name != "SB1_F1" or not 10 <= i < 110:
                estimate = m.update(name, LegSample(t_s, pressures_for(force), 1e6))
            if name == "SB1_F1" and i == 110:
                back = estimate
    assert back.force_N == pytest.approx(60e3) and back.valid
    assert m.legs["SB1_F1"].restarts == 1
    assert all(m.legs[name].restarts == 0 for name in LEGS[1:])


def test_a_leg_sent_less_often_than_its_stale_time_is_found_restarting() -> None:
    # Cycle time 10 ms, stale after 30 ms. SB1_F1 comes every 40 ms (a hub's page each
    # fourth frame, say): each sample is one after an "outage", the median restarts.
    leg = LegGeometry(**DEFAULT)
    m = MachineEstimator(
        {name: leg for name in LEGS}, EstimatorSettings(), 1.0, {name: 0.01 for name in LEGS}
    )
    forces = [30e3, 30e3, 90e3, 30e3, 30e3] * 4  # a spike the median would take out
    slow = []
    for i, force in enumerate(forces):
        sample = LegSample(t_s=1.0 + 0.04 * i, p_piston_Pa=pressures_for(force), p_rod_Pa=1e6)
        slow.append(m.update("SB1_F1", sample))
        for k in range(4):  # the others every 10 ms, one outage of 0.5 s in SB1_F2's
            t_s = 1.0 + 0.04 * i + 0.01 * k + (0.5 if i >= 10 else 0.0)
            for name in LEGS[1:]:
                m.update(name, LegSample(t_s, pressures_for(force), 1e6))
    # Nothing filtered, the spikes pass: the median restarted at each sample.
    assert [e.force_N for e in slow] == [e.force_raw_N for e in slow]
    assert max(e.force_N for e in slow) == pytest.approx(90e3)
    assert m.legs["SB1_F1"].restarts == len(forces) - 1
    assert m.restarting_legs() == {"SB1_F1": (len(forces) - 1, len(forces))}
    assert m.legs["SB1_F2"].restarts == 1  # one outage is no pattern
