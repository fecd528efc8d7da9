"""json_bytes' fast path writes the same bytes as the reference (NaN/inf -> null first)."""

import json
import math
from collections import Counter
from types import MappingProxyType

from hypothesis import given
from hypothesis import strategies as st

from daq.payloads import _finite, json_bytes


def reference(payload: object) -> bytes:
    """What json_bytes wrote before its fast path: every value made finite, then dumped."""
    return json.dumps(_finite(payload), separators=(",", ":"), allow_nan=False).encode()


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
def test_json_bytes_equals_the_reference(payload: dict) -> None:
    assert json_bytes(payload) == reference(payload)


def test_non_finite_values_and_other_mappings_take_the_slow_path() -> None:
    payload = {"a": math.nan, "b": [math.inf, (1.5, -math.inf)], "c": Counter(x=2)}
    assert json_bytes(payload) == b'{"a":null,"b":[null,[1.5,null]],"c":{"x":2}}'
    proxy = MappingProxyType({"t": 1.0, "nested": MappingProxyType({"k": math.nan})})
    assert json_bytes(proxy) == reference(proxy) == b'{"t":1.0,"nested":{"k":null}}'
