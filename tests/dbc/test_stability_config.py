"""The ``[stability]`` table: the example loads, non-default values apply, bad ones refused."""

import math
from pathlib import Path

import pytest

from daq.pose import PoseTracker
from dbc.decoding import DecodedFrame
from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from tests.helpers import EXAMPLE_CONFIG

EXAMPLE = EXAMPLE_CONFIG.read_text()


def load(tmp_path: Path, text: str):  # type: ignore[no-untyped-def]
    path = tmp_path / "machine.toml"
    path.write_text(text)
    return load_machine_config(path)[0]


def test_example_layout_and_non_default_values(tmp_path: Path) -> None:
    stability = load_machine_config(EXAMPLE_CONFIG)[0].stability
    assert stability is not None
    assert [base.name for base in stability.layout.bases] == ["SB1", "SB2"]
    assert str(stability.rotation) == "BRIDGE_MOTION.Bridge_RotationAngle"
    assert stability.warning_margin_m == 0.3
    text = EXAMPLE.replace("warning_margin_m = 0.3", "warning_margin_m = 0.5").replace(
        "hinge_m = 3.0", "hinge_m = 2.0"
    )
    changed = load(tmp_path, text).stability
    assert changed.warning_margin_m == 0.5 and changed.layout.hinge_m == 2.0
    # Folded by 90 deg the far base's axis sits at the hinge: 0.07 + 2.0 along x; with
    # SB2 standing (its axis at 0), 6.0 - 2.0 from SB2's axis, and SB1 turned round.
    assert changed.layout.feet_m(0.0, 1.5707963267948966)["SB2_F1"] == pytest.approx((3.67, 0))
    sb2 = changed.layout.feet_m(0.0, 1.5707963267948966, standing=1, far_bridge_rad=0.0)
    assert sb2["SB1_F1"] == pytest.approx((4.0 + 0.07 - 1.6, 0))


def test_without_the_table_there_is_no_margin(tmp_path: Path) -> None:
    start = EXAMPLE.index("[stability]")
    end = EXAMPLE.index("# End-to-end protection")
    assert load(tmp_path, EXAMPLE[:start] + EXAMPLE[end:]).stability is None


@pytest.mark.parametrize(
    ("old", "new", "key", "reason"),
    [
        ("warning_margin_m = 0.3", "warning_margin_m = -0.1", "stability.warning_margin_m", ">= 0"),
        ("hinge_m = 3.0", "hinge_m = 7.0", "stability.hinge_m", "on the bridge"),
        ("bridge_length_m = 6.0", "bridge_length_m = 0", "stability.bridge_length_m", "> 0"),
        (
            'rotation = "BRIDGE_MOTION.Bridge_RotationAngle"',
            'rotation = "BRIDGE_MOTION.Carriage_Position"',
            "stability.rotation",
            "deg",
        ),
        (
            'fold = "BRIDGE_POSE.Bridge_FoldAngle"',
            'fold = "BRIDGE_POSE.Fold"',
            "stability.fold",
            "no signal",
        ),
        (
            'rotation = "BRIDGE_MOTION.Bridge_RotationAngle"',
            'rotation = { signal = "BRIDGE_MOTION.Bridge_RotationAngle", unit = "furlong" }',
            "stability.rotation.unit",
            "'furlong' is not an angle unit; use one of deg",
        ),
        (  # the table form names its signal key, and itself for the DBC's unit
            'fold = "BRIDGE_POSE.Bridge_FoldAngle"',
            'fold = { signal = "BRIDGE_POSE.Fold" }',
            "stability.fold.signal",
            "no signal 'Fold' in message BRIDGE_POSE",
        ),
        (
            'rotation = "BRIDGE_MOTION.Bridge_RotationAngle"',
            'rotation = { signal = "BRIDGE_MOTION.Carriage_Position" }',
            "stability.rotation",
            "has unit 'm' in the DBC, not an angle unit",
        ),
        (
            'fold = "BRIDGE_POSE.Bridge_FoldAngle"',
            'fold = { signal = "BRIDGE_POSE.Bridge_FoldAngle", units = "rad" }',
            "stability.fold.units",
            "unknown key",
        ),
        ("axis_m = [0.07, 0.0]", "axis_m = [0.07]", "stability.bases.SB1.axis_m", "[x, y]"),
        (
            "SB1_F1 = [1.6, 0.0]",
            "SB1_F1 = [1.6, true]",
            "stability.bases.SB1.feet_m.SB1_F1",
            "must be a number, got True",
        ),
        # NaN and inf were taken (the margin was NaN), 10**400 an OverflowError traceback.
        (
            "SB1_F1 = [1.6, 0.0]",
            "SB1_F1 = [nan, 0.0]",
            "stability.bases.SB1.feet_m.SB1_F1",
            "finite",
        ),
        ("axis_m = [0.07, 0.0]", "axis_m = [0.07, -inf]", "stability.bases.SB1.axis_m", "finite"),
        (
            "axis_m = [0.07, 0.0]",
            f"axis_m = [{10**400}, 0.0]",
            "stability.bases.SB1.axis_m",
            "must fit in 64 bits",
        ),
        ("SB1_F1 = [1.6, 0.0], ", "", "stability.bases", "missing ['SB1_F1']"),
        ("SB1_F1 = [1.6, 0.0]", "SB1_F9 = [1.6, 0.0]", "stability.bases", "not legs ['SB1_F9']"),
        # Only what is wrong: it said "missing [], not legs [...]".
        (
            "SB1_F1 = [1.6, 0.0], ",
            "SB1_F9 = [1.6, 0.0], SB1_F1 = [1.6, 0.0], ",
            "stability.bases",
            "every leg needs one foot: not legs ['SB1_F9']",
        ),
        # A foot in both bases: the second base's place was taken, silently.
        (
            "SB2_F1 = [1.6, 0.0], ",
            "SB2_F1 = [1.6, 0.0], SB1_F1 = [9.0, 0.0], ",
            "stability.bases",
            "every leg needs one foot: in both bases ['SB1_F1']",
        ),
        (
            "warning_margin_m = 0.3",
            "warning_margin = 0.3",
            "stability.warning_margin",
            "unknown key",
        ),
        (
            "[stability.bases.SB2]",
            "[stability.bases.SB3]\naxis_m = [0.0, 0.0]\nfeet_m = {}\n[stability.bases.SB2]",
            "stability.bases",
            "two bases",
        ),
    ],
)
def test_bad_stability_config_is_refused(
    tmp_path: Path, old: str, new: str, key: str, reason: str
) -> None:
    assert old in EXAMPLE
    with pytest.raises(ConfigError) as info:
        load(tmp_path, EXAMPLE.replace(old, new, 1))
    assert info.value.key == key
    assert reason in str(info.value)


#: No range of values: the DBC's [0|360] deg would refuse 2094 mrad.
UNBOUNDED = (-math.inf, math.inf)


def test_angles_in_another_unit_give_the_same_pose(tmp_path: Path) -> None:
    """The DBC's degrees, or radians and milliradians the config says the values are in:
    one bridge pose, one set of feet."""
    old = 'rotation = "BRIDGE_MOTION.Bridge_RotationAngle"'
    assert old in EXAMPLE
    degrees = load_machine_config(EXAMPLE_CONFIG)[0].stability
    assert degrees is not None and degrees.rotation_rad_per_unit == math.pi / 180
    feet = {}
    for unit, rotation in (("deg", 120.0), ("rad", 2 * math.pi / 3), ("mrad", 2000 * math.pi / 3)):
        given = f'rotation = {{ signal = "BRIDGE_MOTION.Bridge_RotationAngle", unit = "{unit}" }}'
        stability = load(tmp_path, EXAMPLE.replace(old, given)).stability
        ages_s = {"BRIDGE_MOTION": 1.0, "BRIDGE_POSE": 1.0}
        tracker = PoseTracker(stability, ages_s, {"rotation": UNBOUNDED, "fold": UNBOUNDED})
        motion = DecodedFrame("BRIDGE_MOTION", 10.0, {"Bridge_RotationAngle": rotation})
        tracker.observe(motion, 10.0)
        tracker.observe(DecodedFrame("BRIDGE_POSE", 10.0, {"Bridge_FoldAngle": 30.0}), 10.0)
        feet[unit] = tracker.feet_m(10.0, {})
    turned = feet["deg"]
    assert turned is not None and turned["SB2_F1"] == pytest.approx((-3.529038, 6.233717))
    for unit in ("rad", "mrad"):
        assert feet[unit] is not None and feet[unit].keys() == turned.keys()
        for leg, at_m in turned.items():
            assert feet[unit][leg] == pytest.approx(at_m, abs=1e-9)
