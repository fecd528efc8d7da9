"""A machine whose legs are in a CAN FD message: the bridge sends FD frames (and opens
the bus for FD), its frames log keeps them FD in every format, and they replay into
eq. (4) of the pressures sent."""

from pathlib import Path

import can
import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from daq.replay import can_log_frames
from dbc.encoding import FrameEncoder
from dbc.machine import load_machine_config
from estimator import foot_force_N
from sim_bridge.emitter import Emitter, end_of_run_ns
from tests.helpers import LEG_DEFAULTS_TOML, LEGS, dbc_text
from tests.sim_bridge.synthetic import make_playout, make_result

SIGNALS = "\n".join(
    f' SG_ {leg}_p{chamber} : {16 * (2 * i + k) + 7}|16@0+ (1,0) [0|65535] "kPa" DAQ'
    for i, leg in enumerate(LEGS)
    for k, chamber in enumerate(("Piston", "Rod"))
)
DBC = dbc_text(
    f"BO_ 768 ALL_LEGS: 32 Hub\n{SIGNALS}",
    'BA_ "GenMsgCycleTime" BO_ 768 10;\nBA_ "VFrameFormat" BO_ 768 14;\n',
)
LEG_TABLES = "".join(
    f'[legs.{leg}]\npiston = "ALL_LEGS.{leg}_pPiston"\nrod = "ALL_LEGS.{leg}_pRod"\n'
    for leg in LEGS
)
CONFIG = f'[machine]\nid = "fd"\nmass_kg = 18800.0\ndbc = "fd.dbc"\n{LEG_DEFAULTS_TOML}{LEG_TABLES}'


def test_the_encoder_marks_frames_of_fd_messages(tmp_path: Path) -> None:
    (tmp_path / "fd.dbc").write_text(DBC)
    (tmp_path / "machine.toml").write_text(CONFIG)
    config, database = load_machine_config(tmp_path / "machine.toml")
    message = database.get_message_by_name("ALL_LEGS")
    zeros = {signal.name: 0 for signal in message.signals}
    frame = FrameEncoder.from_config(config, database).encode("ALL_LEGS", zeros)
    assert frame.is_fd and len(frame.data) == 32


@pytest.mark.parametrize("suffix", [".log", ".asc", ".blf"])
def test_fd_frames_sent_and_logged_replay_into_eq4(tmp_path: Path, suffix: str) -> None:
    (tmp_path / "fd.dbc").write_text(DBC)
    (tmp_path / "machine.toml").write_text(CONFIG)
    config, database = load_machine_config(tmp_path / "machine.toml")
    result = make_result(duration_s=0.1)
    playout = make_playout(result, config=config, database=database)
    log_path = tmp_path / f"frames{suffix}"
    with can.Bus(interface="virtual", channel=str(tmp_path)) as bus, can.Logger(log_path) as log:
        Emitter(
            bus,
            playout,
            end_sim_ns=end_of_run_ns(playout.timeline.cycle_ns, 1),
            as_fast_as_possible=True,
            frames_log=log,
        ).run()
    frames = list(can_log_frames(log_path))
    assert len(frames) == 10 and all(frame.is_fd and frame.dlc == 32 for frame in frames)
    pipeline = Pipeline.from_config(config, database)
    estimates = [e for frame in frames for e in pipeline.process(frame).estimates]
    assert len(estimates) == 60 and not pipeline.bad
    row = 3
    for estimate in estimates[6 * row : 6 * row + 6]:
        column = LEGS.index(estimate.leg)
        p_piston_Pa = round(result.p_piston_Pa[row, column] / 1e3) * 1e3  # 1 kPa steps
        p_rod_Pa = round(result.p_rod_Pa[row, column] / 1e3) * 1e3
        expected_N = foot_force_N(p_piston_Pa, p_rod_Pa, config.legs[estimate.leg].geometry)
        assert estimate.valid and estimate.force_raw_N == pytest.approx(expected_N, rel=1e-12)


def test_an_fd_message_of_a_length_no_fd_frame_has_goes_out_padded_and_is_read(
    tmp_path: Path,
) -> None:
    """A hand-written DBC's 30-byte FD message (FD frames carry 24 or 32): a controller
    sends it as 32 bytes, and every such frame was ``wrong_dlc`` (the legs never had a
    sample); the bridge sent 30, which only a virtual bus carries."""
    (tmp_path / "fd.dbc").write_text(DBC.replace("ALL_LEGS: 32 Hub", "ALL_LEGS: 30 Hub"))
    (tmp_path / "machine.toml").write_text(CONFIG)
    config, database = load_machine_config(tmp_path / "machine.toml")
    message = database.get_message_by_name("ALL_LEGS")
    assert message.length == 30
    sent = {signal.name: 1e6 for signal in message.signals}
    frame = FrameEncoder.from_config(config, database).encode("ALL_LEGS", sent)
    assert frame.is_fd and len(frame.data) == 32 and frame.data[30:] == bytes(2)
    pipeline = Pipeline.from_config(config, database)
    for data in (frame.data, frame.data[:30]):
        estimates = pipeline.process(RawFrame(1.0, 768, False, data)).estimates
        assert len(estimates) == 6 and all(e.valid for e in estimates)
        assert {e.p_piston_Pa for e in estimates} == {1e6}
    assert pipeline.process(RawFrame(1.0, 768, False, frame.data + bytes(16))).decoded is None
    assert pipeline.bad == {"wrong_dlc": 1}
