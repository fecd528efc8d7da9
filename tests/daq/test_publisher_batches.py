"""The publisher's queue takes batches (one hand-off per consumer batch) but is bounded
and counted in messages: what does not fit is dropped and counted per message, what
fits is published in order, on a real Zenoh session."""

from queue import Empty

import pytest
import zenoh

from daq.publisher import MessageQueue, ZenohPublisher
from tests.daq.service_support import Collector, free_port, peer_config


def test_the_queue_is_sized_and_bounded_in_messages() -> None:
    queue = MessageQueue(maxsize=4)
    queue.put_nowait([("a", b"1"), ("b", b"2"), ("c", b"3")])
    assert queue.qsize() == 3
    queue.put_nowait([("d", b"4"), ("e", b"5")])  # taken: fewer than 4 were waiting
    assert queue.qsize() == 5 and queue.full()
    assert [suffix for suffix, _ in queue.get(0)] == ["a", "b", "c"]
    assert queue.qsize() == 2 and not queue.full()
    assert [suffix for suffix, _ in queue.get(0.1)] == ["d", "e"]
    with pytest.raises(Empty):
        queue.get(0.01)
    assert queue.qsize() == 0


def test_a_batch_that_does_not_fit_is_dropped_and_counted_per_message() -> None:
    port = free_port()
    with zenoh.open(peer_config(listen=f"tcp/127.0.0.1:{port}")) as session:
        publisher = ZenohPublisher(session, "test/batches", queue_size=3)
        publisher.submit_batch([(f"leg/{i}", b"{}") for i in range(3)])  # not started: waits
        publisher.submit_batch([("leg/x", b"{}"), ("leg/y", b"{}")])
        publisher.submit("ground", {"t": 1.0})
        publisher.submit_batch([])  # nothing to hand over
        assert (publisher.depth, publisher.dropped) == (3, 3)

        collector = Collector(session, "test/batches/**")  # same session: no routing race
        with publisher:
            publisher.submit_batch([("leg/3", b'{"n":3}'), ("ground", {"n": float("nan")})])
            collector.wait_until(lambda: len(collector.samples) == 5)
    assert [key for key, _, _ in collector.samples] == [
        "test/batches/leg/0",
        "test/batches/leg/1",
        "test/batches/leg/2",
        "test/batches/leg/3",
        "test/batches/ground",
    ]
    assert collector.samples[-1][1] == {"n": None}
    assert (publisher.published, publisher.dropped, publisher.errors) == (5, 3, 0)
