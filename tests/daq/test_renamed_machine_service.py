"""A held-out-style machine (tests/files/renamed: the default DBC with every message,
signal, frame ID and leg renamed) played by the simulator bridge into the service: the
bridge's :class:`Emitter` sends a synthetic cycle on python-can's ``virtual`` bus and
its truth on Zenoh, the service (in-process, a real Zenoh session on loopback) decodes,
estimates and records both into one MCAP file, and the report reads it: every config
leg's estimates meet the truth of its simulated leg under the config's leg name."""

import shutil
import uuid
from pathlib import Path

import numpy as np

from daq.report.content import analyse
from daq.report.loading import load_recording
from daq.service_config import load_service_config
from tests.daq.service_support import free_port
from tests.daq.test_report_end_to_end import play_cycle
from tests.daq.test_service_live import live_service
from tests.sim_bridge.synthetic import make_result
from tests.sim_bridge.test_leg_map import RENAMED, RENAMED_LEGS

#: Eq. (4) of two pressures each off by at most 500 Pa (the DBC's quantization), N.
QUANTIZATION_N = 4.2


def test_the_service_estimates_meet_the_truth_under_the_configs_leg_names(
    tmp_path: Path,
) -> None:
    shutil.copy(RENAMED.parent / "renamed_sensors.dbc", tmp_path)
    (tmp_path / "portal-daq.toml").write_text(
        f"""
[bus]
interface = "virtual"
channel = "renamed-{uuid.uuid4().hex}"

[zenoh]
mode = "peer"
listen = ["tcp/127.0.0.1:{free_port()}"]
multicast_scouting = false

[recording]
directory = "{tmp_path / "rec"}"
flush_period_s = 0.5
truth = true
"""
        + RENAMED.read_text()
    )
    config = load_service_config(tmp_path / "portal-daq.toml")
    result = make_result(duration_s=2.0)
    with live_service(config) as service:
        stats = play_cycle(config, service, result)
        recorder = service.recorder
        assert recorder is not None
    assert sum(stats.sent.values()) == service.pipeline.frames and stats.truth_samples == 200
    assert service.pipeline.bad == {} and recorder.dropped == 0
    (path,) = recorder.paths

    recording = load_recording(path)
    assert set(recording.legs) == set(RENAMED_LEGS)
    assert set(recording.truth.force_true_N) == set(RENAMED_LEGS)
    truth_at = {t_s: i for i, t_s in enumerate(recording.truth.t_s)}
    for leg, track in recording.legs.items():
        assert track.valid.all() and track.t_s.size == 200
        # each estimate at its frame time against the truth sample of that time
        rows = [truth_at[t_s] for t_s in track.t_s]
        true_N = recording.truth.force_true_N[leg][rows]
        assert np.max(np.abs(track.force_raw_N - true_N)) <= QUANTIZATION_N, leg
    content = analyse(recording)
    assert set(content.comparisons) == set(RENAMED_LEGS)
    for deviation in content.deviations.values():
        # the centred running median of a smooth wave: exact but near its turning points
        # (another leg's truth would be kN away: the synthetic legs are 1 MPa apart)
        assert deviation.samples >= 190 and deviation.abs50_N <= QUANTIZATION_N, deviation
        assert deviation.abs95_N < 200.0, deviation
