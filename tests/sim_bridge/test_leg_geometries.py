"""Legs each of their own geometry: the simulation sends each leg the chamber pressures
its own cylinder and levers need, so that eq. (4) with the config's geometry of that leg
reads the simulated foot force (it sent every leg the first leg's)."""

import dataclasses
import logging

import numpy as np
import pytest

from dbc.machine import load_machine_config
from estimator import foot_force_N
from sim_bridge.__main__ import column_geometries
from sim_bridge.leg_map import leg_map
from sim_bridge.model import simulate
from sim_bridge.params import ModelParams
from tests.helpers import FILES


def test_each_leg_gets_the_pressures_of_its_own_geometry() -> None:
    config, _ = load_machine_config(FILES / "machine_distinct_legs.toml")
    columns = leg_map(config).columns
    first = config.legs["SB1_F1"].geometry
    legs = column_geometries(config, columns, first)
    assert [legs[columns[name]] for name in config.legs] == [
        leg.geometry for leg in config.legs.values()
    ]
    frictionless = ModelParams(
        leg=first, legs=legs, cylinder_viscous_N_s_m=0.0, cylinder_static_friction_N=0.0
    )
    r = simulate(frictionless, rtol=1e-4)
    for name, leg in config.legs.items():
        column = columns[name]
        estimate = foot_force_N(r.p_piston_Pa[:, column], r.p_rod_Pa[:, column], leg.geometry)
        true_N = r.force_true_N[:, column]
        # Exact without friction; with the first leg's geometry SB2_F3 (A_piston 8.5e-3
        # m2 against 7.0e-3, its lever at 82.5 deg against 70) read 55 % high.
        assert np.max(np.abs(estimate - true_N)) < 1e-6 * true_N.max(), name


def test_legs_of_other_geometries_played_as_one_are_named(
    caplog: pytest.LogCaptureFixture,
) -> None:
    config, _ = load_machine_config(FILES / "machine_distinct_legs.toml")
    columns = dict(leg_map(config).columns)
    columns["SB2_F3"] = columns["SB1_F1"]  # two legs of other geometries on one column
    first = config.legs["SB1_F1"].geometry
    # A calibration alone is no other geometry: the design is what the model simulates.
    calibrated = dataclasses.replace(config.legs["SB1_F2"].geometry, force_gain=1.2)
    legs = dict(config.legs) | {
        "SB1_F2": dataclasses.replace(config.legs["SB1_F2"], geometry=calibrated)
    }
    with caplog.at_level(logging.WARNING, logger="sim_bridge"):
        geometries = column_geometries(dataclasses.replace(config, legs=legs), columns, first)
    assert geometries[columns["SB1_F1"]] == first
    assert geometries[5] == first  # SB2_F3's own column: no config leg left on it
    assert [r.getMessage() for r in caplog.records] == [
        "legs.SB2_F3 is played as SB1_F1 with legs.SB1_F1, of another geometry: it is sent "
        "that leg's pressures, so eq. (4) reads other forces than its truth"
    ]
