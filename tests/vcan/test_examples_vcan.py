"""Each shipped machine example end to end on a real vcan0: bridge -> service -> Zenoh.

For every shipped example (``daq/examples/*/portal-daq.toml``): the service runs
with the example's machine tables on vcan0, ``python -m sim_bridge`` plays the first
seconds of the model's cycle onto vcan0 while ``candump -L`` records what went out, and
every ``leg/<LEG>/ground`` estimate the service publishes must be eq. (4) of the
quantized pressures in those frames (decoded and converted to Pa by
:class:`tests.examples_support.SentFrames`, independently of the service), to 1 N, with
one estimate per trigger frame sent: no sample lost. Run through ``tests/vcan/with-vcan``.
"""

import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from daq.service_config import load_service_config
from tests.daq.service_support import free_port
from tests.examples_support import EXAMPLE_CONFIGS, SentFrames, example_id, machine_part
from tests.vcan.bridge_support import frames_sent, run_bridge_recorded
from tests.vcan.test_service_vcan import WAIT_S, watched_service

pytestmark = pytest.mark.vcan

CHANNEL = "vcan0"
SPEED = 1.0
DURATION_S = 3.0  # simulated: 300 samples per leg
#: In the guest the bridge and the service share one slow CPU: a rod frame and the piston
#: frame sent right after it may be far apart. The timing rule has its own unit tests.
MAX_SKEW_S = 10.0
CANDUMP_LINE = re.compile(r"^\((\d+\.\d+)\) vcan0 ([0-9A-F]{3}|[0-9A-F]{8})#([0-9A-F]*)$")


def service_config(example: Path, tmp_path: Path, port: int) -> Path:
    """``example``'s machine on vcan0, Zenoh on a loopback port, nothing recorded."""
    path = tmp_path / "portal-daq.toml"
    path.write_text(
        f"""
[bus]
interface = "socketcan"
channel = "{CHANNEL}"

[zenoh]
mode = "peer"
listen = ["tcp/127.0.0.1:{port}"]
multicast_scouting = false

[publish]
# The legs are what is checked; fewer messages for the slow guest to publish.
signals = false
status_period_s = 0.2

"""
        + "\n".join(
            f"max_skew_s = {MAX_SKEW_S}" if line.startswith("max_skew_s") else line
            for line in machine_part(example)
        )
        + "\n"
    )
    return path


def candump_frames(path: Path) -> Iterator[tuple[float, int, bool, bytes]]:
    """(kernel time, ID, extended, data) of each frame in a ``candump -L`` log."""
    for line in path.read_text().splitlines():
        match = CANDUMP_LINE.match(line.strip())
        assert match, f"not a candump -L frame: {line!r}"
        frame_id = match.group(2)
        yield (
            float(match.group(1)),
            int(frame_id, 16),
            len(frame_id) == 8,
            bytes.fromhex(match.group(3)),
        )


@pytest.mark.parametrize("example", EXAMPLE_CONFIGS, ids=example_id)
def test_the_example_end_to_end_publishes_eq_4_of_the_frames_sent(
    example: Path, tmp_path: Path
) -> None:
    port = free_port()
    config_path = service_config(example, tmp_path, port)
    config = load_service_config(config_path)
    prefix = config.zenoh.key_prefix
    log = tmp_path / "candump.log"
    with watched_service(config, tmp_path) as (_, collector):
        bridge = run_bridge_recorded(
            log,
            ["--config", str(config_path), "--channel", CHANNEL, "--speed", str(SPEED),
             "--duration", str(DURATION_S), "--rtol", "1e-3"],
            timeout_s=300,
        )  # fmt: skip
        assert bridge.returncode == 0, bridge.stderr
        sent = SentFrames(config.machine, config.database)
        for frame in candump_frames(log):
            sent.add(*frame)
        total = sum(sent.frames.values())
        # candump saw every frame the bridge says it sent
        assert frames_sent(bridge) == total, bridge.stderr
        # the service received and processed every one of them
        statuses = lambda: collector.of(f"{prefix}/status")  # noqa: E731
        try:
            collector.wait_until(lambda: statuses()[-1]["frames"]["processed"] >= total, WAIT_S)
        except AssertionError:
            raise AssertionError(f"sent {total}, last status {statuses()[-1]}") from None
        status = statuses()[-1]
        assert status["frames"]["received"] == total and status["bad"] == {}, status
        assert sum(status["dropped"].values()) == 0 and status["frames_lost"] == 0, status
        keys = {leg: f"{prefix}/leg/{leg}/ground" for leg in config.machine.legs}
        collector.wait_until(
            lambda: all(
                len(collector.of(key)) >= len(sent.samples[leg]) for leg, key in keys.items()
            ),
            WAIT_S,
        )
    for leg, key in keys.items():
        expected, published = sent.samples[leg], collector.of(key)
        # one estimate per trigger frame sent (100 Hz), none lost
        assert len(published) == len(expected) == round(DURATION_S / 0.01), leg
        for estimate, sample in zip(published, expected, strict=True):
            assert sample.complete
            assert estimate["valid"] is True, estimate
            assert estimate["p_piston_Pa"] == pytest.approx(sample.p_piston_Pa, rel=1e-12)
            assert estimate["p_rod_Pa"] == pytest.approx(sample.p_rod_Pa, rel=1e-12)
            assert abs(estimate["force_raw_N"] - sample.force_raw_N) <= 1.0
            # Pa, not bar or kPa: the model's loaded legs are at 3.6 .. 8.1 MPa here
            assert 1e6 < estimate["p_piston_Pa"] < 3e7 and 1e5 < estimate["p_rod_Pa"] < 3e7
