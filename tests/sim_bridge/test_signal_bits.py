"""The bridge on a DBC that declares no range (tests/files/stranger/j1939_slots: ``[0|0]``):
a simulated pressure beyond what a signal's bits hold (8 MPa in 16 bits at 0.05 kPa/bit,
3.28 MPa at most) stopped ``portal-sim`` with cantools' "OverflowError: Unsigned integer
value 160000 out of range" traceback. It is clipped into the bits, as into a DBC range."""

from pathlib import Path

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.machine import load_machine_config
from tests.dbc.test_held_out_machines import STRANGER
from tests.sim_bridge.synthetic import make_result, sent_by_the_command

#: The held-out legs, played as the simulator's legs of one base.
SIMULATED = {"two-bytes": "SB1_F1", "four-bytes": "SB1_F2", "one-byte": "SB1_F3", "rear": "SB2_F1"}


def test_a_pressure_beyond_a_signals_bits_is_clipped_into_them(tmp_path: Path) -> None:
    text = (STRANGER / "j1939_slots.toml").read_text().split("[stability]")[0]
    for leg, simulated in SIMULATED.items():
        text = text.replace(f"[legs.{leg}]\n", f'[legs.{leg}]\nsimulated_leg = "{simulated}"\n')
    (tmp_path / "j1939_slots.dbc").write_bytes((STRANGER / "j1939_slots.dbc").read_bytes())
    (tmp_path / "machine.toml").write_text(text)
    sent = sent_by_the_command(
        tmp_path / "machine.toml",
        tmp_path,
        make_result(duration_s=0.2),  # pistons 5..14 MPa
    )
    frames = [RawFrame(1.0, m.arbitration_id, True, bytes(m.data)) for m in sent]
    two_bytes = {f.data[:2] for f in frames if f.arbitration_id & 0xFF == 0x30}
    assert two_bytes == {b"\xff\xff"}  # every piston pressure above 3.28 MPa: the top code
    pipeline = Pipeline.from_config(*load_machine_config(tmp_path / "machine.toml"))
    estimates = [e for frame in frames for e in pipeline.process(frame).estimates]
    assert {e.leg: e.reasons for e in estimates}["two-bytes"] == ("range",)
    four = [e for e in estimates if e.leg == "four-bytes"]  # 32 bits hold the pressures
    assert four and all(e.valid for e in four)
