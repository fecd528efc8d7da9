"""Typed reading of one TOML table, with errors that name the file and dotted key."""

import math
import re
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

from dbc.errors import ConfigError

T = TypeVar("T")

_MISSING: Any = object()
#: TOML's integers are 64-bit signed (the spec: an integer that cannot be held losslessly
#: is an error); Python's reader takes any, so ``1e400`` written as digits came through.
INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1
# The first word of an estimator ValueError names the offending field.
_FIELD_NAME = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\b")


class TomlTable:
    """A TOML table and where it sits (``source`` file, dotted ``path``)."""

    def __init__(self, data: dict[str, Any], source: str, path: str = "") -> None:
        self.data = data
        self.source = source
        self.path = path

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def error(self, name: str, reason: str) -> ConfigError:
        return ConfigError(self.source, self.key(name) if name else self.path, reason)

    def __contains__(self, name: str) -> bool:
        return name in self.data

    def _get(self, name: str, default: Any) -> Any:
        if name in self.data:
            return self.data[name]
        if default is _MISSING:
            raise self.error(name, "missing")
        return default

    def number(self, name: str, default: Any = _MISSING) -> float:
        return self.finite(name, self._get(name, default))

    def finite(self, name: str, value: Any) -> float:
        """``value``, given under ``name`` (a key, or one of its items), as a finite float."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(name, f"must be a number, got {value!r}")
        if isinstance(value, int):
            value = self._int64(name, value)  # float() of a longer one raised OverflowError
        if not math.isfinite(value):
            raise self.error(name, f"must be finite, got {value!r}")
        return float(value)

    def integer(self, name: str, default: Any = _MISSING) -> int:
        value = self._get(name, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(name, f"must be an integer, got {value!r}")
        return self._int64(name, value)

    def _int64(self, name: str, value: int) -> int:
        if not INT64_MIN <= value <= INT64_MAX:
            bits = value.bit_length()
            raise self.error(name, f"must fit in 64 bits (TOML's integers), got a {bits}-bit one")
        return value

    def string(self, name: str, default: Any = _MISSING, pattern: str | None = None) -> str:
        value = self._get(name, default)
        if not isinstance(value, str) or not value:
            raise self.error(name, f"must be a non-empty string, got {value!r}")
        if pattern is not None and not re.fullmatch(pattern, value):
            raise self.error(name, f"{value!r} does not match {pattern}")
        return value

    def file(self, name: str, base_dir: Path) -> Path:
        """A file or directory path, relative to ``base_dir`` (the config file's) unless absolute;
        a leading ``~`` is the home directory, as in a shell (``~/recordings``)."""
        return base_dir / Path(self.string(name)).expanduser()

    def boolean(self, name: str, default: Any = _MISSING) -> bool:
        value = self._get(name, default)
        if not isinstance(value, bool):
            raise self.error(name, f"must be true or false, got {value!r}")
        return value

    def strings(self, name: str, default: Any = _MISSING) -> tuple[str, ...]:
        """A list of non-empty strings, e.g. Zenoh endpoints."""
        value = self._get(name, default)
        if not isinstance(value, (list, tuple)) or not all(
            isinstance(item, str) and item for item in value
        ):
            raise self.error(name, f"must be a list of non-empty strings, got {value!r}")
        return tuple(value)

    def table(self, name: str, required: bool = True) -> "TomlTable":
        value = self._get(name, _MISSING if required else {})
        if not isinstance(value, dict):
            raise self.error(name, f"must be a table, got {value!r}")
        return TomlTable(value, self.source, self.key(name))

    def signal_table(self, name: str, allowed: Iterable[str]) -> tuple["TomlTable", str]:
        """A signal written ``"MESSAGE.SIGNAL"`` or as a table of it and more (``allowed``)
        keys, ``{ signal = "M.S", unit = "bar" }``: that table (the short form read as
        ``{ signal = "M.S" }``), and the key that names the signal in errors: ``"signal"``,
        or ``""`` for the short form (the table itself: ``legs.SB1_F1.piston``)."""
        if isinstance(self.data.get(name), dict):
            table = self.table(name)
            table.reject_unknown(allowed)
            return table, "signal"
        return TomlTable({"signal": self.string(name)}, self.source, self.key(name)), ""

    def subtables(self) -> Iterable[tuple[str, "TomlTable"]]:
        for name in self.data:
            yield name, self.table(name)

    def reject_unknown(self, allowed: Iterable[str]) -> None:
        """Refuse keys nobody reads: a typo would otherwise silently keep a default."""
        known = set(allowed)
        for name in self.data:
            if name not in known:
                raise self.error(name, f"unknown key; expected one of {sorted(known)}")

    def build(
        self,
        factory: Callable[..., T],
        owners: Mapping[str, "TomlTable"] | None = None,
        **kwargs: Any,
    ) -> T:
        """Call ``factory(**kwargs)``; its ValueError becomes a ConfigError.

        The error names the key of the field the message starts with, in the
        table ``owners`` says it came from (this table by default). Where the fields
        the message names come from several tables (a leg's own ``A_piston_m2`` below
        ``[leg_defaults]``' ``A_rod_m2``), it names this one, and this table's key among
        them: the value set here is the one that broke what the others allow; before,
        ``leg_defaults.A_rod_m2`` was blamed for a leg's piston area. Where they all
        come from one other table (the lever of ``[leg_defaults]`` alone), that one.
        """
        try:
            return factory(**kwargs)
        except ValueError as exc:
            message = str(exc)
            match = _FIELD_NAME.match(message)
            field = match.group(1) if match and match.group(1) in kwargs else ""

            def owner_of(name: str) -> "TomlTable":
                return (owners or {}).get(name, self)

            def names(name: str) -> bool:
                return re.search(rf"\b{re.escape(name)}\b", message) is not None

            # An angle's message names it without its unit: alpha_cyl for alpha_cyl_rad.
            named = [n for n in kwargs if n == field or names(n) or names(n.removesuffix("_rad"))]
            tables = {id(owner_of(n)): owner_of(n) for n in named}
            owner = next(iter(tables.values())) if len(tables) == 1 else self
            if owner is self and owner_of(field) is not self:
                field = next((n for n in named if owner_of(n) is self and names(n)), "")
            raise owner.error(field, message) from exc
