"""The controller's signals (machine state, carriage, inclination) of a held-out-style
machine whose DBC calls them otherwise (tests/files/renamed): the bridge sends them where
the config's ``[signals]`` places them, and says once which ones the DBC lacks."""

import logging
import shutil
import tomllib
import uuid
from pathlib import Path

import can
import numpy as np
import pytest

from daq.frames import RawFrame
from daq.mcap_file import CONFIG_ATTACHMENT, DBC_ATTACHMENT, McapFile
from daq.pipeline import Pipeline
from daq.report.content import analyse
from daq.report.loading import load_recording
from daq.report.page import render_page
from dbc.machine import load_machine_config
from sim_bridge.__main__ import cli
from sim_bridge.faults import FaultConfig
from sim_bridge.result import PHASES
from sim_bridge.schedule import instants, schedule
from tests.sim_bridge.synthetic import make_playout, make_result, write_export
from tests.sim_bridge.test_leg_map import RENAMED
from tests.sim_bridge.test_renamed_machine import quantized_Pa

CONFIG, DATABASE = load_machine_config(RENAMED)


def test_the_controllers_signals_reach_the_service_under_the_configs_names() -> None:
    """Bridge frames -> the service's pipeline (its decoder): each signal named in
    ``[signals]`` holds what the simulation put in, quantized by the DBC."""
    result = make_result(duration_s=1.0)
    playout = make_playout(result, FaultConfig(seed=1), CONFIG, DATABASE)
    pipeline = Pipeline.from_config(CONFIG, DATABASE)
    seen: dict[str, int] = {}
    for instant in instants(schedule(playout.cycles, end_sim_ns=round(1e9))):
        position, outgoing = playout.frames(instant)
        row = position.row
        for item in outgoing:
            frame = item.frame
            raw = RawFrame(instant.sim_t_ns / 1e9, frame.arbitration_id, False, frame.data)
            decoded = pipeline.process(raw).decoded
            assert decoded is not None and decoded.crc_ok and decoded.counter_ok
            signals = decoded.signals
            seen[decoded.message] = seen.get(decoded.message, 0) + 1
            for b, base in enumerate(("NEAR", "FAR")):
                if decoded.message == f"TILT_{base}":
                    assert signals[f"TILT_{base}_pPiston"] == quantized_Pa(
                        result.incl_p_piston_Pa[row, b]
                    )
                    assert signals[f"TILT_{base}_pRod"] == quantized_Pa(
                        result.incl_p_rod_Pa[row, b]
                    )
                    assert signals[f"TILT_{base}_Status"] == "ok"
                if decoded.message == "BRIDGE_GEOMETRY":
                    tilt = signals[f"Tilt{base.capitalize()}_deg"]
                    assert tilt == pytest.approx(result.inclination_deg[row, b], abs=0.005)
                    assert abs(tilt) > 0.01 or abs(result.inclination_deg[row, b]) < 0.01
            if decoded.message == "BRIDGE_DRIVE":
                assert signals["Trolley_m"] == pytest.approx(result.carriage_m[row], abs=0.0005)
            if decoded.message == "VEHICLE_STATE":
                assert signals["StepPhase"] == PHASES[result.phase[row]]
                assert signals["StepCount"] == 0
                assert signals["StepTime_s"] == pytest.approx(result.t_s[row], abs=0.005)
    assert seen["TILT_NEAR"] == seen["TILT_FAR"] == 100 and seen["VEHICLE_STATE"] == 10
    assert pipeline.bad == {} and pipeline.frames_lost == 0
    # the simulation's phases all went out, by their value-table names
    assert {PHASES[i] for i in result.phase[::10]} == set(PHASES)


def without_signals(tmp_path: Path) -> Path:
    """The renamed machine's config without its ``[signals]`` table, next to its DBC."""
    text = RENAMED.read_text()
    start = text.index("[signals]")
    text = text[:start] + text[text.index("[protection.", start) :]
    assert "signals" not in tomllib.loads(text)
    shutil.copy(RENAMED.parent / "renamed_sensors.dbc", tmp_path)
    path = tmp_path / "machine.toml"
    path.write_text(text)
    return path


def test_without_signals_the_bridge_says_once_what_it_does_not_send(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    config_path = without_signals(tmp_path)
    data, mapping = write_export(tmp_path, make_result(duration_s=0.3))
    channel = f"renamed-{uuid.uuid4()}"
    args = ["--config", str(config_path), "--interface", "virtual", "--channel", channel]
    args += ["--input", str(data), "--mapping", str(mapping), "--as-fast-as-possible"]
    with can.Bus(interface="virtual", channel=channel) as rx, caplog.at_level(logging.INFO):
        assert cli(args) == 0
        sent = set()
        while (message := rx.recv(timeout=0)) is not None:
            sent.add(DATABASE.get_message_by_frame_id(message.arbitration_id).name)
    (line,) = [r.getMessage() for r in caplog.records if "[signals]" in r.getMessage()]
    assert line.startswith(
        "no signal in the DBC for [signals] phase, cycle_count, cycle_time, carriage, "
        "bases.near.inclination, bases.near.piston, bases.near.rod, bases.near.status, "
        "bases.far.inclination, "
    )
    # nothing of theirs goes out: the messages only they are in are not sent at all
    assert not sent & {"VEHICLE_STATE", "TILT_NEAR", "TILT_FAR"}
    assert "HYD_NEAR_TIP" in sent


def test_the_report_finds_the_cycles_in_the_renamed_machine_state(tmp_path: Path) -> None:
    """``portal-sim --frames-log`` on the renamed machine, then the report's reading of
    that log with its config: the cycles and phases the simulation played."""
    result = make_result(duration_s=1.0)
    data, mapping = write_export(tmp_path, result)
    log = tmp_path / "cycle.log"
    args = ["--config", str(RENAMED), "--interface", "virtual", "--channel", str(uuid.uuid4())]
    args += ["--input", str(data), "--mapping", str(mapping), "--as-fast-as-possible"]
    assert cli([*args, "--cycles", "2", "--frames-log", str(log)]) == 0
    state = load_recording(log, RENAMED).state
    assert list(state.cycle_count) == [0] * 10 + [1] * 10
    assert list(state.phase) == [PHASES[i] for i in result.phase[::10]] * 2
    assert state.cycle_time_s == pytest.approx(np.tile(result.t_s[::10], 2), abs=0.005)


def test_a_recording_of_it_finds_them_by_its_embedded_config(tmp_path: Path) -> None:
    """The service's recording (the config and DBC embedded) reports its cycles without
    ``--config``: the embedded config says where the machine state is."""
    result = make_result(duration_s=1.0)
    playout = make_playout(result, FaultConfig(seed=1), CONFIG, DATABASE)
    pipeline = Pipeline.from_config(CONFIG, DATABASE)
    attachments = {
        CONFIG_ATTACHMENT: RENAMED.read_bytes(),
        DBC_ATTACHMENT: CONFIG.dbc_path.read_bytes(),
    }
    path = tmp_path / "renamed-1_run.mcap"
    with open(path, "wb") as stream, McapFile(stream, DATABASE) as mcap:
        mcap.start(attachments, 1000.0, None)
        for instant in instants(schedule(playout.cycles, end_sim_ns=round(1e9))):
            for item in playout.frames(instant)[1]:
                frame = item.frame
                raw = RawFrame(
                    1000.0 + instant.sim_t_ns / 1e9, frame.arbitration_id, False, frame.data
                )
                mcap.write_result(pipeline.process(raw))
    recording = load_recording(path)
    state = recording.state
    assert list(state.phase) == [PHASES[i] for i in result.phase[::10]]
    assert list(state.cycle_count) == [0] * 10
    # the page names where the cycles came from
    content = analyse(recording)
    assert content.time.in_cycle and content.time.label == "time in cycle / s (VEHICLE_STATE)"
    assert "Cycles from VEHICLE_STATE (StepCount)" in render_page(content, {})
