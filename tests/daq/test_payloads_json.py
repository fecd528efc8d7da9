"""json_bytes (orjson) writes the same JSON values as the reference (NaN/inf -> null
first, then the standard library), as strict JSON: the bytes may differ in how a float
or a non-ASCII character is spelled, never in what a reader gets."""

import json
import math
import tracemalloc
from collections import Counter
from types import MappingProxyType

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from daq.payloads import _finite, json_bytes


def reference(payload: object) -> bytes:
    """What json_bytes wrote before orjson: every value made finite, then dumped."""
    return json.dumps(_finite(payload), separators=(",", ":"), allow_nan=False).encode()


def strict_loads(data: bytes) -> object:
    """Parse as strict JSON: NaN, Infinity and -Infinity are refused."""

    def refuse(constant: str) -> object:
        raise AssertionError(f"not strict JSON: {constant}")

    return json.loads(data, parse_constant=refuse)


scalars = st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5)
values = st.recursive(
    scalars,
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.lists(inner, max_size=4).map(tuple)
        | st.dictionaries(st.text(max_size=5), inner, max_size=4)
    ),
    max_leaves=20,
)


@given(st.dictionaries(st.text(max_size=8), values, max_size=6))
def test_json_bytes_reads_back_as_the_reference(payload: dict) -> None:
    assert strict_loads(json_bytes(payload)) == strict_loads(reference(payload))


def test_floats_read_back_bit_for_bit() -> None:
    values = [1e-05, 1e16, 1764612345.123456, 0.1 + 0.2, 5e-324, 1.7976931348623157e308, -0.0]
    read = strict_loads(json_bytes({"v": values}))
    assert isinstance(read, dict)
    assert [repr(v) for v in read["v"]] == [repr(v) for v in values]


def test_numpy_scalars_and_big_integers() -> None:
    assert strict_loads(json_bytes({"f": np.float64(1.5), "i": np.int64(3)})) == {"f": 1.5, "i": 3}
    assert strict_loads(json_bytes({"big": 10**30, "nan": np.float64("nan")})) == {
        "big": 10**30,
        "nan": None,
    }


def test_non_finite_values_and_other_mappings_take_the_slow_path() -> None:
    payload = {"a": math.nan, "b": [math.inf, (1.5, -math.inf)], "c": Counter(x=2)}
    assert json_bytes(payload) == b'{"a":null,"b":[null,[1.5,null]],"c":{"x":2}}'
    proxy = MappingProxyType({"t": 1.0, "nested": MappingProxyType({"k": math.nan})})
    assert json_bytes(proxy) == reference(proxy) == b'{"t":1.0,"nested":{"k":null}}'


def test_a_payload_holds_no_more_memory_than_its_bytes() -> None:
    # orjson leaves its output in a 4 KiB buffer; kept in a queue, each payload held that.
    payload = {"leg": "F1", "t": 1764612345.123456, "force_N": 64477.25, "reasons": []}
    tracemalloc.start()
    try:
        kept = [json_bytes(payload) for _ in range(100)]
        held_bytes, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(kept[0]) < 100
    assert held_bytes < 100 * 300  # ~75 bytes of JSON each, with the object's header
