"""Leg chambers in a multiplexed message (a sensor hub sending one leg per multiplexer
value): each frame makes the samples of the legs it carries, a leg's chambers in two
multiplexer values pair by the timing rule, and what cannot work is refused at load.
The bridge playing this hub: tests/sim_bridge/test_multiplexed.py."""

from pathlib import Path

import pytest
from cantools.database.can import Database

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.errors import ConfigError
from dbc.machine import MachineConfig, load_machine_config
from estimator import foot_force_N
from tests.helpers import LEG_DEFAULTS_TOML, dbc_text

DBC = dbc_text(
    """
BO_ 512 HUB_PRESS: 8 Hub
 SG_ Leg M : 0|8@1+ (1,0) [0|5] "" DAQ
 SG_ A_pPiston m0 : 8|16@1+ (0.01,0) [0|655.35] "BAR" DAQ
 SG_ A_pRod m0 : 24|16@1+ (0.01,0) [0|655.35] "BAR" DAQ
 SG_ B_pPiston m1 : 8|16@1+ (0.01,0) [0|655.35] "BAR" DAQ
 SG_ B_pRod m1 : 24|16@1+ (0.01,0) [0|655.35] "BAR" DAQ
 SG_ C_pPiston m2 : 8|16@1+ (0.01,0) [0|655.35] "bar" DAQ
 SG_ C_Status m2 : 24|8@1+ (1,0) [0|1] "" DAQ
 SG_ C_pRod m3 : 8|16@1+ (0.01,0) [0|655.35] "bar" DAQ
 SG_ HubTemp m5 : 8|8@1+ (1,-40) [-40|215] "degC" DAQ
 SG_ HubStatus : 56|8@1+ (1,0) [0|255] "" DAQ

BO_ 513 LEG_PLAIN: 4 Hub
 SG_ pPiston : 0|16@1+ (0.01,0) [0|655.35] "bar" DAQ
 SG_ pRod : 16|16@1+ (0.01,0) [0|655.35] "bar" DAQ

BO_ 514 DIAG: 8 Hub
 SG_ DiagMux M : 0|8@1+ (1,0) [0|1] "" DAQ
 SG_ Machine_Phase m0 : 8|8@1+ (1,0) [0|4] "" DAQ
 SG_ Machine_CycleTime m1 : 8|16@1+ (0.01,0) [0|655.35] "s" DAQ
""",
    """
BA_ "GenMsgCycleTime" BO_ 512 10;
BA_ "GenMsgCycleTime" BO_ 513 10;
BA_ "GenMsgCycleTime" BO_ 514 100;
VAL_ 512 HubStatus 0 "ok" 1 "fault";
""",
)

CONFIG = (
    """
[machine]
id = "mux"
mass_kg = 5000.0
dbc = "hub.dbc"

"""
    + LEG_DEFAULTS_TOML
    + """
[legs.SB1_F1]
piston = "HUB_PRESS.A_pPiston"
rod = "HUB_PRESS.A_pRod"
status = "HUB_PRESS.HubStatus"

[legs.SB1_F2]
piston = "HUB_PRESS.B_pPiston"
rod = "HUB_PRESS.B_pRod"

[legs.SB1_F3]
piston = { signal = "HUB_PRESS.C_pPiston", status = "C_Status", status_ok = 0 }
rod = "HUB_PRESS.C_pRod"
max_skew_s = 0.02
"""
)


def _load(tmp_path: Path, config: str = CONFIG) -> tuple[MachineConfig, Database]:
    (tmp_path / "hub.dbc").write_text(DBC)
    (tmp_path / "machine.toml").write_text(config)
    return load_machine_config(tmp_path / "machine.toml")


def _frame(database: Database, t_s: float, values: dict[str, float | int]) -> RawFrame:
    message = database.get_message_by_name("HUB_PRESS")
    data = message.encode({"HubStatus": 0} | values, strict=False)
    return RawFrame(t_s, 512, False, bytes(data))


def test_each_frame_makes_the_samples_of_the_legs_of_its_multiplexer_value(
    tmp_path: Path,
) -> None:
    config, database = _load(tmp_path)
    pipeline = Pipeline.from_config(config, database)
    a = pipeline.process(_frame(database, 1.0, {"Leg": 0, "A_pPiston": 120, "A_pRod": 15}))
    b = pipeline.process(_frame(database, 1.005, {"Leg": 1, "B_pPiston": 80, "B_pRod": 30}))
    assert [e.leg for e in a.estimates] == ["SB1_F1"]
    assert [e.leg for e in b.estimates] == ["SB1_F2"]
    assert a.estimates[0].valid and b.estimates[0].valid
    for result, (p_piston_bar, p_rod_bar) in ((a, (120, 15)), (b, (80, 30))):
        estimate = result.estimates[0]
        geometry = config.legs[estimate.leg].geometry
        expected_N = foot_force_N(p_piston_bar * 1e5, p_rod_bar * 1e5, geometry)
        assert estimate.force_raw_N == pytest.approx(expected_N, rel=1e-12)
    diagnostics = pipeline.process(_frame(database, 1.006, {"Leg": 5, "HubTemp": 20}))
    assert diagnostics.decoded is not None and diagnostics.estimates == ()
    assert not pipeline.bad


def test_chambers_in_two_multiplexer_values_pair_by_the_timing_rule(tmp_path: Path) -> None:
    config, database = _load(tmp_path)
    pipeline = Pipeline.from_config(config, database)
    rod = pipeline.process(_frame(database, 2.0, {"Leg": 3, "C_pRod": 12}))
    piston = pipeline.process(_frame(database, 2.01, {"Leg": 2, "C_pPiston": 150, "C_Status": 0}))
    assert rod.estimates == ()
    (estimate,) = piston.estimates
    assert estimate.valid, estimate.reasons
    assert (estimate.p_piston_Pa, estimate.p_rod_Pa) == pytest.approx((150e5, 12e5))
    faulty = pipeline.process(_frame(database, 2.015, {"Leg": 2, "C_pPiston": 150, "C_Status": 1}))
    assert faulty.estimates[0].reasons == ("status_1",)


def test_a_status_in_another_multiplexer_value_than_its_chamber_is_refused(
    tmp_path: Path,
) -> None:
    config = CONFIG.replace(
        '{ signal = "HUB_PRESS.C_pPiston", status = "C_Status", status_ok = 0 }',
        '"HUB_PRESS.C_pPiston"',
    ).replace(
        'rod = "HUB_PRESS.C_pRod"', 'rod = { signal = "HUB_PRESS.C_pRod", status = "C_Status" }'
    )
    with pytest.raises(ConfigError, match=r"legs\.SB1_F3\.rod\.status: C_Status .*multiplexer"):
        _load(tmp_path, config)
