"""Frozen records built fast: for the dataclasses made once or twice per CAN frame.

A frozen dataclass's generated ``__init__`` sets each field with
``object.__setattr__`` (its own ``__setattr__`` refuses), a generic attribute
look-up per field: about half a microsecond for a record of six fields, a sizeable
part of the per-frame path. With ``slots=True`` each field is a slot whose
descriptor sets it directly; :func:`fast_init` gives the class an ``__init__`` that
does so, with the same parameters and defaults. Nothing else changes: the instances
are as frozen, compared, hashed, printed and ``replace``-able as before.

>>> from dataclasses import dataclass
>>> @fast_init
... @dataclass(frozen=True, slots=True)
... class Point:
...     x: float
...     y: float = 0.0
>>> Point(1.0), Point(y=2.0, x=1.0) == Point(1.0, 2.0)
(Point(x=1.0, y=0.0), True)
"""

import types
from dataclasses import MISSING, fields
from typing import Any, TypeVar

Record = TypeVar("Record", bound=type)


def fast_init(cls: Record) -> Record:
    """Class decorator above ``@dataclass(frozen=True, slots=True)``: a faster ``__init__``.

    Refuses (TypeError) what the plain ``__init__`` would do more of: a
    ``__post_init__``, ``init=False`` or keyword-only fields, default factories, or no slots.
    """
    record_fields = fields(cls)
    if hasattr(cls, "__post_init__") or any(
        not field.init or field.kw_only or field.default_factory is not MISSING
        for field in record_fields
    ):
        raise TypeError(f"fast_init: {cls.__name__} needs the dataclass's own __init__")
    namespace: dict[str, Any] = {}
    params, body = [], []
    for field in record_fields:
        name = field.name
        slot = cls.__dict__.get(name)
        if not isinstance(slot, types.MemberDescriptorType):
            raise TypeError(f"fast_init: {cls.__name__}.{name} is not a slot")
        namespace[f"_set_{name}"] = slot.__set__
        if field.default is MISSING:
            params.append(name)
        else:
            namespace[f"_default_{name}"] = field.default
            params.append(f"{name}=_default_{name}")
        body.append(f"    _set_{name}(self, {name})\n")
    exec(f"def __init__(self, {', '.join(params)}):\n{''.join(body)}", namespace)
    init = namespace["__init__"]
    init.__qualname__ = f"{cls.__qualname__}.__init__"
    init.__module__ = cls.__module__
    setattr(cls, "__init__", init)  # noqa: B010 (mypy: no assigning to a method)
    return cls
