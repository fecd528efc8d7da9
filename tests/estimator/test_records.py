"""fast_init: the same records as the dataclass's own __init__ makes, or a clear refusal."""

import inspect
from dataclasses import FrozenInstanceError, dataclass, field, replace

import pytest

from daq.pipeline import FrameResult
from dbc.decoding import DecodedFrame
from estimator.leg import LegEstimate, LegSample
from estimator.records import fast_init


@dataclass(frozen=True, slots=True)
class Plain:
    name: str
    t_s: float
    faults: tuple[str, ...] = ()
    lost: int = 0


@fast_init
@dataclass(frozen=True, slots=True)
class Fast:
    name: str
    t_s: float
    faults: tuple[str, ...] = ()
    lost: int = 0


def test_same_fields_defaults_and_values_as_the_plain_init() -> None:
    for args, kwargs in [
        (("a", 1.5), {}),
        (("a", 1.5, ("crc",)), {}),
        (("a",), {"lost": 3, "t_s": -0.0}),
    ]:
        plain, fast = Plain(*args, **kwargs), Fast(*args, **kwargs)
        assert [getattr(fast, name) for name in Plain.__slots__] == [
            getattr(plain, name) for name in Plain.__slots__
        ]
    assert Fast("a", 1.5, lost=2) == Fast("a", 1.5, (), 2) != Fast("a", 1.5)
    assert hash(Fast("a", 1.5)) == hash(Fast("a", 1.5))
    assert repr(Fast("a", 1.5)) == "Fast(name='a', t_s=1.5, faults=(), lost=0)"
    assert str(inspect.signature(Fast)) == "(name, t_s, faults=(), lost=0)"


def test_missing_or_unknown_arguments_fail_as_with_the_plain_init() -> None:
    with pytest.raises(TypeError, match="t_s"):
        Fast("a")  # type: ignore[call-arg]
    with pytest.raises(TypeError, match="colour"):
        Fast("a", 1.0, colour=1)  # type: ignore[call-arg]


def test_still_frozen_and_replaceable() -> None:
    record = Fast("a", 1.5)
    with pytest.raises(FrozenInstanceError):
        record.t_s = 2.0  # type: ignore[misc]
    assert replace(record, lost=4) == Fast("a", 1.5, (), 4)


@pytest.mark.parametrize("record", [DecodedFrame, FrameResult, LegSample, LegEstimate])
def test_the_per_frame_records_use_it(record: type) -> None:
    assert record.__init__.__code__.co_filename == "<string>"  # type: ignore[misc]
    assert record.__init__.__qualname__ == f"{record.__qualname__}.__init__"  # type: ignore[misc]


def test_refuses_what_it_cannot_do() -> None:
    @dataclass(frozen=True)
    class NoSlots:
        x: float

    @dataclass(frozen=True, slots=True)
    class Factory:
        x: list[float] = field(default_factory=list)

    @dataclass(frozen=True, slots=True)
    class PostInit:
        x: float

        def __post_init__(self) -> None:
            pass

    @dataclass(frozen=True, slots=True)
    class Derived:
        x: float
        y: float = field(init=False, default=0.0)

    for cls in (NoSlots, Factory, PostInit, Derived):
        with pytest.raises(TypeError, match=cls.__name__):
            fast_init(cls)
