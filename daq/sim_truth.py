"""Simulation ground truth heard on Zenoh, handed to the recorder.

The simulator bridge (``python -m sim_bridge --zenoh``, :mod:`sim_bridge.truth`) puts
one JSON sample per simulation row on ``<prefix>/sim/truth``::

    {"t_unix_s": 1750000000.12, "t_cycle_s": 0.12, "cycle": 0,
     "legs": {"SB1_F1": {"force_true_N": 61234.5, "p_piston_Pa": ..., "p_rod_Pa": ...,
                         "pressure_true_Pa": ...}, ...}}

``t_unix_s`` is the frame time of that row: the Unix time its frames went onto the
bus, i.e. what the estimates of those frames carry as ``t``.

:class:`TruthSubscriber` only enqueues: its Zenoh callback wraps the payload bytes in
a :class:`TruthRecord` and hands it to ``submit`` (the recorder's non-blocking
:meth:`~daq.recorder.Recorder.submit`). Parsing and checking happen on the recorder's
thread (:func:`truth_payload`).
"""

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from daq.payloads import finite_number, parse_json, unix_time_s

logger = logging.getLogger(__name__)

#: Key suffix under the service's prefix (the bridge's ``ZenohTruthPublisher.key``).
TRUTH_KEY = "sim/truth"


@dataclass(frozen=True, slots=True)
class TruthRecord:
    """One truth sample as received: the JSON payload, not yet parsed."""

    payload: bytes


def truth_payload(record: TruthRecord) -> dict[str, Any] | None:
    """The sample as a dict, or None unless it is a JSON object with ``t_unix_s`` a
    plausible Unix time (:func:`daq.payloads.unix_time_s`: seconds, not milliseconds)
    and ``legs`` an object of objects whose values are finite numbers or null.

    The payload comes from outside: only the known fields are kept, every number
    checked, so that nothing in it can fail later (MCAP log time, JSON encoding).

    >>> truth_payload(TruthRecord(b'{"t_unix_s": 1750000000.5, "legs": {}}'))
    {'t_unix_s': 1750000000.5, 'legs': {}}
    >>> truth_payload(TruthRecord(b'{"t_unix_s": 1750000000500, "legs": {}}')) is None
    True
    """
    sample = parse_json(record.payload)
    if not isinstance(sample, dict) or not isinstance(sample.get("legs"), dict):
        return None
    t_s = unix_time_s(sample.get("t_unix_s"))
    if t_s is None:
        return None
    legs: dict[str, dict[str, float | None]] = {}
    for name, leg in sample["legs"].items():
        if not isinstance(leg, dict):
            return None
        values = {str(field): finite_number(value) for field, value in leg.items()}
        if any(value is None and leg[field] is not None for field, value in values.items()):
            return None  # a number that is not finite, or not a number at all
        legs[str(name)] = values
    checked: dict[str, Any] = {"t_unix_s": t_s}
    for field in ("t_cycle_s", "cycle"):
        if field in sample:
            checked[field] = finite_number(sample[field])
    checked["legs"] = legs
    return checked


class TruthSubscriber:
    """Subscribes to ``key`` and hands every sample to ``submit``; nothing else.

    The constructor declares nothing; :meth:`start` declares the subscriber,
    :meth:`close` undeclares it (idempotent; the session belongs to the caller).
    """

    def __init__(
        self, session: zenoh.Session, key: str, submit: Callable[[TruthRecord], None]
    ) -> None:
        self.session = session
        self.key = key
        self._submit = submit
        self._subscriber: zenoh.Subscriber[None] | None = None
        self._closed = False
        #: Samples received (each handed to ``submit``).
        self.received = 0

    def __enter__(self) -> "TruthSubscriber":
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def start(self) -> None:
        if self._subscriber is not None or self._closed:
            return
        self._subscriber = self.session.declare_subscriber(self.key, self._on_sample)
        logger.info("recording simulation truth published on %s", self.key)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        """Zenoh's thread: enqueue, nothing else (``submit`` never blocks)."""
        self.received += 1
        self._submit(TruthRecord(sample.payload.to_bytes()))

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        subscriber, self._subscriber = self._subscriber, None
        if subscriber is not None:
            try:
                subscriber.undeclare()  # type: ignore[no-untyped-call]
            except zenoh.ZError as exc:  # e.g. the session was closed first
                logger.debug("undeclaring the truth subscriber: %s", exc)
