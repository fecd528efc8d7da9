"""Eq. (3), (4), (5) against independent hand calculations, and the geometry's checks."""

import math

import numpy as np
import pytest

from dbc.machine import load_machine_config
from estimator import LegGeometry, contact_pressure_Pa, cylinder_force_N, foot_force_N
from tests.helpers import FILES, LEGS

DEFAULT = dict(
    A_piston_m2=7.854e-3,
    A_rod_m2=4.737e-3,
    l_r_m=0.90,
    l_z_m=0.25,
    l_b_m=1.20,
    l_gb_m=0.55,
    alpha_cyl_rad=math.radians(75.0),
    F_gLeg_N=4905.0,
    A_foot_m2=0.33,
)


def hand_eq4(pp: float, pr: float, g: dict[str, float]) -> float:
    """Eq. (4) written out as printed in the paper, term by term."""
    a = g["alpha_cyl_rad"]
    F_cyl = pp * g["A_piston_m2"] - pr * g["A_rod_m2"]
    return (
        F_cyl * (g["l_r_m"] * math.sin(a) - g["l_z_m"] * math.cos(a)) / g["l_b_m"]
        + (g["l_gb_m"] / g["l_b_m"]) * g["F_gLeg_N"]
    )


def test_eq4_matches_a_number_worked_out_by_hand() -> None:
    # F_cyl = 10e6*7.854e-3 - 1e6*4.737e-3 = 73803 N
    # lever = 0.9 sin 75 - 0.25 cos 75 = 0.869333 - 0.064705 = 0.804628 m; / 1.2 = 0.670524
    # F = 73803 * 0.670524 + (0.55/1.2) * 4905 = 49486.66 + 2248.13 = 51734.79 N
    leg = LegGeometry(**DEFAULT)
    assert foot_force_N(10e6, 1e6, leg) == pytest.approx(51734.79, abs=0.01)
    assert cylinder_force_N(10e6, 1e6, leg) == pytest.approx(73803.0, abs=1e-6)


def test_eq4_per_leg_against_hand_calculation_with_distinct_geometries() -> None:
    config, _ = load_machine_config(FILES / "machine_distinct_legs.toml")
    rng = np.random.default_rng(4)
    ratios = set()
    for name in LEGS:
        leg = config.legs[name].geometry
        ratios.add(leg.force_ratio)
        g = {key: getattr(leg, key) for key in DEFAULT}
        for pp, pr in rng.uniform(0.0, 30e6, size=(20, 2)):
            assert foot_force_N(pp, pr, leg) == pytest.approx(hand_eq4(pp, pr, g), rel=1e-12)
    assert len(ratios) == len(LEGS), "the fixture should give every leg its own geometry"


def test_eq4_scalar_and_array_paths_are_bit_identical() -> None:
    leg = LegGeometry(**DEFAULT)
    rng = np.random.default_rng(1)
    pp, pr = rng.uniform(-1e5, 4e7, size=(2, 1000))
    batch = foot_force_N(pp, pr, leg)
    streamed = np.array(
        [foot_force_N(float(a), float(b), leg) for a, b in zip(pp, pr, strict=True)]
    )
    assert np.array_equal(batch, streamed)


def test_eq5_divides_by_foot_area() -> None:
    assert contact_pressure_Pa(61_050.0, 0.33) == pytest.approx(185_000.0)
    assert np.allclose(contact_pressure_Pa(np.array([33_000.0, 0.0]), 0.33), [100e3, 0.0])


def test_leg_weight_alone_when_both_chambers_are_empty() -> None:
    leg = LegGeometry(**DEFAULT)
    assert foot_force_N(0.0, 0.0, leg) == pytest.approx(0.55 / 1.2 * 4905.0)


@pytest.mark.parametrize(
    ("change", "word"),
    [
        ({"A_piston_m2": -1.0}, "A_piston_m2"),
        ({"A_rod_m2": 0.0}, "A_rod_m2"),
        ({"A_rod_m2": 8e-3}, "A_rod_m2"),
        ({"l_b_m": 0.0}, "l_b_m"),
        ({"A_foot_m2": float("nan")}, "A_foot_m2"),
        ({"F_gLeg_N": -5.0}, "F_gLeg_N"),
        ({"alpha_cyl_rad": 0.0}, "cannot carry the foot"),
    ],
)
def test_geometry_refuses_impossible_values(change: dict[str, float], word: str) -> None:
    with pytest.raises(ValueError, match=word):
        LegGeometry(**{**DEFAULT, **change})
