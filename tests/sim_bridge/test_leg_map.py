"""Which simulated leg plays each config leg: by name, stated (``simulated_leg``), derived
from ``[stability.bases]`` (foot angles, else feet order) or from the legs' order; and
the one-line errors where none applies."""

import math
import tomllib
from pathlib import Path
from types import SimpleNamespace as Leg
from typing import Any

import pytest

from dbc.errors import ConfigError
from dbc.machine import load_machine_config, parse_machine_config
from sim_bridge.__main__ import cli
from sim_bridge.leg_map import leg_map
from sim_bridge.result import LEGS
from tests.helpers import EXAMPLE_CONFIG, FILES

RENAMED = FILES / "renamed" / "machine.toml"
#: The renamed machine's legs, as the simulation's feet angles place them.
RENAMED_LEGS = {
    "near_tip": "SB1_F1",
    "near_left": "SB1_F2",
    "near_right": "SB1_F3",
    "far_tip": "SB2_F1",
    "far_left": "SB2_F2",
    "far_right": "SB2_F3",
}


def renamed_data() -> dict[str, Any]:
    return tomllib.loads(RENAMED.read_text())


def renamed_without_stability() -> dict[str, Any]:
    data = renamed_data()
    del data["stability"]
    del data["signals"]["bases"]  # named after [stability]'s bases
    return data


def parsed(data: dict[str, Any], name: str = "m.toml"):  # type: ignore[no-untyped-def]
    config, database = load_machine_config(RENAMED)
    return parse_machine_config(data, name, database, config.dbc_path)


def test_legs_named_like_the_simulations_are_those() -> None:
    config, _ = load_machine_config(EXAMPLE_CONFIG)
    legs = leg_map(config)
    assert legs.simulated == {leg: leg for leg in LEGS} and legs.rule == "leg names"
    assert legs.columns == {leg: i for i, leg in enumerate(LEGS)}


def test_renamed_legs_are_placed_by_their_feet_angles_not_their_order() -> None:
    config, _ = load_machine_config(RENAMED)
    legs = leg_map(config)
    # the config lists the legs, and each base its feet, in another order
    assert list(config.legs) != list(RENAMED_LEGS)
    assert list(config.stability.layout.bases[0].feet_m)[0] == "near_left"  # type: ignore[union-attr]
    assert dict(legs.simulated) == RENAMED_LEGS
    assert list(legs.simulated) == list(config.legs)
    assert legs.rule == "[stability.bases] (near's feet by angle, far's feet by angle)"
    assert str(legs).startswith("far_left=SB2_F2, near_right=SB1_F3")


def test_feet_off_the_simulations_angles_go_by_their_order() -> None:
    data = renamed_data()
    # the far base's feet turned by 60 deg: each foot between two of the simulation's
    turned = {}
    for leg, (x, y) in data["stability"]["bases"]["far"]["feet_m"].items():
        angle = math.atan2(y, x) + math.radians(60)
        turned[leg] = [1.6 * math.cos(angle), 1.6 * math.sin(angle)]
    data["stability"]["bases"]["far"]["feet_m"] = turned
    legs = leg_map(parsed(data))
    assert legs.rule == "[stability.bases] (near's feet by angle, far's feet by order)"
    # feet order: far_right, far_tip, far_left
    assert [legs.simulated[leg] for leg in ("far_right", "far_tip", "far_left")] == list(LEGS[3:])
    assert {legs.simulated[leg] for leg in ("near_tip", "near_left", "near_right")} == set(LEGS[:3])
    assert legs.simulated["near_tip"] == "SB1_F1"


def test_without_stability_the_legs_order_decides() -> None:
    legs = leg_map(parsed(renamed_without_stability()))
    assert list(legs.simulated.values()) == list(LEGS)
    assert list(legs.simulated) == [
        "far_left",
        "near_right",
        "near_tip",
        "far_tip",
        "near_left",
        "far_right",
    ]
    assert legs.rule == "the legs' order in the config"


def test_a_stated_simulated_leg_wins_over_the_derived_one() -> None:
    data = renamed_data()
    # mirrored: the near base's feet play SB2's, the far base's SB1's
    stated = {
        leg: ("SB2" if sim[:3] == "SB1" else "SB1") + sim[3:] for leg, sim in RENAMED_LEGS.items()
    }
    for leg, sim in stated.items():
        data["legs"][leg]["simulated_leg"] = sim
    config = parsed(data)
    assert config.legs["near_tip"].simulated_leg == "SB2_F1"
    legs = leg_map(config)
    assert dict(legs.simulated) == stated and legs.rule == "simulated_leg"
    assert legs.columns["near_tip"] == LEGS.index("SB2_F1")


def test_stated_and_named_legs_mix() -> None:
    data = tomllib.loads(EXAMPLE_CONFIG.read_text())
    data["legs"]["FRONT"] = data["legs"].pop("SB1_F1") | {"simulated_leg": "SB1_F1"}
    del data["stability"]  # it names the feet of the example's legs
    legs = leg_map(parse_machine_config(data, "m.toml", load_machine_config(EXAMPLE_CONFIG)[1]))
    assert legs.simulated["FRONT"] == "SB1_F1" and legs.simulated["SB2_F3"] == "SB2_F3"
    assert legs.rule == "simulated_leg and leg names"


@pytest.mark.parametrize(
    ("values", "message"),
    [
        (
            {"near_tip": "SB3_F1"},
            r"^m.toml: legs.near_tip.simulated_leg: the simulation has no leg 'SB3_F1'; "
            "its legs are SB1_F1, ",
        ),
        ({"near_tip": 1}, r"^m.toml: legs.near_tip.simulated_leg: must be a non-empty string"),
        (
            {"near_tip": "SB1_F1", "far_tip": "SB1_F1"},
            r"^m.toml: legs.(near|far)_tip.simulated_leg: SB1_F1 is already legs.(near|far)_tip's "
            "simulated leg",
        ),
    ],
)
def test_a_bad_simulated_leg_stops_the_config_load(values: dict[str, Any], message: str) -> None:
    data = renamed_data()
    for leg, value in values.items():
        data["legs"][leg]["simulated_leg"] = value
    with pytest.raises(ConfigError, match=message):
        parsed(data)


def test_a_bad_simulated_leg_is_one_line_and_status_2_from_the_bridge(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = RENAMED.read_text().replace(
        "[legs.far_tip]\n", '[legs.far_tip]\nsimulated_leg = "SB2_F9"\n'
    )
    (tmp_path / "renamed_sensors.dbc").write_bytes(
        (RENAMED.parent / "renamed_sensors.dbc").read_bytes()
    )
    (tmp_path / "machine.toml").write_text(text)
    assert cli(["--config", str(tmp_path / "machine.toml"), "--interface", "virtual"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line == (
        f"sim_bridge: {tmp_path / 'machine.toml'}: legs.far_tip.simulated_leg: the simulation "
        f"has no leg 'SB2_F9'; its legs are {', '.join(LEGS)}"
    )


def test_a_leg_left_over_says_which_simulated_legs_are_free() -> None:
    data = renamed_data()
    for leg in ("near_tip", "near_left", "near_right", "far_tip", "far_left"):
        data["legs"][leg]["simulated_leg"] = RENAMED_LEGS[leg]
    with pytest.raises(
        ConfigError,
        match=r"^m.toml: legs.far_right: the simulation has no leg 'far_right'; "
        "add simulated_leg = one of SB2_F3$",
    ):
        leg_map(parsed(data))


def test_a_leg_named_like_a_stated_one_is_left_over() -> None:
    data = tomllib.loads(EXAMPLE_CONFIG.read_text())
    data["legs"]["SB1_F2"]["simulated_leg"] = "SB1_F1"
    with pytest.raises(
        ConfigError,
        match=r"legs.SB1_F1: SB1_F1 is legs.SB1_F2's simulated_leg; add simulated_leg = one of "
        "SB1_F2$",
    ):
        leg_map(parse_machine_config(data, "m.toml", load_machine_config(EXAMPLE_CONFIG)[1]))


def test_fewer_or_more_legs_than_six_go_by_their_order() -> None:
    """A machine of fewer legs (a held-out hub of two) plays the first simulated legs; a
    seventh leg plays the first again (it was refused: "the bridge plays six at most")."""
    data = renamed_without_stability()
    del data["legs"]["far_right"]
    del data["legs"]["far_tip"]
    legs = leg_map(parsed(data))
    assert legs.simulated == {
        "far_left": "SB1_F1",
        "near_right": "SB1_F2",
        "near_tip": "SB1_F3",
        "near_left": "SB2_F1",
    }
    assert legs.rule == "the legs' order in the config"
    seven = [f"leg{i}" for i in range(7)]
    config = Leg(
        source="m.toml", stability=None, legs={name: Leg(simulated_leg=None) for name in seven}
    )
    assert list(leg_map(config).simulated.values()) == [*LEGS, "SB1_F1"]
    assert leg_map(config).columns["leg6"] == 0


def test_bases_of_two_or_four_feet_play_their_simulated_bases_legs_in_feet_order() -> None:
    """Each base's feet play its own simulated base's legs (a fourth foot F1 again), so a
    lifted simulated base lifts the config's base; by the legs' order a 2 + 2 machine's
    rear left foot played SB1_F3."""

    def base(name: str, feet: list[str]) -> Leg:
        return Leg(name=name, feet_m={leg: (float(k), 0.0) for k, leg in enumerate(feet)})

    for front, rear, played in [
        (["VL", "VR"], ["HL", "HR"], ["SB1_F1", "SB1_F2", "SB2_F1", "SB2_F2"]),
        (
            ["VL1", "VL2", "VR1", "VR2"],
            ["HL1", "HL2", "HR1", "HR2"],
            ["SB1_F1", "SB1_F2", "SB1_F3", "SB1_F1", "SB2_F1", "SB2_F2", "SB2_F3", "SB2_F1"],
        ),
    ]:
        layout = Leg(bases=(base("front", front), base("rear", rear)))
        config = Leg(
            source="m.toml",
            stability=Leg(layout=layout),
            legs={name: Leg(simulated_leg=None) for name in rear + front},
        )
        legs = leg_map(config)
        assert [legs.simulated[leg] for leg in front + rear] == played
        assert legs.rule == "[stability.bases] (front's feet by order, rear's feet by order)"


def test_legs_beyond_the_six_named_ones_play_the_free_then_the_six_again() -> None:
    """A machine of four legs per base named SB1_F1 .. SB1_F4, SB2_F1 .. SB2_F4: SB1_F4
    and SB2_F4 were refused ("the simulation has no leg 'SB1_F4'; remove the leg")."""
    names = [f"SB{b}_F{f}" for b in (1, 2) for f in (1, 2, 3, 4)]
    config = Leg(source="m.toml", stability=None, legs={n: Leg(simulated_leg=None) for n in names})
    legs = leg_map(config)
    assert {n: legs.simulated[n] for n in ("SB1_F4", "SB2_F4")} == {
        "SB1_F4": "SB1_F1",
        "SB2_F4": "SB1_F2",
    }
    assert all(legs.simulated[n] == n for n in names if n in LEGS)
    assert legs.rule == "leg names and the other legs' order"
    # without a leg SB2_F3, its simulated leg is free: the first left over plays it
    legs_table = {n: Leg(simulated_leg=None) for n in names if n != "SB2_F3"}
    legs_table["rear"] = Leg(simulated_leg=None)
    legs = leg_map(Leg(source="m.toml", stability=None, legs=legs_table))
    assert [legs.simulated[n] for n in ("SB1_F4", "SB2_F4", "rear")] == [
        "SB2_F3",
        "SB1_F1",
        "SB1_F2",
    ]
