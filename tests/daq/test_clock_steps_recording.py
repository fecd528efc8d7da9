"""The service recording through a clock step: the kernel stamps of its frames jump back
by hours across a rotation; the recording keeps them in order, replay equals live."""

from __future__ import annotations

import time
import uuid
from pathlib import Path

from daq.service_config import load_service_config
from tests.daq.service_support import free_port, leg_messages, write_service_config
from tests.daq.test_service_live import (
    assert_replay_is_live,
    encoder_for,
    live_estimates,
    send_and_wait,
)
from tests.helpers import recorded_raw_frames

STEP_S = 2 * 3600.0


def test_a_clock_stepped_back_at_a_rotation_keeps_the_frames_in_order(tmp_path: Path) -> None:
    path = write_service_config(
        tmp_path,
        channel=f"test-{uuid.uuid4().hex}",
        port=free_port(),
        recording=tmp_path / "rec",
        max_duration_s=1.0,
    )
    config = load_service_config(path)
    encoder = encoder_for(config)
    t0 = time.time() + 30.0
    messages = leg_messages(encoder, 300, t0)
    for i, message in enumerate(messages):
        if i >= len(messages) // 2:  # the clock stepped back by two hours half-way
            message.timestamp -= STEP_S
    paths = send_and_wait(config, messages)
    recorded = [frame for path in paths for frame in recorded_raw_frames(path)]
    assert [(f.t_s, f.arbitration_id) for f in recorded] == [
        (m.timestamp, m.arbitration_id) for m in messages
    ]
    assert_replay_is_live(paths, live_estimates(paths))
