"""``portal-daq calibrate`` on a recording of the simulated cycle made with a wrong config.

The simulator runs the true machine, with known transducer zero offsets on the piston
pressures; the service records with a config whose lever ratios are off by known
amounts. The cycle moves SB2 only: SB2's feet are in the air (t = 12..44 s), SB1's never, and
the vertical balance cannot tell a common scale of the gains from the offsets' sum
(see estimator.calibration): the command must refuse, saying why, and write nothing.
"""

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest

from daq.calibrate.command import calibrate_main
from daq.frames import RawFrame
from daq.mcap_file import CONFIG_ATTACHMENT, DBC_ATTACHMENT, McapFile
from daq.pipeline import Pipeline
from dbc import DEFAULT_DBC_PATH
from dbc.encoding import FrameEncoder
from dbc.machine import load_machine_config
from sim_bridge.frames import FrameBuilder
from sim_bridge.model import simulate
from sim_bridge.playout import Playout
from sim_bridge.schedule import instants, schedule
from tests.helpers import EXAMPLE_CONFIG

LEGS = ("SB1_F1", "SB1_F2", "SB1_F3", "SB2_F1", "SB2_F2", "SB2_F3")
RATIO_ERROR = dict(zip(LEGS, (-0.06, 0.04, 0.03, -0.05, 0.05, -0.02), strict=True))
ZERO_OFFSET_PA = np.array([2e5, -1.5e5, 1e5, -1e5, 1.5e5, 0.5e5])
T0_S = 1.8e9


def wrong_config(path: Path) -> Path:
    """The example with each leg's l_r_m set so that its lever ratio is off as above."""
    config = load_machine_config(EXAMPLE_CONFIG)[0]
    g = config.legs["SB1_F1"].geometry
    a = g.alpha_cyl_rad
    text = EXAMPLE_CONFIG.read_text()
    for leg, error in RATIO_ERROR.items():
        l_r_m = (g.force_ratio * (1 + error) * g.l_b_m + g.l_z_m * math.cos(a)) / math.sin(a)
        header = f"[legs.{leg}]\n"
        text = text.replace(header, f"{header}l_r_m = {l_r_m!r}\n")
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    directory = tmp_path_factory.mktemp("calibrate")
    config_path = wrong_config(directory / "wrong.toml")
    wrong, database = load_machine_config(config_path)
    true, _ = load_machine_config(EXAMPLE_CONFIG)
    result = simulate(rtol=1e-3)
    result = dataclasses.replace(result, p_piston_Pa=result.p_piston_Pa + ZERO_OFFSET_PA)
    playout = Playout(result, FrameBuilder(true, database), FrameEncoder(database, true.protection))
    pipeline = Pipeline.from_config(wrong, database)
    path = directory / "cycle.mcap"
    with open(path, "wb") as stream, McapFile(stream, database) as mcap:
        mcap.start(
            {
                CONFIG_ATTACHMENT: config_path.read_bytes(),
                DBC_ATTACHMENT: DEFAULT_DBC_PATH.read_bytes(),
            }
        )
        for instant in instants(schedule(playout.cycles, end_sim_ns=playout.timeline.cycle_ns)):
            for item in playout.frames(instant)[1]:
                frame = item.frame
                t_s = T0_S + instant.sim_t_ns / 1e9
                mcap.write_result(
                    pipeline.process(
                        RawFrame(t_s, frame.arbitration_id, frame.is_extended_id, frame.data)
                    )
                )
    return path, config_path


def test_calibrate_refuses_what_the_cycle_cannot_identify(
    recording: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """SB1's feet never leave the ground: its offsets are seen only as their sum, which
    trades against the common scale of its gains (and through the six-feet instants
    against SB2's): nothing can be written, and the command says why."""
    path, _ = recording
    out = tmp_path / "cal" / "calibration.toml"
    assert calibrate_main([str(path), "--out", str(out)]) == 1  # the embedded (wrong) config
    stdout, stderr = capsys.readouterr()
    assert stdout == "" and not out.exists()
    lines = stderr.splitlines()
    assert re.fullmatch(
        r"portal-daq calibrate: \d{3} quasi-static instants of 45\d snapshots; data rank \d+ of "
        r"12, condition \d+",
        lines[0],
    )
    assert re.fullmatch(
        r"portal-daq calibrate: weight residual RMS over them: \d+ N before, \d+ N after",
        lines[1],
    )
    assert lines[2].startswith("portal-daq calibrate: gains are not identifiable")
    assert "force_offset_N of SB1_F1, SB1_F2, SB1_F3" in lines[3]
    assert lines[-1].startswith("portal-daq: ")
    # With the right config the same recording still cannot be calibrated.
    assert calibrate_main([str(path), "--config", str(EXAMPLE_CONFIG), "--out", str(out)]) == 1


def test_calibrate_refuses_bad_input(
    recording: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[machine]\nid = 'x'\n")
    assert calibrate_main([str(recording[0]), "--config", str(bad)]) == 2
    not_mcap = tmp_path / "x.mcap"
    not_mcap.write_bytes(b"hello")
    assert calibrate_main([str(not_mcap), "--config", str(recording[1])]) == 1
    stderr = capsys.readouterr().err
    assert len(stderr.splitlines()) == 2 and stderr.startswith("portal-daq: ")
