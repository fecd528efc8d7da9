"""The Zenoh surface: the shipped access control refuses foreign puts; safe defaults."""

from __future__ import annotations

import json
import logging
import time
import uuid
from pathlib import Path

import pytest
import zenoh
from mcap.reader import make_reader

from daq.live.feed import LiveFeed
from daq.live.session import open_viewer_session, viewer_zenoh_config
from daq.publisher import ZenohPublisher
from daq.service_config import ServiceConfig, ZenohSettings, load_service_config
from daq.zenoh_links import link_destinations, unreached
from daq.zenoh_session import config_value, open_session, zenoh_config
from dbc.errors import ConfigError
from tests.daq.service_support import (
    WAIT_S,
    Collector,
    KeysSeen,
    free_port,
    leg_messages,
    peer_config,
    write_service_config,
)
from tests.daq.test_service_live import encoder_for, live_service, sender
from tests.helpers import ROOT

FAKE = b'{"t_unix_s": 1750000000.0, "legs": {"SB1_F1": {"force_true_N": 666.0}}}'
REAL = b'{"t_unix_s": 1750000000.5, "legs": {"SB1_F1": {"force_true_N": 5.0}}}'


def connected(session: zenoh.Session) -> None:
    deadline = time.monotonic() + WAIT_S
    while not session.info.peers_zid():
        assert time.monotonic() < deadline, "not connected"
        time.sleep(0.05)


def locked_down_service(tmp_path: Path, *more_listen: str) -> tuple[ServiceConfig, str]:
    """A service config recording truth behind the shipped zenoh.json5's access control,
    listening on a free TCP port (and ``more_listen``); the config and that endpoint."""
    tcp = f"tcp/127.0.0.1:{free_port()}"
    path = write_service_config(
        tmp_path,
        channel=f"test-{uuid.uuid4().hex}",
        port=int(tcp.rsplit(":", 1)[1]),
        recording=tmp_path / "rec",
        truth=True,
    )
    listen = ", ".join(f'"{endpoint}"' for endpoint in (tcp, *more_listen))
    text = path.read_text().replace(
        f'listen = ["{tcp}"]',
        f'config_file = "{ROOT / "deploy" / "zenoh.json5"}"\nlisten = [{listen}]',
        1,
    )
    path.write_text(text)
    return load_service_config(path), tcp


def on_own_zenoh_file(config: ServiceConfig, zenoh_text: str) -> tuple[ServiceConfig, Path]:
    """``config`` (of :func:`locked_down_service`) on a zenoh.json5 of its own beside it,
    holding ``zenoh_text``: the config loaded again, and that file."""
    path = Path(config.source)
    zenoh_file = path.parent / "zenoh.json5"
    zenoh_file.write_text(zenoh_text)
    path.write_text(path.read_text().replace(str(ROOT / "deploy" / "zenoh.json5"), "zenoh.json5"))
    return load_service_config(path), zenoh_file


def test_foreign_puts_are_refused_and_the_local_socket_may_put_truth(tmp_path: Path) -> None:
    unix = f"unixsock-stream/{tmp_path / 'zenoh.sock'}"
    config, tcp = locked_down_service(tmp_path, unix)
    prefix = config.zenoh.key_prefix
    with (
        live_service(config) as service,
        zenoh.open(peer_config(connect=tcp)) as foreign,
        zenoh.open(peer_config(connect=unix)) as simulator,
    ):
        seen = Collector(service.session, f"{prefix}/**")  # what reaches the service
        connected(foreign)
        connected(simulator)
        seen.wait_until(lambda: bool(seen.of(f"{prefix}/status")))
        # Subscribing and querying (history) are allowed to anyone.
        status = Collector(foreign, f"{prefix}/status", advanced=True)
        status.wait_until(lambda: bool(status.of(f"{prefix}/status")))
        (units,) = foreign.get(f"{prefix}/units")  # the access control lets it answer
        assert json.loads(units.ok.payload.to_bytes())["signals"]["LEG_SB1_F1"]
        for _ in range(5):
            foreign.put(f"{prefix}/sim/truth", FAKE)
            foreign.put(f"{prefix}/status", b'{"healthy": true}')
            foreign.delete(f"{prefix}/ground")
        simulator.put(f"{prefix}/sim/truth", REAL, congestion_control=zenoh.CongestionControl.BLOCK)
        recorder = service.truth
        assert recorder is not None
        deadline = time.monotonic() + WAIT_S
        while recorder.received < 1:
            assert time.monotonic() < deadline
            time.sleep(0.05)
        # The simulator's put came after the foreign ones on another link: give those
        # as long again to arrive, if they were let through.
        seen.wait_until(lambda: bool(seen.of(f"{prefix}/sim/truth")))
        status.wait_until(lambda: len(status.of(f"{prefix}/status")) >= 3)
        assert recorder.received == 1
        assert [payload for key, payload, _ in seen.samples if key.endswith("sim/truth")] == [
            json.loads(REAL)
        ]
        statuses = [payload for key, payload, _ in seen.samples if key.endswith("status")]
        assert statuses and {"healthy": True} not in statuses
        assert service.recorder is not None
        recording = service.recorder.paths[0]
    with open(recording, "rb") as file:
        messages = list(make_reader(file).iter_messages(topics=["/sim/truth"]))
    assert [json.loads(m.data) for _, _, m in messages] == [json.loads(REAL)]


def test_without_a_config_file_the_service_listens_on_loopback_and_does_not_scout() -> None:
    config = zenoh_config(ZenohSettings())
    assert config_value(config, "listen/endpoints") == ["tcp/127.0.0.1:7447"]
    assert config_value(config, "scouting/multicast/enabled") is False
    assert config_value(config, "scouting/gossip/enabled") is False
    wait_us = "transport/link/tx/queue/congestion_control/block/wait_before_close"
    assert config_value(config, wait_us) == 1_000_000
    explicit = zenoh_config(ZenohSettings(listen=("tcp/10.0.0.2:7447",), multicast_scouting=True))
    assert config_value(explicit, "listen/endpoints") == ["tcp/10.0.0.2:7447"]
    assert config_value(explicit, "scouting/multicast/enabled") is True
    client = zenoh_config(ZenohSettings(mode="client", connect=("tcp/10.0.0.1:7447",)))
    assert config_value(client, "listen/endpoints") != ["tcp/127.0.0.1:7447"]


def test_production_example_is_locked_down() -> None:
    config = load_service_config(ROOT / "deploy" / "portal-daq.example.toml")
    assert config.recording.truth is False
    zenoh_cfg = zenoh_config(config.zenoh, config.source)
    assert config_value(zenoh_cfg, "listen/endpoints") == ["tcp/127.0.0.1:7447"]
    assert config_value(zenoh_cfg, "scouting/multicast/enabled") is False
    assert config_value(zenoh_cfg, "access_control/enabled") is True


def test_truth_that_never_comes_is_said_once(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # A bench's bridge connected over TCP (the natural way) had its truth dropped by the
    # access control, unseen: the recording had no truth and nobody said why.
    config, tcp = locked_down_service(tmp_path)
    prefix = config.zenoh.key_prefix
    caplog.set_level(logging.WARNING, logger="daq.service")
    with (
        live_service(config) as service,
        zenoh.open(peer_config(connect=tcp)) as bridge,
        sender(config) as bus,
    ):
        connected(bridge)
        for message in leg_messages(encoder_for(config), 3, time.time()):
            bus.send(message)
        deadline = time.monotonic() + WAIT_S
        while "no sample came on" not in caplog.text:
            assert time.monotonic() < deadline, "no warning"
            bridge.put(f"{prefix}/sim/truth", REAL)  # refused: TCP
            time.sleep(0.05)
        assert service.truth is not None and service.truth.received == 0
        service.status()
    warnings = [r.getMessage() for r in caplog.records if "no sample came on" in r.getMessage()]
    assert len(warnings) == 1 and f"{prefix}/sim/truth" in warnings[0]
    assert "a Unix socket, not TCP" in warnings[0]


def test_an_access_control_that_leaves_the_key_prefix_open_stops_the_service(
    tmp_path: Path,
) -> None:
    """The shipped zenoh.json5 denies puts under portal/**: with another key prefix, a
    foreign peer's fake truth was recorded (5 of 5). The service refuses to start with
    one line naming the file; with the rule's key moved as it says, the peer is refused."""
    config, tcp = locked_down_service(tmp_path)
    path = Path(config.source)
    path.write_text(path.read_text().replace("[zenoh]\n", '[zenoh]\nkey_prefix = "site7/pam"\n'))
    shipped = (ROOT / "deploy" / "zenoh.json5").read_text()
    config, zenoh_file = on_own_zenoh_file(load_service_config(path), shipped)
    assert config.zenoh.key_prefix == "site7/pam" and config.zenoh.config_file == zenoh_file
    with pytest.raises(ConfigError) as error:
        open_session(config.zenoh, config.source)
    assert str(error.value) == (
        f"{zenoh_file}: access_control: its deny rules name no key under site7/pam (their "
        "keys: portal/**), the service's key prefix: puts and deletes from other sessions "
        'under it (a fake /sim/truth, a fake /status) pass; add "site7/pam/**" to the '
        "key_exprs of the rule that denies them"
    )
    assert '"portal/**"' in shipped
    zenoh_file.write_text(shipped.replace('"portal/**"', '"site7/pam/**"'))
    with (
        live_service(config) as service,
        zenoh.open(peer_config(connect=tcp)) as foreign,
    ):
        # What reaches the service's session (its ingress is what the access control checks).
        received = KeysSeen(service.session)
        connected(foreign)
        received.routed(lambda: foreign.put("marker/0", b"{}"), "marker/0")
        for _ in range(5):
            foreign.put("site7/pam/sim/truth", FAKE)
        foreign.put("marker/1", b"{}")  # after them, on the same link
        received.wait_for("marker/1")
        assert service.truth is not None and service.truth.received == 0
        assert "site7/pam/sim/truth" not in received


def test_a_viewer_with_the_service_config_gets_every_sample_behind_the_access_control(
    tmp_path: Path,
) -> None:
    """A viewer (``portal-daq monitor --config``, the dashboard) takes the service's Zenoh
    file, access control and all. Applied to the viewer's own session, the rule that
    guards the service refused every sample the service published: the viewer got only
    what its advanced subscribers queried from the service's cache, about one /ground a
    second of ten, the rest counted as missed (the demo's monitor said 'STALE ground').
    The viewer leaves the access control out; it gets every sample, none missed."""
    config, tcp = locked_down_service(tmp_path)
    prefix = config.zenoh.key_prefix
    viewer_config = viewer_zenoh_config(config.zenoh, connect=[tcp], source=config.source)
    assert config_value(viewer_config, "access_control/enabled") is False
    with (
        open_session(config.zenoh, config.source) as service,
        ZenohPublisher(service, prefix) as publisher,
        open_viewer_session(viewer_config) as viewer,
        LiveFeed(viewer, prefix) as feed,
    ):
        connected(viewer)
        deadline = time.monotonic() + WAIT_S
        while (item := feed.wait(0.05)) is None:  # until the subscription is routed
            assert time.monotonic() < deadline, "the viewer got nothing"
            publisher.submit("ground", {"n": -1})
        for n in range(30):
            publisher.submit("ground", {"n": n})
        received: list[int] = []
        while len(received) < 30 and time.monotonic() < deadline:
            item = feed.wait(0.05)
            if item is not None and (n := json.loads(item.payload)["n"]) >= 0:
                received.append(n)
        assert received == list(range(30))
        assert (feed.missed, feed.dropped) == (0, 0)


def test_a_foreign_peer_cannot_answer_for_the_service_s_links(tmp_path: Path) -> None:
    """The links the status judges ``zenoh.unreached`` by are asked of the session's own
    admin space. The query went to every peer too: one that declared a queryable on
    ``@/<service zid>/session/**`` answered with a link to the unreached endpoint, and the
    status said it was reached (healthy) while no link went there."""
    dead = f"tcp/127.0.0.1:{free_port()}"
    listen = f"tcp/127.0.0.1:{free_port()}"
    config = peer_config(listen=listen)
    config.insert_json5("connect/endpoints", json.dumps([dead]))
    with zenoh.open(config) as service, zenoh.open(peer_config(connect=listen)) as foreign:
        connected(foreign)
        zid = service.info.zid()
        asked: list[str] = []

        def answer(query: zenoh.Query) -> None:
            asked.append(str(query.key_expr))
            link = f"@/{zid}/session/transport/unicast/{foreign.info.zid()}/link/0"
            query.reply(link, json.dumps({"src": "tcp/127.0.0.1:1", "dst": dead}))

        spoof = foreign.declare_queryable(f"@/{zid}/session/**", answer)
        # Declarations on one link arrive in order: once the service's get finds the
        # queryable declared after it, the service knows the spoofing one too.
        probe = foreign.declare_queryable("probe", lambda q: q.reply("probe", b"here"))
        deadline = time.monotonic() + WAIT_S
        while not [r for r in service.get("probe", timeout=1.0) if r.ok is not None]:
            assert time.monotonic() < deadline, "the foreign queryables never showed"
        destinations = link_destinations(service)
        assert unreached([dead], destinations) == [dead]
        assert asked == []
        spoof.undeclare()
        probe.undeclare()


def test_an_access_control_blind_to_the_zenoh_namespace_stops_the_service(tmp_path: Path) -> None:
    """Zenoh's ``namespace`` puts every key under it on the wire, and the access control
    sees the wire's keys: with ``namespace: "site7"`` in the shipped file, a foreign
    peer's put to ``site7/<prefix>/sim/truth`` passed ``portal/**`` and reached the
    service as ``<prefix>/sim/truth`` (the key prefix check said the rule covered it).
    Now the service refuses to start naming the key to deny; so denied, the put is refused."""
    config, tcp = locked_down_service(tmp_path)
    prefix = config.zenoh.key_prefix
    shipped = (ROOT / "deploy" / "zenoh.json5").read_text()
    namespaced = shipped.replace('mode: "peer",', 'mode: "peer",\n  namespace: "site7",')
    config, zenoh_file = on_own_zenoh_file(config, namespaced)
    with pytest.raises(ConfigError) as error:
        open_session(config.zenoh, config.source)
    assert str(error.value).startswith(
        f"{zenoh_file}: access_control: its deny rules name no key under site7/{prefix} "
        "(their keys: portal/**), the service's key prefix in the namespace site7: "
    )
    assert str(error.value).endswith(
        f'add "site7/{prefix}/**" to the key_exprs of the rule that denies them'
    )
    zenoh_file.write_text(zenoh_file.read_text().replace('"portal/**"', f'"site7/{prefix}/**"'))
    with (
        open_session(config.zenoh, config.source) as service,
        zenoh.open(peer_config(connect=tcp)) as foreign,
    ):
        received = KeysSeen(service)
        connected(foreign)
        # The service's namespace: what it gets under site7/ comes without it.
        received.routed(lambda: foreign.put("site7/marker/0", b"{}"), "marker/0")
        for _ in range(5):
            foreign.put(f"site7/{prefix}/sim/truth", FAKE)
        foreign.put("site7/marker/1", b"{}")  # after them, on the same link
        received.wait_for("marker/1")
        assert f"{prefix}/sim/truth" not in received
        received.undeclare()


@pytest.mark.parametrize(
    ("old", "new"),
    [
        (
            'flows: ["ingress"],\n        messages: ["put", "delete"],',
            'flows: ["egress"],\n        messages: ["put", "delete"],',
        ),
        ('messages: ["put", "delete"],', 'messages: ["query"],'),
        ('{ rules: ["no-put-under-portal"], subjects: ["anyone"] },', ""),
    ],
    ids=["egress-only", "no-put", "in-no-policy"],
)
def test_a_deny_rule_that_keeps_no_put_out_is_no_cover_for_the_key_prefix(
    tmp_path: Path, old: str, new: str
) -> None:
    """The check took any deny rule naming ``portal/**`` for cover: one on the egress
    flow only, one denying queries only, or one no policy names let a foreign peer's
    put to ``<prefix>/sim/truth`` reach the service (tried with real sessions on each),
    and the service started. Now it exits 2 saying which rule keeps nothing out."""
    config, _ = locked_down_service(tmp_path)
    shipped = (ROOT / "deploy" / "zenoh.json5").read_text()
    assert old in shipped
    config, zenoh_file = on_own_zenoh_file(config, shipped.replace(old, new, 1))
    with pytest.raises(ConfigError) as error:
        open_session(config.zenoh, config.source)
    assert str(error.value).startswith(
        f"{zenoh_file}: access_control: its deny rules name no key under "
        f"{config.zenoh.key_prefix} (their keys: none; a deny rule no policy names, or that "
        "denies no put arriving (flows: ingress, messages: put), keeps nothing out: portal/**)"
    )
