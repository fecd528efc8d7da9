"""``portal-daq check --config FILE``: a configuration checked against its DBC without a
bus or a log, each leg's mapping printed (exit 0), a wrong key one line (exit 2)."""

import shutil
from pathlib import Path

import pytest

from daq.cli import main
from daq.init_command import init_main
from tests.helpers import FILES

STRANGER = FILES / "stranger"


def test_each_legs_chambers_are_shown_as_read(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "--config", str(STRANGER / "iom_channels.toml")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].endswith(
        "machine iom, 4 legs, DBC " + str(STRANGER / "iom_channels.dbc") + " (2 messages)"
    )
    assert lines[4:7] == [
        "leg VR: sample on each rod value, the other chamber's at most 10 ms older",
        "  piston: IOM_VORNE_AIN.AIN_Druck[Kanal=2] in 'mbar', every 10 ms, status "
        "AIN_Diagnose (fine: OK)",
        "  rod: IOM_VORNE_AIN.AIN_Druck[Kanal=3] in 'mbar', every 10 ms, status AIN_Diagnose "
        "(fine: OK)",
    ]
    assert lines[-2:] == [
        "protected IOM_VORNE_AIN: counter IOM_Zaehler 0..15 (steps up to 2)",
        "protected IOM_HINTEN_AIN: counter IOM_Zaehler 0..15 (steps up to 2)",
    ]
    assert main(["check", "--config", str(STRANGER / "xdcr_two_rates.toml")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert (
        "  rod: XDCR_ROD.HydPress@0x53 in 'kPa', every 50 ms, status SensorState (fine: Ok)"
        in lines
    )
    assert (
        "  piston: XDCR_PISTON.Pressure@0x42 in 'psi', every 10 ms, status SensorState (fine: Ok)"
        in lines
    )


def test_each_legs_equation_is_shown_with_its_constants(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # By hand: (0.95 sin 82.5 deg - 0.25 cos 82.5 deg) / 1.2 = 0.757701; 0.65 / 1.2 x
    # 4905 N = 2656.88 N. Nothing showed the constants a leg of its own geometry got.
    assert main(["check", "--config", str(FILES / "machine_distinct_legs.toml")]) == 0
    assert (
        "eq. (4) SB2_F3: F_zFoot = 0.757701 x F_cyl + 2656.88 N, F_cyl = p_piston x 0.0085 "
        "m2 - p_rod x 0.004737 m2; p_ground = F_zFoot / 0.33 m2"
    ) in capsys.readouterr().out.splitlines()
    text = (
        (FILES / "machine_distinct_legs.toml")
        .read_text()
        .replace(
            "[legs.SB2_F3]\n", "[legs.SB2_F3]\nforce_gain = 1.1\nforce_offset_N = -3000.0\n", 1
        )
    )
    text = text.replace('dbc = "../../dbc/', f'dbc = "{FILES.parent.parent}/dbc/', 1)
    (tmp_path / "m.toml").write_text(text)
    assert main(["check", "--config", str(tmp_path / "m.toml")]) == 0
    assert (
        "eq. (4) SB2_F3: F_zFoot = 0.833471 x F_cyl - 343.125 N (lever 0.757701 x gain 1.1; "
        "leg 2656.88 N, offset -3000 N), F_cyl = p_piston x 0.0085 m2 - p_rod x 0.004737 m2; "
        "p_ground = F_zFoot / 0.33 m2"
    ) in capsys.readouterr().out.splitlines()


def test_a_service_config_written_by_init_checks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert init_main([str(tmp_path), "--example", "j1939"]) == 0
    capsys.readouterr()
    assert main(["check", "--config", str(tmp_path / "portal-daq.toml")]) == 0
    out = capsys.readouterr().out
    assert "machine hda-j1939, 6 legs" in out
    assert "  rod: HYD_PRESS.Pressure@0x2C in 'bar', every 10 ms, status Status (fine: ok)" in out


def test_a_wrong_key_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    shutil.copy(STRANGER / "split_rates.dbc", tmp_path)
    text = (STRANGER / "split_rates.toml").read_text()
    (tmp_path / "m.toml").write_text(text.replace("p_Stange_F2", "p_stange_f2", 1))
    assert main(["check", "--config", str(tmp_path / "m.toml")]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == (
        f"portal-daq: {tmp_path / 'm.toml'}: legs.SB1_F2.rod: no signal 'p_stange_f2' in "
        "message STANGE_SB1 of the DBC; did you mean p_Stange_F2?\n"
    )


@pytest.mark.parametrize(
    ("zenoh_lines", "json5", "where", "reason"),
    [
        ('connect = ["tcp/10.0.0.1:99999"]', None, "zenoh.connect", "port 99999 is beyond 65535"),
        ('config_file = "z.json5"', "{ mode: 3 }", "z.json5", "not a valid Zenoh config"),
        ('config_file = "."', None, "zenoh.config_file", "it is a directory"),
        ('config_file = "/dev/null"', None, "zenoh.config_file", "not a regular file"),
    ],
)
def test_the_zenoh_part_is_checked_as_run_opens_it(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    zenoh_lines: str,
    json5: str | None,
    where: str,
    reason: str,
) -> None:
    # check said fine (exit 0) where run then stopped with exit 2: the JSON5 file and the
    # endpoints were only read when the session was opened.
    assert init_main([str(tmp_path)]) == 0
    config = tmp_path / "portal-daq.toml"
    text = config.read_text()
    config.write_text(text.replace('config_file = "zenoh.json5"', zenoh_lines, 1))
    if json5 is not None:
        (tmp_path / "z.json5").write_text(json5)
    capsys.readouterr()
    assert main(["check", "--config", str(config)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("portal-daq: ") and err.count("\n") == 1
    assert f"{where}: " in err and reason in err


def test_each_protected_message_shows_how_it_is_checked(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The counter's values (AUTOSAR E2E profile 1's 0..14 where the DBC says [0|15]), the
    largest step taken, the CRC's algorithm, data ID and profile 1's data ID mode: a config
    naming the wrong profile or mode shows before a bus does; it said only the names."""
    assert main(["check", "--config", str(STRANGER / "e2e_p1_modes.toml")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-5:] == [
        "protected ZYL_VL: counter ZYL_VL_Zaehler 0..14 (steps up to 2), "
        "CRC ZYL_VL_Pruefsumme e2e_p1, data ID 0x0123 (both)",
        "protected ZYL_VR: counter ZYL_VR_AliveCounter 0..14 (steps up to 2), "
        "CRC ZYL_VR_Checksum e2e_p1, data ID 0x1234 (alt)",
        "protected ZYL_HL: counter ZYL_HL_MsgCntr 0..14 (steps up to 2), "
        "CRC ZYL_HL_CRC8 e2e_p1, data ID 0x0056 (low)",
        "protected ZYL_HR: counter ZYL_HR_Cnt 0..14 (steps up to 1), "
        "CRC ZYL_HR_CRC e2e_p1, data ID 0x0A42 (nibble in ZYL_HR_DataIDNibble)",
        "protected MASCHINE_ZUSTAND: counter MZ_Zaehler 0..15 (steps up to 2), CRC MZ_CRC "
        "e2e_p2, data ID list 0x60, 0x61, 0x62, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69, "
        "0x6A, 0x6B, 0x6C, 0x6D, 0x6E, 0x6F by counter",
    ]
