"""The calibration fit on synthetic instants from a known model, and its identifiability."""

import numpy as np
import pytest

from estimator.calibration import Snapshots, fit_calibration, quasi_static, snapshots
from estimator.leg import LegEstimate

LEGS = ("SB1_F1", "SB1_F2", "SB1_F3", "SB2_F1", "SB2_F2", "SB2_F3")
WEIGHT_N = 184_365.0
W_TERM_N = np.full(6, 2248.0)
#: The config's lever ratios are off: the true gain is 1 / (1 + error).
TRUE_GAIN = 1.0 / (1.0 + np.array([-0.06, 0.04, 0.03, -0.05, 0.05, -0.02]))
#: Transducer zero offsets as forces in the estimate; the correction is minus them.
ZERO_OFFSET_N = np.array([1053.0, -790.0, 527.0, -527.0, 790.0, 263.0])


def instants(seed: int = 1, lifts: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(design lever term, contact, true force) of 300 instants: six feet down with the
    centre of gravity wandering, and (``lifts``) each base in the air in turn."""
    rng = np.random.default_rng(seed)
    rows, downs = [], []
    for k in range(300):
        down = np.ones(6, dtype=bool)
        if lifts and k % 3 == 1:
            down[3:] = False
        elif lifts and k % 3 == 2:
            down[:3] = False
        share = rng.uniform(0.3, 1.0, 6) * down
        rows.append(WEIGHT_N * share / share.sum())
        downs.append(down)
    true_N = np.array(rows)
    contact = np.array(downs)
    # What the estimator (gain 1, offset 0, wrong ratios) shows: F = L + w, where the
    # true force is k L + w + b with b = -k x zero offset (the correction).
    lever_N = (true_N - W_TERM_N) / TRUE_GAIN + ZERO_OFFSET_N
    lever_N += rng.normal(0.0, 100.0, lever_N.shape)  # friction and noise
    return lever_N, contact, true_N


def test_gains_offsets_and_residual_are_recovered() -> None:
    lever_N, contact, true_N = instants()
    fit = fit_calibration(lever_N, contact, W_TERM_N, WEIGHT_N, LEGS)
    assert fit.gain_identified.all() and fit.offset_identified.all() and fit.refusals == ()
    assert fit.rank == 12
    assert np.abs(fit.gain / TRUE_GAIN - 1).max() < 0.01
    assert np.abs(fit.offset_N - (-TRUE_GAIN * ZERO_OFFSET_N)).max() < 150.0
    before = np.sqrt(np.mean(fit.residual_before_N**2))
    after = np.sqrt(np.mean(fit.residual_after_N**2))
    assert after < before / 5
    # ... and the forces come closer to the truth.
    deviation_before = np.nanmean(np.abs(fit.force_before_N - np.where(contact, true_N, np.nan)))
    deviation_after = np.nanmean(np.abs(fit.force_after_N - np.where(contact, true_N, np.nan)))
    assert deviation_after < deviation_before / 5


def test_without_lifted_feet_the_gains_scale_is_refused() -> None:
    """All feet always down: a common scale of the gains trades against the offsets."""
    lever_N, contact, _ = instants(lifts=False)
    fit = fit_calibration(lever_N, contact, W_TERM_N, WEIGHT_N, LEGS)
    assert not fit.offset_identified.any()
    assert fit.rank < 12
    assert any("force_offset_N of SB1_F1" in line for line in fit.refusals)
    # What is refused keeps the prior.
    assert (fit.offset_N[~fit.offset_identified] == 0.0).all()


def test_an_unchanging_load_distribution_is_refused_in_one_line() -> None:
    lever_N, contact, _ = instants(lifts=False)
    lever_N[:] = lever_N[0]
    fit = fit_calibration(lever_N, contact, W_TERM_N, WEIGHT_N, LEGS)
    assert not fit.gain_identified.any()
    assert fit.refusals[0].startswith(
        "gains are not identifiable: the load distribution never changed enough"
    )
    assert (fit.gain == 1.0).all()


def test_quasi_static_needs_steady_forces_valid_legs_and_no_touchdown() -> None:
    t = np.arange(20) * 0.1
    force = np.full((20, 2), 50e3)
    force[10, 0] += 3e3  # a bump at 1.0 s
    valid = np.ones((20, 2), dtype=bool)
    valid[3, 1] = False
    contact = np.ones((20, 2), dtype=bool)
    contact[16:, 1] = False  # lifts at 1.6 s
    snaps = Snapshots(("A", "B"), t, force, valid, contact)
    still = quasi_static(snaps, window=2, max_change_N=1e3)
    assert np.flatnonzero(still).tolist() == [6, 7, 13]


@pytest.mark.parametrize("bad_gain", [0.0])
def test_lever_of_an_idle_leg_is_reported(bad_gain: float) -> None:
    lever_N, contact, _ = instants()
    contact[:, 5] = False
    lever_N[:, 5] = bad_gain
    fit = fit_calibration(lever_N, contact, W_TERM_N, WEIGHT_N, LEGS)
    assert fit.refusals[0] == "SB2_F3: never carried load: gain not identifiable"
    assert not fit.gain_identified[5]


def test_eq4_applies_the_leg_s_gain_and_offset() -> None:
    import dataclasses

    from estimator import foot_force_N
    from sim_bridge.params import default_leg

    leg = default_leg()
    calibrated = dataclasses.replace(leg, force_gain=1.1, force_offset_N=500.0)
    lever_N = (9e6 * leg.A_piston_m2 - 1e6 * leg.A_rod_m2) * leg.force_ratio
    assert foot_force_N(9e6, 1e6, leg) == pytest.approx(lever_N + leg.weight_term_N)
    assert foot_force_N(9e6, 1e6, calibrated) == pytest.approx(
        1.1 * lever_N + leg.weight_term_N + 500.0
    )


def _estimates(times_s: list[float]) -> list[LegEstimate]:
    """Two legs, each on the ground with 50 kN at every time of ``times_s``."""
    return [
        LegEstimate(leg, t, 5e4, 5e4, 1e5, 1e7, 1e6, True, True, ())
        for t in times_s
        for leg in ("A", "B")
    ]


def test_a_clock_set_from_1970_is_one_stale_snapshot_not_decades_of_them() -> None:
    """Sampled every 0.1 s across the step, 56 years of snapshots filled the memory
    (``calibrate`` of such a log: MemoryError)."""
    before = [12.0 + 0.01 * k for k in range(100)]  # 1 s of a clock not set yet
    after = [1.79e9 + 0.01 * k for k in range(100)]  # then set by NTP
    snaps = snapshots(_estimates(before + after), ("A", "B"), 0.1, 0.03)
    # none heard yet at the first; the step is one snapshot of every leg stale, so no
    # window of steady instants spans it
    assert snaps.valid.all(axis=1).tolist() == [False] + [True] * 10 + [False] + [True] * 10
    assert snaps.t_s[12] == pytest.approx(1.79e9, abs=0.1)


def test_a_clock_stepping_back_starts_the_sampling_again() -> None:
    """Nothing was sampled until the frame times caught up with the time before the step."""
    times = [100.0 + 0.01 * k for k in range(100)] + [50.0 + 0.01 * k for k in range(100)]
    snaps = snapshots(_estimates(times), ("A", "B"), 0.1, 0.03)
    assert len(snaps.t_s) == 20
    assert snaps.t_s[10] == 50.0 and not snaps.valid[10].any()  # stale until heard again
    assert snaps.valid[11:].all()


@pytest.mark.parametrize("count", [1, 3])
def test_fewer_equations_than_parameters_identify_nothing_they_leave_open(count: int) -> None:
    """One instant (6 feet down) or three (one of each stance: 9 equations for 12
    parameters) fit exactly whatever the gains: the directions no equation reaches were
    not counted as undetermined, nor was a fit without a spare equation judged, and every
    parameter was written (gains off by up to 6 %, offsets by 1.1 kN)."""
    lever_N, contact, _ = instants()
    fit = fit_calibration(lever_N[:count], contact[:count], W_TERM_N, WEIGHT_N, LEGS)
    assert not fit.gain_identified.any() and not fit.offset_identified.any()
    assert (fit.gain == 1.0).all() and (fit.offset_N == 0.0).all()


@pytest.mark.parametrize(
    ("gain", "offset_N", "line"),
    [
        (2.0, 0.0, "force_gain of SB1_F1 at 1.5 stopped at the fit's bound (0.5..1.5)"),
        (0.3, 0.0, "force_gain of SB1_F1 at 0.5 stopped at the fit's bound (0.5..1.5)"),
        (
            1.0,
            80e3,
            "force_offset_N of SB1_F1 at -50000 stopped at the fit's bound (-50000..50000 N)",
        ),
    ],
)
def test_a_leg_beyond_the_bounds_is_named_not_blamed_on_the_load_distribution(
    gain: float, offset_N: float, line: str
) -> None:
    """A leg whose config is off by more than the bounds (a lever ratio of half or three
    times the truth: a length in the wrong unit; a transducer 80 kN off): the fit stops at
    the bound, its residual is large, nothing is identified, and the refusal said 'the
    load distribution never changed enough' of data of rank 12, condition 8."""
    true_gain = TRUE_GAIN.copy()
    true_gain[0] = gain
    zero_offset_N = ZERO_OFFSET_N.copy()
    zero_offset_N[0] = offset_N
    lever_N, contact, true_N = instants()
    lever_N = (true_N - W_TERM_N) / true_gain + zero_offset_N  # noise-free, feet in the air too
    fit = fit_calibration(lever_N, contact, W_TERM_N, WEIGHT_N, LEGS)
    assert fit.rank == 12
    assert not fit.gain_identified.any() and not fit.offset_identified.any()
    assert fit.refusals[0].startswith(line), fit.refusals
    assert not any("load distribution" in refusal for refusal in fit.refusals)
