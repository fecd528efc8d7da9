"""The README's Zenoh contract is what a dashboard author receives, field by field.

A plain Zenoh subscriber on ``<prefix>/**`` (what someone who only reads Zenoh writes)
collects what the service publishes while the simulator's frames come in; every key
expression the README lists must be published, nothing else may be, and each payload
must have exactly the fields of the README's example, nested objects too.
"""

from __future__ import annotations

import json
import re
import time
import uuid
from pathlib import Path
from typing import Any

from daq.service import units
from daq.service_config import load_service_config
from sim_bridge.schedule import instants, schedule
from tests.daq.service_support import (
    can_message,
    free_port,
    subscriber_session,
    write_service_config,
)
from tests.daq.test_service_live import connected_collector, live_service, sender, zenoh_port
from tests.helpers import ROOT
from tests.sim_bridge.synthetic import make_playout, make_result

#: Objects keyed by names (legs, signals, fault kinds): their entries are not fields.
MAPS = {"legs", "signals", "bad", "leg_faults", "feet_m"}


def documented() -> dict[str, Any]:
    """Each key of the README's contract section (``ground``, ``leg/*/ground``, ...) with
    its example payload, ``…`` read as "some value"."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    section = readme.split("### Zenoh keys: the contract dashboards rely on", 1)[1]
    section = section.split("\n### ", 1)[0].split("**Late joiners", 1)[0]
    bullet = r"^- `<prefix>/([^`]+)`[^\n]*?:\s+`(\{[^\n]*\})`$"  # the example ends its line
    examples = dict(re.findall(bullet, section, re.M))
    leg = examples["leg/<LEG>/ground"]
    payloads = {}
    for key, text in examples.items():
        text = text.replace("{…as above…}", leg).replace("[x,y]", "[0,0]")
        text = re.sub(r",…(?=[\]}])", "", text)  # "more of the same"
        text = re.sub(r":…", ":null", text)  # "some value"
        payloads[key.replace("<LEG>", "*").replace("<MESSAGE>", "*")] = json.loads(text)
    assert {"ground", "leg/*/ground", "signals/*", "metrics", "status"} <= set(payloads)
    return payloads


def differences(doc: Any, real: Any, where: str) -> list[str]:
    """Fields ``real`` has that ``doc`` does not show, or lacks, recursively."""
    if not isinstance(doc, dict) or not isinstance(real, dict):
        return []  # a value; null where the README shows an object (stability) is fine
    found = [f"{where}.{k}: not in the README" for k in real.keys() - doc.keys()]
    found += [f"{where}.{k}: documented, not published" for k in doc.keys() - real.keys()]
    for key in doc.keys() & real.keys():
        if key in MAPS and isinstance(real[key], dict):
            model = next(iter(doc[key].values()), None)
            for name, item in real[key].items():
                found += differences(model, item, f"{where}.{key}.{name}")
        else:
            found += differences(doc[key], real[key], f"{where}.{key}")
    return found


def test_every_key_and_field_published_is_the_readmes(tmp_path: Path) -> None:
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), recording=tmp_path / "r"
    )
    config = load_service_config(path)
    prefix = config.zenoh.key_prefix
    playout = make_playout(make_result(duration_s=1.0))
    with (
        live_service(config),
        subscriber_session(zenoh_port(config)) as session,
        sender(config) as bus,
    ):
        collector = connected_collector(session, prefix)
        start_s = time.time()
        for instant in instants(schedule(playout.cycles, end_sim_ns=500_000_000)):
            for item in playout.frames(instant)[1]:
                bus.send(can_message(item.frame, start_s + instant.sim_t_ns / 1e9))
        collector.wait_for(f"{prefix}/ground", lambda p: p["stability"] is not None)
        collector.wait_for(f"{prefix}/metrics", lambda p: p["legs"]["SB1_F1"]["samples"] > 0)
        collector.wait_for(f"{prefix}/status", lambda p: p["frames"]["processed"] > 0)
        samples = list(collector.samples)
        # What the /signals values are in: a plain get, no DBC needed (there was no way).
        (reply,) = session.get(f"{prefix}/units")
        answer = json.loads(reply.ok.payload.to_bytes())
    assert str(reply.ok.key_expr) == f"{prefix}/units"
    assert answer["signals"]["BRIDGE_POSE"]["Bridge_FoldAngle"] == "deg"
    assert answer["signals"]["LEG_SB1_F1"]["SB1_F1_pPiston"] == "Pa"
    assert set(answer["signals"]) == {message.name for message in config.database.messages}
    contract = documented()
    assert answer.keys() == contract.pop("units").keys()  # answered, never put
    published: dict[str, list[Any]] = {}
    for key, payload, encoding in samples:
        assert encoding == "application/json"
        suffix = key.removeprefix(prefix + "/")
        pattern = re.sub(r"^(leg|signals)/[^/]+", r"\1/*", suffix)
        published.setdefault(pattern, []).append(payload)
    assert set(published) == set(contract), "keys published vs the README's"
    problems = [
        difference
        for pattern, payloads in published.items()
        for payload in payloads
        for difference in differences(contract[pattern], payload, pattern)
    ]
    assert not sorted(set(problems))


def test_units_name_what_the_decoder_converted_each_signal_to() -> None:
    # The e2e machine's DBC gives its leg pressures in kPa and the inclination cylinders'
    # in MPa: /signals carries them in Pa, which is what /units must say.
    config = load_service_config(ROOT / "deploy" / "examples" / "e2e" / "portal-daq.toml")
    signals = units(config)["signals"]
    assert signals["LEG_SB1_F1"]["SB1_F1_pPiston"] == "Pa"  # "kPa" in the DBC
    assert signals["INCL_SB1"]["INCL_SB1_pPiston"] == "Pa"  # "MPa" in the DBC
    assert signals["LEG_SB1_F1"]["SB1_F1_Status"] == ""
    assert signals["BRIDGE_POSE"]["Bridge_FoldAngle"] == "deg"
