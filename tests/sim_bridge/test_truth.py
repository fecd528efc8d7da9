"""Ground-truth writers: CSV and MCAP read back with the right values; Zenoh keys and JSON."""

import csv
import io
import json
import math
import threading
from pathlib import Path
from types import SimpleNamespace

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType

from sim_bridge.frames import Position
from sim_bridge.result import LEGS, SimulationResult
from sim_bridge.truth import (
    TOPIC,
    CsvTruthWriter,
    McapTruthWriter,
    TruthSample,
    ZenohTruthPublisher,
    best_compression,
    csv_header,
    truth_sample,
)

FEET_M2 = {leg: 0.33 for leg in LEGS}
T0_S = 1_750_000_000.0


def samples(result: SimulationResult, rows: range) -> list[TruthSample]:
    return [
        truth_sample(result, Position(cycle=row // 100, row=row % 100, t_cycle_s=0.0),
                     T0_S + 0.01 * row, FEET_M2)
        for row in rows
    ]  # fmt: skip


def test_truth_sample_holds_the_row_and_the_contact_pressure(result: SimulationResult) -> None:
    (sample,) = samples(result, range(42, 43))
    assert (sample.t_unix_s, sample.t_cycle_s, sample.cycle) == (T0_S + 0.42, result.t_s[42], 0)
    for i, leg in enumerate(LEGS):
        truth = sample.legs[leg]
        assert truth.force_true_N == result.force_true_N[42, i]
        assert truth.pressure_true_Pa == result.force_true_N[42, i] / 0.33
        assert (truth.p_piston_Pa, truth.p_rod_Pa) == (
            result.p_piston_Pa[42, i],
            result.p_rod_Pa[42, i],
        )


def test_csv_reads_back(tmp_path: Path, result: SimulationResult) -> None:
    path = tmp_path / "truth.csv"
    with open(path, "w", newline="") as stream, CsvTruthWriter(stream, LEGS) as writer:
        for sample in samples(result, range(150)):
            writer.write(sample)
    with open(path, newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert list(rows[0]) == csv_header(LEGS)
    assert list(rows[0])[:7] == [
        "t_unix_s", "t_cycle_s", "cycle",
        "force_true_N_SB1_F1", "p_piston_Pa_SB1_F1", "p_rod_Pa_SB1_F1", "pressure_true_Pa_SB1_F1",
    ]  # fmt: skip
    assert len(rows) == 150
    row = rows[123]
    assert float(row["t_unix_s"]) == T0_S + 1.23
    assert (float(row["t_cycle_s"]), int(row["cycle"])) == (result.t_s[23], 1)
    assert float(row["force_true_N_SB2_F3"]) == result.force_true_N[23, 5]  # repr round-trips
    assert float(row["pressure_true_Pa_SB2_F3"]) == result.force_true_N[23, 5] / 0.33
    assert float(row["p_rod_Pa_SB1_F2"]) == result.p_rod_Pa[23, 1]


def test_csv_writes_unknown_truth_as_empty_cells(result: SimulationResult) -> None:
    result.force_true_N[:] = math.nan
    stream = io.StringIO()
    with CsvTruthWriter(stream, ["SB1_F1"]) as writer:
        writer.write(samples(result, range(1))[0])
    header, row = stream.getvalue().splitlines()
    assert row.split(",")[3] == "" and row.split(",")[6] == ""
    assert float(row.split(",")[4]) == result.p_piston_Pa[0, 0]


def test_an_empty_csv_still_has_its_header_and_close_is_idempotent() -> None:
    stream = io.StringIO()
    writer = CsvTruthWriter(stream, ["SB1_F1"])
    with writer:
        pass
    writer.close()
    assert stream.getvalue().splitlines() == [",".join(csv_header(["SB1_F1"]))]


@pytest.mark.parametrize("compression", [None, CompressionType.NONE, CompressionType.LZ4])
def test_mcap_reads_back(tmp_path: Path, result: SimulationResult, compression) -> None:
    path = tmp_path / "truth.mcap"
    with open(path, "wb") as stream, McapTruthWriter(stream, LEGS, compression) as writer:
        for sample in samples(result, range(200)):
            writer.write(sample)
        writer.close()  # idempotent: __exit__ closes again
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics.message_count == 200
        messages = list(reader.iter_messages(topics=[TOPIC]))
    schema, channel, message = messages[77]
    assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
    assert channel.topic == "/sim/truth"
    assert json.loads(schema.data)["properties"]["legs"]["properties"].keys() == set(LEGS)
    payload = json.loads(message.data)
    assert message.log_time == round((T0_S + 0.77) * 1e9)
    assert payload["t_unix_s"] == T0_S + 0.77 and payload["cycle"] == 0
    assert payload["legs"]["SB1_F2"]["force_true_N"] == result.force_true_N[77, 1]
    assert payload["legs"]["SB1_F2"]["pressure_true_Pa"] == result.force_true_N[77, 1] / 0.33
    assert [m.sequence for _, _, m in messages] == list(range(200))


def test_mcap_without_samples_is_still_a_valid_file(tmp_path: Path) -> None:
    path = tmp_path / "empty.mcap"
    with open(path, "wb") as stream, McapTruthWriter(stream, LEGS):
        pass
    with open(path, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and summary.statistics.message_count == 0
    assert [c.topic for c in summary.channels.values()] == [TOPIC]


def test_the_best_available_compression_is_used() -> None:
    assert best_compression() in (CompressionType.ZSTD, CompressionType.LZ4)


class FakePublisher:
    def __init__(self, key: str, log: list[tuple[str, bytes]], matching: bool = True) -> None:
        self.key, self.log, self.undeclared = key, log, False
        self.matching_status = SimpleNamespace(matching=matching)

    def put(self, payload: bytes) -> None:
        self.log.append((self.key, payload))

    def undeclare(self) -> None:
        self.undeclared = True


class FakeSession:
    def __init__(self, matching: bool = True) -> None:
        self.log: list[tuple[str, bytes]] = []
        self.publishers: list[FakePublisher] = []
        self.matching = matching

    def declare_publisher(self, key_expr: str, *, encoding: str) -> FakePublisher:
        assert encoding == "application/json"
        publisher = FakePublisher(key_expr, self.log, self.matching)
        self.publishers.append(publisher)
        return publisher


def test_zenoh_puts_the_sample_and_each_leg(result: SimulationResult) -> None:
    session = FakeSession()
    result.force_true_N[3, 4] = math.nan
    with ZenohTruthPublisher(session, "portal/pam-proto-1", LEGS) as publisher:
        publisher.write(samples(result, range(3, 4))[0])
    keys = [key for key, _ in session.log]
    assert keys == [f"portal/pam-proto-1/sim/truth/{leg}" for leg in LEGS] + [
        "portal/pam-proto-1/sim/truth"
    ]
    leg = json.loads(session.log[0][1])
    assert leg["leg"] == "SB1_F1" and leg["force_true_N"] == result.force_true_N[3, 0]
    assert leg["t_unix_s"] == T0_S + 0.03 and leg["cycle"] == 0
    whole = json.loads(session.log[-1][1])
    assert whole["legs"]["SB2_F2"]["force_true_N"] is None  # NaN is JSON null
    assert all(p.undeclared for p in session.publishers)


@pytest.mark.parametrize("matching", [False, True])
def test_truth_nobody_subscribed_to_is_said_at_the_end(
    result: SimulationResult, matching: bool, caplog: pytest.LogCaptureFixture
) -> None:
    # Truth published under another machine id than the service's, or to a service not
    # recording truth, or not connected to it, went nowhere with nothing said.
    with ZenohTruthPublisher(FakeSession(matching), "portal/other", LEGS) as publisher:
        for sample in samples(result, range(3)):
            publisher.write(sample)
    said = [r.getMessage() for r in caplog.records if "nobody subscribed" in r.getMessage()]
    if matching:
        assert said == []
    else:
        assert said == [
            "nobody subscribed to portal/other/sim/truth while 3 truth samples were put: they "
            "went nowhere (to record them, the service needs [recording] truth = true, the "
            "machine id in this key, and the bridge connected to it: --connect)"
        ]


def test_zenoh_for_real_in_one_session(result: SimulationResult) -> None:
    zenoh = pytest.importorskip("zenoh")
    config = zenoh.Config()
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("listen/endpoints", "[]")
    got: list[tuple[str, dict]] = []
    done = threading.Event()

    def on_sample(sample) -> None:  # type: ignore[no-untyped-def]
        got.append((str(sample.key_expr), json.loads(sample.payload.to_bytes())))
        if len(got) == 7:
            done.set()

    with zenoh.open(config) as session:
        subscriber = session.declare_subscriber("test/**", on_sample)
        with ZenohTruthPublisher(session, "test", LEGS) as publisher:
            publisher.write(samples(result, range(1))[0])
            assert done.wait(10.0)
        subscriber.undeclare()
    assert dict(got)["test/sim/truth"]["legs"]["SB1_F1"]["p_rod_Pa"] == result.p_rod_Pa[0, 0]
    assert dict(got)["test/sim/truth/SB2_F1"]["leg"] == "SB2_F1"


def test_a_closed_writer_refuses_samples(tmp_path: Path, result: SimulationResult) -> None:
    with open(tmp_path / "x.mcap", "wb") as stream:
        writer = McapTruthWriter(stream, LEGS)
        writer.close()
        with pytest.raises(ValueError, match="closed"):
            writer.write(samples(result, range(1))[0])
