"""The co-simulation model reproduces the paper's figures (section 4.1) and section 3.4's check."""

import numpy as np
import pytest

from estimator import foot_force_N
from sim_bridge.model import simulate
from sim_bridge.noise import ImpulsiveNoise
from sim_bridge.params import G_M_S2, ModelParams
from sim_bridge.result import LEGS, SimulationResult

A_FOOT_M2 = 0.33


@pytest.fixture(scope="module")
def result() -> SimulationResult:
    return simulate(rtol=1e-5)


def window(r: SimulationResult, start_s: float, end_s: float) -> np.ndarray:
    return (r.t_s >= start_s) & (r.t_s <= end_s)


def pressure_kPa(r: SimulationResult) -> np.ndarray:
    return r.force_true_N / A_FOOT_M2 / 1e3


def test_statics_the_feet_carry_the_machine(result: SimulationResult) -> None:
    idle = window(result, 0.0, 2.0)
    total = result.force_true_N[idle].sum(axis=1)
    assert total == pytest.approx(np.full(total.shape, ModelParams().mass_kg * G_M_S2), rel=2e-3)


def test_six_feet_down_loaded_base_near_120_kPa(result: SimulationResult) -> None:
    # After the carriage moved over SB1 (t = 7 s), paper: ~120 kPa per foot of the loaded base.
    at_7s = pressure_kPa(result)[np.searchsorted(result.t_s, 7.0)]
    assert np.all((at_7s[:3] >= 108) & (at_7s[:3] <= 132)), at_7s
    assert np.all(at_7s[3:] > 20), "all six feet carry load"
    # Before the move it is the other way round: SB2 is the loaded base.
    at_1s = pressure_kPa(result)[np.searchsorted(result.t_s, 1.0)]
    assert at_1s[3:].mean() > at_1s[:3].mean() + 25


def test_three_feet_after_lifting_180_to_190_kPa(result: SimulationResult) -> None:
    lifted = window(result, 12.5, 18.0)
    mean = pressure_kPa(result)[lifted].mean(axis=0)
    assert np.all((mean[:3] >= 162) & (mean[:3] <= 209)), mean
    assert np.all(result.force_true_N[lifted][:, 3:] == 0.0), "SB2's feet are in the air"


def test_peak_over_310_kPa_when_the_fold_stops(result: SimulationResult) -> None:
    kPa = pressure_kPa(result)
    around_stop = window(result, 22.5, 24.5)
    peak = kPa[around_stop].max()
    assert peak > 310
    t_peak = result.t_s[around_stop][kPa[around_stop].max(axis=1).argmax()]
    assert 23.0 <= t_peak <= 23.6
    # It is an oscillation on top of the fold's static load, not the static load itself.
    before = kPa[window(result, 21.5, 22.0)].max()
    assert before < 260
    # And the highest of the whole cycle.
    assert peak == kPa.max()


def test_near_constant_230_kPa_on_sb1_f1_at_40_to_43_s(result: SimulationResult) -> None:
    sb1_f1 = pressure_kPa(result)[window(result, 40.0, 43.0), LEGS.index("SB1_F1")]
    assert 207 <= sb1_f1.mean() <= 253
    assert sb1_f1.std() / sb1_f1.mean() < 0.03, "nearly constant"


def test_the_cycle_ends_with_the_load_on_all_six_feet(result: SimulationResult) -> None:
    """Section 2.1: "At t = 44 s, all six legs are on the ground again and the load of the
    machine is once again carried by all six legs" (Figure 7's end state)."""
    contact_on_N = 8_000.0  # deploy/machine.example.toml [estimator]
    at_44s = result.force_true_N[np.searchsorted(result.t_s, 44.0)]
    assert np.all(at_44s > 5_000.0), at_44s  # all six on the ground, each carrying load
    end = result.force_true_N[-1]
    assert result.t_s[-1] == pytest.approx(45.0)
    assert end.sum() == pytest.approx(ModelParams().mass_kg * G_M_S2, rel=2e-3)
    share = end / end.sum()
    assert np.all((share > 0.08) & (share < 0.30)), share  # every foot a plausible share
    assert np.all(end[3:] > 2 * contact_on_N), end  # SB2's feet well above the threshold
    assert 0.25 <= share[3:].sum() <= 0.5, share  # SB2 carries a real part, SB1 the most


def test_ground_spring_compresses_about_0_2_mm(result: SimulationResult) -> None:
    assert 0.15e-3 <= result.ground_compression_m.max() <= 0.3e-3


def test_eq4_on_model_pressures_against_true_forces(result: SimulationResult) -> None:
    """Section 3.4: 50 % of deviations within +-1 kN, 95 % within +-3.6 kN (stance legs)."""
    leg = ModelParams().leg
    estimate = foot_force_N(result.p_piston_Pa, result.p_rod_Pa, leg)
    stance = (result.force_true_N > 5_000.0) & (result.t_s[:, None] >= 1.0)
    deviation = np.abs(estimate - result.force_true_N)[stance]
    assert np.percentile(deviation, 50) <= 1_000.0
    assert np.percentile(deviation, 95) <= 3_600.0
    # The cylinder friction makes eq. (4) deviate, as the paper explains.
    assert deviation.max() > 500.0


def test_friction_free_rigid_model_makes_eq4_exact() -> None:
    frictionless = ModelParams(cylinder_viscous_N_s_m=0.0, cylinder_static_friction_N=0.0)
    r = simulate(frictionless, rtol=1e-4)
    estimate = foot_force_N(r.p_piston_Pa, r.p_rod_Pa, frictionless.leg)
    assert np.max(np.abs(estimate - r.force_true_N)) < 1e-6 * r.force_true_N.max()


def test_signals_follow_the_cycle(result: SimulationResult) -> None:
    def at(t: float) -> int:
        return int(np.searchsorted(result.t_s, t))

    assert result.phase[at(1.0)] == 0 and result.phase[at(4.0)] == 1
    assert result.phase[at(15.0)] == 2 and result.phase[at(27.0)] == 3
    assert result.phase[at(40.0)] == 4
    assert result.fold_deg[at(30.0)] == pytest.approx(45.0, abs=1.0)
    assert result.rotation_deg[at(20.0)] == pytest.approx(180.0)
    assert result.rotation_deg[at(33.0)] == pytest.approx(0.0, abs=1e-9)
    assert result.stroke_m[at(20.0), 3] == pytest.approx(0.3)
    assert result.inclination_deg[at(15.0), 0] == pytest.approx(3.0)
    assert np.all(result.incl_p_piston_Pa > 0)
    assert not result.slipping.any(), "no slip expected (paper, section 4.2)"


def fold_stop_samples(deviation_N: np.ndarray, limit_N: float) -> int:
    """The samples (rows, all legs) where two solutions of the cycle differ by ``limit_N``
    or more. The bridge's fold stop lands at an instant the solver's tolerance moves by a
    few milliseconds, so the one 10 ms sample that straddles it may differ by kilonewtons
    (6.6 kN at 43.26 s on one machine, under 2 kN on another: the solver's steps follow
    the CPU's rounding); everywhere else the solutions agree within the tolerance."""
    return int(np.count_nonzero(deviation_N.max(axis=1) >= limit_N))


@pytest.mark.parametrize("rtol", [1e-3, 1e-5])
def test_tolerance_is_configurable_and_results_agree(rtol: float, result: SimulationResult) -> None:
    r = simulate(rtol=rtol)
    deviation_N = np.abs(r.force_true_N - result.force_true_N)
    assert fold_stop_samples(deviation_N, 2_000.0) <= 1
    assert np.percentile(deviation_N, 99) < 500.0


def test_impulsive_noise_is_seeded_and_removed_by_the_median() -> None:
    from estimator import running_median

    clean = simulate(rtol=1e-3)
    noisy = simulate(rtol=1e-3, noise=ImpulsiveNoise(rate_per_s=2.0, amplitude_Pa=3e6, seed=5))
    again = simulate(rtol=1e-3, noise=ImpulsiveNoise(rate_per_s=2.0, amplitude_Pa=3e6, seed=5))
    other = simulate(rtol=1e-3, noise=ImpulsiveNoise(rate_per_s=2.0, amplitude_Pa=3e6, seed=6))
    assert np.array_equal(noisy.p_piston_Pa, again.p_piston_Pa)
    assert not np.array_equal(noisy.p_piston_Pa, other.p_piston_Pa)
    spikes = np.abs(noisy.p_piston_Pa - clean.p_piston_Pa) > 1e5
    assert 100 < spikes.sum() < 1500
    leg = ModelParams().leg
    raw = foot_force_N(noisy.p_piston_Pa[:, 0], noisy.p_rod_Pa[:, 0], leg)
    raw_clean = foot_force_N(clean.p_piston_Pa[:, 0], clean.p_rod_Pa[:, 0], leg)
    assert np.abs(raw - raw_clean).max() > 5_000.0
    # Isolated one-sample spikes do not survive an 11-sample median: with fewer than six
    # spikes in a window, its median lies within the clean values of that window (a bound
    # that holds exactly, whatever the signal does; the raw spikes break it).
    window = 11
    padded = np.concatenate([np.full(window - 1, np.nan), raw_clean])
    windows = np.lib.stride_tricks.sliding_window_view(padded, window)
    low, high = np.nanmin(windows, axis=1), np.nanmax(windows, axis=1)
    spiky = np.convolve(np.abs(raw - raw_clean) > 0, np.ones(window), mode="full")[: len(raw)]
    judged = spiky < (window + 1) // 2
    assert judged.mean() > 0.99
    filtered = running_median(raw, window)
    assert np.all((filtered >= low - 1e-6) & (filtered <= high + 1e-6) | ~judged)
    assert not np.all((raw >= low - 1e-6) & (raw <= high + 1e-6))


@pytest.fixture(scope="module")
def walk() -> SimulationResult:
    """Both steps of a walking cycle: SB2 lifted (0..45 s), then SB1 (45..90 s)."""
    return simulate(rtol=1e-3, steps=2)


def test_the_first_of_two_steps_is_the_one_step_cycle(
    walk: SimulationResult, result: SimulationResult
) -> None:
    assert walk.t_s[-1] == pytest.approx(90.0)
    # Within the solver's tolerance (rtol 1e-3 against 1e-5: the fold stop differs most).
    deviation = np.abs(walk.force_true_N[walk.t_s <= 45.0] - result.force_true_N)
    assert fold_stop_samples(deviation, 2_500.0) <= 1 and np.percentile(deviation, 99) < 500.0
    # The second step starts where the first ends: no jump in any force at t = 45 s.
    at = int(np.searchsorted(walk.t_s, 45.0))
    assert np.max(np.abs(np.diff(walk.force_true_N[at - 5 : at + 5], axis=0))) < 50.0


def test_the_second_step_lifts_sb1_while_sb2_stands(walk: SimulationResult) -> None:
    """The same movement with the bases' roles swapped: the carriage moves over SB2, SB1
    is lifted and folded up, the bridge turns about SB2's axis and ends over SB2_F1."""
    mg = ModelParams().mass_kg * G_M_S2
    lifted = window(walk, 57.5, 88.0)
    assert np.all(walk.force_true_N[lifted][:, :3] == 0.0), "SB1's feet are in the air"
    assert np.all(walk.force_true_N[lifted][:, 3:] > 15_000.0), "SB2 stands on all three"
    still = window(walk, 57.5, 62.0) | window(walk, 72.0, 76.0)
    assert walk.force_true_N[still].sum(axis=1) == pytest.approx(mg, rel=2e-3)
    # Mirror of the first step: three feet at 180..190 kPa, ~230 kPa on the foot under
    # the bridge (now SB2_F1) at the end, a fold-stop peak over 310 kPa.
    kPa = pressure_kPa(walk)
    assert np.all(kPa[window(walk, 57.5, 63.0), 3:].mean(axis=0) >= 162)
    late = kPa[window(walk, 85.0, 88.0)].mean(axis=0)
    assert 195 <= late[LEGS.index("SB2_F1")] <= 253 and late.argmax() == LEGS.index("SB2_F1")
    assert kPa[window(walk, 67.5, 69.5)].max() > 310
    # At the end all six feet are down again, SB2 (under the carriage) carrying the most.
    end = walk.force_true_N[-1]
    assert end.sum() == pytest.approx(mg, rel=2e-3)
    assert np.all(end > 15_000.0) and 0.5 <= end[3:].sum() / end.sum() <= 0.75, end


def test_signals_of_the_second_step(walk: SimulationResult) -> None:
    def at(t: float) -> int:
        return int(np.searchsorted(walk.t_s, t))

    assert [walk.phase[at(t)] for t in (46, 49, 60, 72, 85)] == [0, 1, 2, 3, 4]
    assert walk.rotation_deg[at(65.0)] == pytest.approx(180.0)
    assert walk.rotation_deg[at(78.0)] == pytest.approx(0.0, abs=1e-9)
    # The carriage starts over SB1 (+, towards SB1) and goes behind SB2 (-).
    assert walk.carriage_m[at(45.5)] == pytest.approx(1.5)
    assert walk.carriage_m[at(60.0)] == pytest.approx(-5.08)
    assert walk.stroke_m[at(65.0)] == pytest.approx([0.3, 0.3, 0.3, 1.0, 1.0, 1.0])
    # SB2's inclination joint lifts: continuous from the first step's set-down, and
    # level again after the second's.
    assert walk.inclination_deg[at(60.0), 1] == pytest.approx(3.0, abs=0.05)
    assert walk.inclination_deg[at(60.0), 0] == -walk.inclination_deg[at(60.0), 1]
    assert np.max(np.abs(np.diff(walk.inclination_deg[at(44.0) : at(46.0)], axis=0))) < 1e-3
    assert walk.inclination_deg[-1] == pytest.approx([0.0, 0.0], abs=1e-9)
    assert not walk.slipping.any()


@pytest.mark.parametrize("steps", [0, 3])
def test_steps_beyond_the_walking_cycle_are_refused(steps: int) -> None:
    with pytest.raises(ValueError, match="steps must be 1..2"):
        simulate(steps=steps)
