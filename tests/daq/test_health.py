"""`healthy` means it: drops anywhere, a failing recorder, an unreached endpoint, silence."""

from __future__ import annotations

import errno
import json
import logging
import os
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import can
import pytest
import zenoh

from daq.consumer import Consumer
from daq.frames import RawFrame
from daq.pipeline import Pipeline, decoded_frames
from daq.runner import bus_factory
from daq.service import Service, decoded_for_sure, losses, problems, status_line
from daq.service_config import load_service_config
from daq.zenoh_links import unreached
from daq.zenoh_session import zenoh_config
from tests.daq.service_support import (
    Collector,
    free_port,
    leg_messages,
    peer_config,
    subscriber_session,
    write_service_config,
)
from tests.daq.test_consumer_coalescing import (
    CONFIG,
    DATABASE,
    SETTINGS,
    START_S,
    Collect,
    FakeClock,
    ScriptedSource,
    leg_frames,
)
from tests.daq.test_service_live import encoder_for, live_service, sender, zenoh_port
from tests.daq.test_service_watchdog import wait_until
from tests.helpers import LEGS


def status(**changes: object) -> dict:  # type: ignore[type-arg]
    base = {
        "dropped": {"rx": 0, "publish": 0, "record": 0},
        "recording": {"failing": False, "failed_items": 0},
        "zenoh": {"unreached": []},
    }
    return base | changes


def test_healthy_when_nothing_is_wrong() -> None:
    assert (
        problems(status(), alive=True, lost_before={}, silent_s=0.0, heard_s=0.0, silence_s=1.0)
        == []
    )


def test_any_drop_in_the_period_is_a_problem_whatever_its_key() -> None:
    now = status(dropped={"rx": 3, "publish": 0, "record": 7, "kernel": 2})
    before = {"dropped.rx": 3, "dropped.publish": 0, "dropped.record": 5}
    found = problems(now, alive=True, lost_before=before, silent_s=0.0, heard_s=0.0, silence_s=1.0)
    assert found == ["dropped.record +2", "dropped.kernel +2"]


def test_failing_recorder_hung_thread_unreached_endpoint_and_silence() -> None:
    now = status(
        recording={"failing": True, "failed_items": 0}, zenoh={"unreached": ["tcp/10.0.0.9:7447"]}
    )
    found = problems(now, alive=False, lost_before={}, silent_s=2.5, heard_s=2.5, silence_s=1.0)
    assert found == [
        "a service thread hangs or died",
        "recording stopped (write error)",
        "zenoh connect tcp/10.0.0.9:7447 not reached",
        "no frame for 2.5 s",
    ]


def test_an_item_the_recorder_skipped_is_a_loss_as_a_drop_is() -> None:
    # recording.failed_items (an item whose writing raised) was shown but left the
    # status healthy: the item is missing from the file as surely as a dropped one.
    before = losses(status(recording={"failing": False, "failed_items": 2}))
    now = status(recording={"failing": False, "failed_items": 5})
    found = problems(now, alive=True, lost_before=before, silent_s=0.0, heard_s=0.0, silence_s=1.0)
    assert found == ["recording.failed_items +3"]
    assert (
        problems(now, alive=True, lost_before=losses(now), silent_s=0.0, heard_s=0.0, silence_s=1.0)
        == []
    )


def test_messages_zenoh_failed_to_put_are_counted_and_unhealthy(tmp_path: Path) -> None:
    # A put that raised (here: the session closed under the service) was counted only in
    # the publisher (ZenohPublisher.errors), never shown: /status said healthy while no
    # estimate reached Zenoh.
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), status_period_s=3600.0
    )
    config = load_service_config(path)
    with live_service(config) as service, sender(config) as bus:
        # The loop's first status must be behind us: taken after the session closed, it
        # took the first failures' period, and the test's own call below said "+19" of 21.
        wait_until(lambda: service._lost_mark)
        first = service.status()
        service.session.close()
        for message in leg_messages(encoder_for(config), 2, time.time()):
            bus.send(message)
        wait_until(lambda: service.publisher.errors >= 12)  # two estimates of six legs
        now = service.status()
    assert first["dropped"]["publish_failed"] == 0
    failed = now["dropped"]["publish_failed"]
    assert failed >= 12 and now["healthy"] is False
    assert f"dropped.publish_failed +{failed}" in now["problems"]


class FailingPipeline(Pipeline):
    """A pipeline with a bug: processing the fifth frame of a run raises."""

    def process(self, frame: RawFrame) -> Any:
        self.seen = getattr(self, "seen", 0) + 1
        if self.seen == 5:
            raise ZeroDivisionError("a bug")
        return super().process(frame)


def test_frames_a_bug_cost_are_counted_each_and_make_the_status_unhealthy() -> None:
    # A batch whose processing raised (a bug) was neither published nor recorded, counted
    # as one internal_error however many frames it held (up to 4,096), and /status stayed
    # healthy.
    clock = FakeClock()
    frames = leg_frames(12)
    source = ScriptedSource(clock, [(START_S, frame) for frame in frames])  # one batch
    collect = Collect(clock)
    pipeline = FailingPipeline.from_config(CONFIG, DATABASE)
    consumer = Consumer(
        pipeline, source, SETTINGS, publisher=collect, monotonic=clock.monotonic, wait=clock.wait
    )
    with consumer:
        assert source.done.wait(timeout=30.0)
    assert pipeline.bad["internal_error"] == 12 and collect.batches == []
    before = losses(status(bad={}))
    now = status(bad=dict(pipeline.bad))
    found = problems(now, alive=True, lost_before=before, silent_s=0.0, heard_s=0.0, silence_s=1.0)
    assert found == ["bad.internal_error +12"]


def test_the_time_the_service_takes_to_start_is_no_silence(tmp_path: Path) -> None:
    # The first status of every start said "not healthy: no frame for 1.0 s" 30 ms after
    # the bus opened: silence was counted from when the service was built, before the
    # recorder's process spawned (~0.5 s; seconds on a slow machine).
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), status_period_s=1.0
    )
    config = load_service_config(path)
    with zenoh.open(zenoh_config(config.zenoh)) as session:
        service = Service(config, open_bus=bus_factory(config.bus, []), session=session)
        built_s = time.monotonic()
        wait_until(lambda: time.monotonic() - built_s > service.silence_s)  # a slow start
        with service:
            first = service.status()
    assert not [problem for problem in first["problems"] if problem.startswith("no frame")]


def test_status_line_says_the_same() -> None:
    line = status_line(
        {
            "bus": {"state": "up"},
            "frames_per_s": 600.4,
            "frames": {"bad": 3},
            "dropped": {"rx": 1, "kernel": 4},
            "healthy": False,
            "problems": ["dropped.kernel +4"],
        }
    )
    assert line == "bus up, 600 frames/s, 3 bad, 5 dropped, NOT HEALTHY: dropped.kernel +4"


def test_endpoint_names_resolve_and_unresolvable_ones_are_unreached() -> None:
    links = {"tcp/127.0.0.1:7447"}
    assert unreached(["tcp/localhost:7447", "tcp/127.0.0.1:7447#iface=lo"], links) == []
    assert unreached(["tcp/no-such-host.invalid:7447"], links) == ["tcp/no-such-host.invalid:7447"]


def test_unreached_connect_endpoint_is_reported_until_it_comes_up(tmp_path: Path) -> None:
    peer_port = free_port()
    endpoint = f"tcp/127.0.0.1:{peer_port}"
    path = write_service_config(
        tmp_path,
        channel=f"test-{uuid.uuid4().hex}",
        port=free_port(),
        recording=tmp_path / "rec",
        status_period_s=0.2,
    )
    path.write_text(
        path.read_text().replace(
            "multicast_scouting = false", f'multicast_scouting = false\nconnect = ["{endpoint}"]', 1
        )
    )
    config = load_service_config(path)
    prefix = config.zenoh.key_prefix
    with live_service(config) as service, subscriber_session(zenoh_port(config)) as session:
        collector = Collector(session, f"{prefix}/status")
        down = collector.wait_for(f"{prefix}/status")
        assert down["zenoh"]["connect"] == [endpoint]
        assert down["zenoh"]["unreached"] == [endpoint] and down["healthy"] is False
        assert f"zenoh connect {endpoint} not reached" in down["problems"]
        assert len(down["zenoh"]["peers"]) == 1  # the subscriber, not the endpoint
        with zenoh.open(peer_config(listen=endpoint)), sender(config) as bus:
            up = None
            deadline = time.monotonic() + 30
            while up is None or up["zenoh"]["unreached"]:
                assert time.monotonic() < deadline
                for message in leg_messages(encoder_for(config), 1, time.time()):
                    bus.send(message)
                up = collector.wait_for(f"{prefix}/status")
            assert len(up["zenoh"]["peers"]) == 2
            assert not [p for p in up["problems"] if p.startswith("zenoh")]
        assert service.connect == [endpoint]


def test_a_flood_of_error_frames_and_unknown_ids_is_no_sensor_talking(tmp_path: Path) -> None:
    # A controller gone bus-off reports error frames, a foreign peer floods an ID of no
    # message: any frame counted as "frames came in", so /status stayed healthy while no
    # sensor was heard and every leg was stale.
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), status_period_s=0.2
    )
    config = load_service_config(path)
    prefix = config.zenoh.key_prefix
    t0 = time.time()
    flood = [
        can.Message(timestamp=t0, arbitration_id=0x7AB, data=bytes(8), is_extended_id=False)
        for _ in range(2000)
    ] + [
        can.Message(timestamp=t0, arbitration_id=0x80, is_error_frame=True, dlc=8, data=bytes(8))
        for _ in range(2000)
    ]
    with live_service(config), subscriber_session(zenoh_port(config)) as session:
        collector = Collector(session, f"{prefix}/status")
        collector.wait_for(f"{prefix}/status")
        with sender(config) as bus:
            for message in flood:
                bus.send(message)
        status = collector.wait_for(
            f"{prefix}/status",
            lambda s: (
                s["frames"]["processed"] == 4000
                and any(p.startswith("no frame") for p in s["problems"])
            ),
        )
    assert status["bad"] == {"unknown_id": 2000, "error_frame": 2000}
    assert status["healthy"] is False
    (silence,) = [p for p in status["problems"] if p.startswith("no frame")]
    assert silence.startswith("no frame of the DBC for ")
    assert silence.endswith(" s, only frames it does not use (see bad)")


def test_a_foreign_frame_being_refused_is_no_sensor_talking() -> None:
    """The pipeline counts a frame, then its kind once decoding refuses it; a status that
    read the counters in between took the 4001st frame of a flood of unknown IDs for a
    sensor's (the flood test above then saw "no frame for 0.3 s", now and then)."""
    pipeline = Pipeline.from_config(CONFIG, DATABASE)
    frame = RawFrame(START_S, 0x7AB, False, bytes(8))
    for _ in range(4000):
        pipeline.process(frame)
    pipeline.frames += 1  # the 4001st, as the consumer is in the middle of it
    assert decoded_frames(pipeline.frames, pipeline.bad) == 1  # read as it was
    assert decoded_for_sure(pipeline.frames, pipeline.bad) == 0
    pipeline.frames -= 1
    for leg_frame in leg_frames(3):  # three of the legs' frames, all decoded
        pipeline.process(leg_frame)
    assert decoded_frames(pipeline.frames, pipeline.bad) == 3
    assert decoded_for_sure(pipeline.frames, pipeline.bad) == 3 - 1  # one may be in flight


class DownOnce:
    """A bus whose interface is set down once (``ENETDOWN``, as a SocketCAN socket
    reports it once), then quiet."""

    kernel_dropped = 0
    rcvbuf_bytes = None

    def __init__(self) -> None:
        self._reported = False
        self._quiet = threading.Event()

    def recv(self, timeout_s: float) -> RawFrame | None:
        if not self._reported:
            self._reported = True
            raise OSError(errno.ENETDOWN, os.strerror(errno.ENETDOWN))
        self._quiet.wait(timeout_s)  # a quiet bus: no frame within the timeout
        return None

    def shutdown(self) -> None:
        pass


def never_opens() -> DownOnce:
    raise OSError(errno.ENODEV, os.strerror(errno.ENODEV))


@pytest.mark.parametrize(
    ("open_bus", "state", "reason"),
    [(DownOnce, "down", "Network is down"), (never_opens, "absent", "No such device")],
)
def test_a_bus_down_or_absent_is_unhealthy_at_once(
    tmp_path: Path, open_bus: Callable[[], DownOnce], state: str, reason: str
) -> None:
    # A bus set down or gone was healthy until the silence rule caught up (a period or
    # the stale time later), and even then the problem said only "no frame for 1.0 s".
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), status_period_s=3600.0
    )
    config = load_service_config(path)
    with zenoh.open(zenoh_config(config.zenoh)) as session:
        with Service(config, open_bus=open_bus, session=session) as service:
            wait_until(lambda: service.reader.state == state)
            now = service.status()
    assert now["bus"]["state"] == state and now["healthy"] is False
    (problem,) = [p for p in now["problems"] if p.startswith("bus ")]
    assert problem == f"bus {state}: {now['bus']['reason']}"
    assert problem.startswith(f"bus {state}: CAN bus {config.bus.channel!r}: {reason}")


def test_frames_held_for_the_poll_period_are_no_silence(tmp_path: Path) -> None:
    # With [service] poll_period_ms = 250 the frames are taken every 250 ms; statuses every
    # 50 ms between two wake-ups found no new frame and said "no frame for 0.1 s", the
    # status flapping between healthy and not on a bus that never paused.
    path = write_service_config(
        tmp_path,
        channel=f"test-{uuid.uuid4().hex}",
        port=free_port(),
        status_period_s=0.05,
        extra="[service]\npoll_period_ms = 250\n",
    )
    config = load_service_config(path)
    estimator = config.machine.estimator
    stale_s = max(estimator.stale_after_s(leg.cycle_time_s) for leg in config.machine.legs.values())
    with zenoh.open(zenoh_config(config.zenoh)) as session:
        service = Service(config, open_bus=bus_factory(config.bus, []), session=session)
    # A wake-up every 250 ms is seen by a status at most one period later.
    assert service.silence_s == max(0.05, stale_s) + 0.25


def test_an_outage_of_a_connect_endpoint_is_counted_after_it(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A site router that restarts: the statuses while it is away reach nobody through
    it, and the ones after said nothing of it (healthy, unreached []): a fleet could not
    tell a machine that was cut off for a while from one that never was."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), status_period_s=0.2
    )
    path.write_text(
        path.read_text().replace(
            "multicast_scouting = false", f'multicast_scouting = false\nconnect = ["{endpoint}"]', 1
        )
    )
    config = load_service_config(path)
    prefix = config.zenoh.key_prefix
    key = f"{prefix}/status"
    caplog.set_level(logging.INFO, logger="daq.zenoh_links")
    with live_service(config), subscriber_session(zenoh_port(config)) as session:
        collector = Collector(session, key)
        with zenoh.open(peer_config(listen=endpoint)):  # the router, up
            before = collector.wait_for(key, lambda s: not s["zenoh"]["unreached"])
            started = time.monotonic()  # before it goes (it may have been away at start)
        down = collector.wait_for(key, lambda s: s["zenoh"]["unreached"] == [endpoint])
        assert down["zenoh"]["outages"] == before["zenoh"]["outages"] + 1
        assert down["healthy"] is False
        with zenoh.open(peer_config(listen=endpoint)):  # back, on the same address
            up = collector.wait_for(key, lambda s: not s["zenoh"]["unreached"])
            span_s = time.monotonic() - started
    assert up["zenoh"]["outages"] == down["zenoh"]["outages"]  # shown after, too
    lasted_s = up["zenoh"]["unreached_s"] - before["zenoh"]["unreached_s"]
    assert 0.0 < lasted_s < span_s
    again = [r.getMessage() for r in caplog.records if "reached again" in r.getMessage()]
    assert again[-1].startswith(f"zenoh connect {endpoint} reached again after ")
    assert again[-1].endswith(" s: what was published meanwhile went nowhere through it")


def router_config(endpoint: str) -> zenoh.Config:
    config = peer_config(listen=endpoint)
    config.insert_json5("mode", '"router"')
    return config


def test_a_client_is_healthy_on_any_one_router_of_its_list(tmp_path: Path) -> None:
    """A client opens a link to one router of its ``connect`` list (the next one when that
    goes): with two routers listed for failover, the other was "not reached" on every
    status, the service unhealthy for ever while it was connected."""
    endpoints = [f"tcp/127.0.0.1:{free_port()}" for _ in range(2)]
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), status_period_s=0.2
    )
    text = path.read_text()
    zenoh_table = text[text.index("[zenoh]") : text.index("[publish]")]
    client = f'[zenoh]\nmode = "client"\nconnect = {json.dumps(endpoints)}\n\n'
    path.write_text(text.replace(zenoh_table, client, 1))
    config = load_service_config(path)
    key = f"{config.zenoh.key_prefix}/status"
    routers = {}
    for endpoint in endpoints:
        router = zenoh.open(router_config(endpoint))
        routers[str(router.info.zid())] = router
    viewer = peer_config()
    viewer.insert_json5("connect/endpoints", json.dumps(endpoints))
    try:
        with live_service(config), zenoh.open(viewer) as session:
            collector = Collector(session, key)
            before = collector.wait_for(key, lambda s: s["zenoh"]["routers"])
            (zid,) = before["zenoh"]["routers"]
            routers.pop(zid).close()  # the router the service is on goes
            (other,) = routers
            after = collector.wait_for(key, lambda s: s["zenoh"]["routers"] == [other])
    finally:
        for router in routers.values():
            router.close()
    for status in (before, after):
        assert status["zenoh"]["connect"] == endpoints and status["zenoh"]["unreached"] == []
        assert not [p for p in status["problems"] if p.startswith("zenoh")]


def test_two_services_under_one_key_prefix_are_told(tmp_path: Path) -> None:
    """Two machines given one id publish into the same keys: a fleet view showed one
    machine, live and healthy, its values taken in turn from both, and nothing said so."""
    configs = []
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        configs.append(
            write_service_config(
                tmp_path / name,
                channel=f"test-{uuid.uuid4().hex}",
                port=free_port(),
                status_period_s=0.2,
            )
        )
    first = load_service_config(configs[0])
    port = zenoh_port(first)
    text = configs[1].read_text()
    configs[1].write_text(
        text.replace(
            "multicast_scouting = false",
            f'multicast_scouting = false\nconnect = ["tcp/127.0.0.1:{port}"]',
            1,
        )
    )
    second = load_service_config(configs[1])
    assert first.zenoh.key_prefix == second.zenoh.key_prefix  # one machine id
    key = f"{first.zenoh.key_prefix}/status"
    lines = Lines()
    with lines.of("daq.service"), live_service(first) as a, subscriber_session(port) as session:
        collector = Collector(session, key)
        alone = collector.wait_for(key)
        assert alone["zenoh"]["same_prefix"] == []
        assert not [p for p in alone["problems"] if "another service" in p]
        a_zid = str(a.session.info.zid())
        with live_service(second) as b:
            b_zid = str(b.session.info.zid())
            status = collector.wait_for(key, lambda s: s["zenoh"]["same_prefix"] == [b_zid])
            assert status["healthy"] is False
            assert (
                f"another service publishes under this key prefix (zenoh session {b_zid})"
                in status["problems"]
            )
            assert b.owners.others() == [a_zid]  # and the other way round
        # Gone: a's statuses say nothing of it any more.
        after = collector.wait_for(key, lambda s: s["zenoh"]["same_prefix"] == [])
        assert not [p for p in after["problems"] if "another service" in p]
    told = [
        line
        for line in lines.messages
        if line.startswith(f"another service publishes under {first.zenoh.key_prefix}")
        and b_zid in line
    ]
    assert len(told) == 1, lines.messages  # a's line, once while it lasted
    assert f"(zenoh session {b_zid}): give each machine its own [machine] id" in told[0]


@pytest.mark.parametrize(("mode", "told"), [("peer", 1), ("client", 0)])
def test_a_peer_on_a_router_is_told_that_the_same_id_check_is_blind_there(
    tmp_path: Path, mode: str, told: int
) -> None:
    """Zenoh routes nothing between two peers through a router: two services of one id
    in peer mode on one site router (the README's ``mode = "peer"`` there) never saw each
    other's token, ``same_prefix`` stayed empty and nothing said why (seen with two
    ``portal-daq run`` on ``portal-daq router``). A peer with a router link says so once."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), status_period_s=0.2
    )
    text = path.read_text()
    zenoh_table = text[text.index("[zenoh]") : text.index("[publish]")]
    listen = f'listen = ["tcp/127.0.0.1:{free_port()}"]\n' if mode == "peer" else ""
    table = f'[zenoh]\nmode = "{mode}"\n{listen}connect = ["{endpoint}"]\n\n'
    path.write_text(text.replace(zenoh_table, table, 1))
    config = load_service_config(path)
    key = f"{config.zenoh.key_prefix}/status"
    lines = Lines()
    viewer = peer_config()
    viewer.insert_json5("mode", '"client"')
    viewer.insert_json5("listen/endpoints", "[]")
    viewer.insert_json5("connect/endpoints", json.dumps([endpoint]))
    with zenoh.open(router_config(endpoint)) as router, lines.of("daq.prefix_owners"):
        with live_service(config), zenoh.open(viewer) as session:
            collector = Collector(session, key)
            linked = collector.wait_for(key, lambda s: s["zenoh"]["routers"])
            router_zid = str(router.info.zid())
            assert linked["zenoh"]["routers"] == [router_zid]
            collector.wait_for(key, lambda s: s["uptime_s"] > linked["uptime_s"])  # one more
    said = [line for line in lines.messages if line.startswith("zenoh: this service is a peer")]
    assert len(said) == told, lines.messages
    if told:
        assert f"linked to a router ({router_zid})" in said[0]
        assert f"another service publishing under {config.zenoh.key_prefix} there" in said[0]
        assert said[0].endswith('set mode = "client" ([zenoh] mode, or mode in its JSON5 file)')


class Lines(logging.Handler):
    """The messages logged to a logger, from any thread (beside pytest's capture)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())

    @contextmanager
    def of(self, name: str) -> Iterator[None]:
        logger = logging.getLogger(name)
        logger.addHandler(self)
        try:
            yield
        finally:
            logger.removeHandler(self)


def test_error_frames_make_their_period_unhealthy_naming_what_they_report(
    tmp_path: Path,
) -> None:
    # The controller's error frames (a bus-off, an overflow of its receive buffer: frames
    # lost before the socket) were counted in bad.error_frame and nothing else: /status
    # stayed healthy, no line said what happened.
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), status_period_s=0.2
    )
    config = load_service_config(path)
    prefix = config.zenoh.key_prefix
    t0 = time.time()
    overflow_and_bus_off = can.Message(
        timestamp=t0, arbitration_id=0x044, is_error_frame=True, dlc=8, data=bytes([0, 1, 0, 0])
    )
    frames = [overflow_and_bus_off, *leg_messages(encoder_for(config), 2, t0)]
    with live_service(config), subscriber_session(zenoh_port(config)) as session:
        collector = Collector(session, f"{prefix}/status")
        collector.wait_for(f"{prefix}/status")
        with sender(config) as bus:
            for message in frames:
                bus.send(message)
        reported = collector.wait_for(
            f"{prefix}/status", lambda s: any(p.startswith("CAN controller") for p in s["problems"])
        )
        after = collector.wait_for(f"{prefix}/status", lambda s: s["frames"]["processed"] == 13)
    assert "CAN controller: rx overflow +1, bus off +1 (error frames)" in reported["problems"]
    assert reported["healthy"] is False
    # The next period has no error frame: the problem is gone.
    assert not [p for p in after["problems"] if p.startswith("CAN controller")]
    assert after["bad"] == {"error_frame": 1}


def test_a_sensor_silent_while_the_others_talk_is_a_problem_until_it_is_back(
    tmp_path: Path,
) -> None:
    # A leg's sensor that stopped while the bus went on (the others talking), or was
    # never heard, left no trace on /status nor in the log: healthy, only /ground's
    # "stale" said it.
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), status_period_s=0.2
    )
    config = load_service_config(path)
    prefix = config.zenoh.key_prefix
    encoder = encoder_for(config)
    others = [leg for leg in LEGS if leg not in ("SB1_F2", "SB1_F3")]
    t0 = time.time()
    # 3 s of frame time (bus time), SB1_F3 heard for its first 0.5 s only, SB1_F2 never;
    # then both are back.
    silent = sorted(
        leg_messages(encoder, 300, t0, others) + leg_messages(encoder, 50, t0, ["SB1_F3"]),
        key=lambda message: message.timestamp,
    )
    back = leg_messages(encoder, 10, t0 + 3.0)
    with live_service(config), subscriber_session(zenoh_port(config)) as session:
        collector = Collector(session, f"{prefix}/status")
        collector.wait_for(f"{prefix}/status")
        with sender(config) as bus:
            for message in silent:
                bus.send(message)
            reported = collector.wait_for(
                f"{prefix}/status",
                lambda s: (
                    s["frames"]["processed"] == len(silent)
                    and any(p.startswith("legs silent") and "SB1_F3" in p for p in s["problems"])
                ),
            )
            for message in back:
                bus.send(message)
            after = collector.wait_for(
                f"{prefix}/status", lambda s: s["frames"]["processed"] == len(silent) + len(back)
            )
    # 299 steps of 10 ms of frames without SB1_F2's, 250 without SB1_F3's; none of the
    # others silent.
    assert [p for p in reported["problems"] if p.startswith("legs")] == [
        "legs silent: SB1_F2 3.0 s, SB1_F3 2.5 s"
    ]
    assert reported["healthy"] is False
    assert not [p for p in after["problems"] if p.startswith("legs")]
