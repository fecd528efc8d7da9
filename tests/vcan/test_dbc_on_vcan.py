"""The project's DBC over real SocketCAN: frames encoded from it cross vcan0 and decode back,
and a frame typed into can-utils' ``cansend`` is decoded by the project's decoder."""

import subprocess

import can
import pytest

from dbc.decoding import FrameDecoder
from dbc.encoding import FrameEncoder
from dbc.protection import crc8_sae_j1850
from dbc.samples import LegSampler
from tests.helpers import LEGS, example_machine

pytestmark = pytest.mark.vcan

CONFIG, DATABASE = example_machine()
RECV_TIMEOUT_S = 5.0


def test_every_leg_frame_crosses_vcan0_and_decodes_to_its_pressures() -> None:
    encoder = FrameEncoder(DATABASE, CONFIG.protection)
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    sampler = LegSampler(CONFIG.legs)
    with (
        can.Bus(interface="socketcan", channel="vcan0") as tx,
        can.Bus(interface="socketcan", channel="vcan0") as rx,
    ):
        for i, leg in enumerate(LEGS):
            p_piston, p_rod = 15_000_000.0 + 1000 * i, 800_000.0 + 3000 * i
            frame = encoder.encode(
                f"LEG_{leg}",
                {f"{leg}_pPiston": p_piston, f"{leg}_pRod": p_rod, f"{leg}_Status": "ok"},
            )
            tx.send(
                can.Message(
                    arbitration_id=frame.arbitration_id, data=frame.data, is_extended_id=False
                )
            )
            received = rx.recv(RECV_TIMEOUT_S)
            assert received is not None
            decoded = decoder.decode(
                received.arbitration_id, bytes(received.data), received.timestamp
            )
            assert decoded.crc_ok and decoded.counter_ok
            ((name, sample),) = sampler.samples(decoded)
            assert (name, sample.p_piston_Pa, sample.p_rod_Pa) == (leg, p_piston, p_rod)
            assert sample.t_s == received.timestamp > 0


def test_cansend_frame_is_decoded_by_the_project_decoder() -> None:
    # LEG_SB1_F2 (0x101): piston raw 0x32C8 -> 12.0 MPa, rod raw 0x07D0 -> 1.0 MPa,
    # counter 5, status 0 (ok), reserved 0, CRC-8 SAE J1850 over bytes 0..6.
    payload = bytes([0xC8, 0x32, 0xD0, 0x07, 0x05, 0x00, 0x00])
    text = payload.hex().upper() + f"{crc8_sae_j1850(payload):02X}"
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    with can.Bus(interface="socketcan", channel="vcan0") as rx:
        subprocess.run(["cansend", "vcan0", f"101#{text}"], check=True, timeout=10)
        received = rx.recv(RECV_TIMEOUT_S)
    assert received is not None and received.arbitration_id == 0x101
    decoded = decoder.decode(received.arbitration_id, bytes(received.data), received.timestamp)
    assert decoded.message == "LEG_SB1_F2"
    assert decoded.signals["SB1_F2_pPiston"] == 12_000_000
    assert decoded.signals["SB1_F2_pRod"] == 1_000_000
    assert decoded.signals["SB1_F2_Counter"] == 5
    assert decoded.signals["SB1_F2_Status"] == "ok"
    assert decoded.crc_ok is True
