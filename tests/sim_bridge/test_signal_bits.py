"""The bridge on a DBC that declares no range (tests/files/stranger/j1939_slots: ``[0|0]``):
a simulated pressure beyond what a signal's bits hold (8 MPa in 16 bits at 0.05 kPa/bit,
3.28 MPa at most) stopped ``portal-sim`` with cantools' "OverflowError: Unsigned integer
value 160000 out of range" traceback. It is clipped into the bits, as into a DBC range."""

import uuid
from pathlib import Path

import can

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.machine import load_machine_config
from sim_bridge.__main__ import cli
from tests.dbc.test_held_out_machines import STRANGER
from tests.sim_bridge.synthetic import make_result, write_export

#: The held-out legs, played as the simulator's legs of one base.
SIMULATED = {"two-bytes": "SB1_F1", "four-bytes": "SB1_F2", "one-byte": "SB1_F3", "rear": "SB2_F1"}


def test_a_pressure_beyond_a_signals_bits_is_clipped_into_them(tmp_path: Path) -> None:
    text = (STRANGER / "j1939_slots.toml").read_text().split("[stability]")[0]
    for leg, simulated in SIMULATED.items():
        text = text.replace(f"[legs.{leg}]\n", f'[legs.{leg}]\nsimulated_leg = "{simulated}"\n')
    (tmp_path / "j1939_slots.dbc").write_bytes((STRANGER / "j1939_slots.dbc").read_bytes())
    (tmp_path / "machine.toml").write_text(text)
    data, mapping = write_export(tmp_path, make_result(duration_s=0.2))  # pistons 5..14 MPa
    channel = f"bits-{uuid.uuid4()}"
    args = ["--config", str(tmp_path / "machine.toml"), "--interface", "virtual"]
    args += ["--channel", channel, "--input", str(data), "--mapping", str(mapping)]
    with can.Bus(interface="virtual", channel=channel) as rx:
        assert cli([*args, "--as-fast-as-possible"]) == 0
        frames = []
        while (message := rx.recv(timeout=0)) is not None:
            frames.append(RawFrame(1.0, message.arbitration_id, True, bytes(message.data)))
    two_bytes = {f.data[:2] for f in frames if f.arbitration_id & 0xFF == 0x30}
    assert two_bytes == {b"\xff\xff"}  # every piston pressure above 3.28 MPa: the top code
    pipeline = Pipeline.from_config(*load_machine_config(tmp_path / "machine.toml"))
    estimates = [e for frame in frames for e in pipeline.process(frame).estimates]
    assert {e.leg: e.reasons for e in estimates}["two-bytes"] == ("range",)
    four = [e for e in estimates if e.leg == "four-bytes"]  # 32 bits hold the pressures
    assert four and all(e.valid for e in four)
