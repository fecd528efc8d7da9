"""External input: a real co-simulation's export (CSV or MATLAB .mat) as a SimulationResult.

The export holds a time column and pressure columns under any names; a mapping file
(TOML) says which is which, so the same emitter drives the bus with it::

    [input]
    time = "time"            # the time column (CSV header / .mat variable name)
    time_unit = "s"          # "s" or "ms"                    (or time_scale = factor to s)
    pressure_unit = "bar"    # "Pa", "kPa", "MPa" or "bar"    (or pressure_scale = factor to Pa)
    force_unit = "kN"        # "N" or "kN"                    (or force_scale = factor to N)
    dt_s = 0.01              # step of the uniform grid the data is resampled to

    [legs.SB1_F1]            # one table per leg SB1_F1 .. SB2_F3 (or the machine
                             # config's leg that plays it), each leg the config plays
    piston = "p_cap_1"       # piston chamber pressure column
    rod = "p_ann_1"          # rod chamber pressure column
    force = "Fz_1"           # optional: the true foot force (ground truth)
    stroke = "s_1"           # optional: leg stroke, m

    [bases.SB1]              # optional, per base SB1/SB2
    piston = "p_incl_cap_1"  # inclination cylinder pressures (pressure_unit)
    rod = "p_incl_ann_1"
    inclination = "incl_1"   # bridge inclination at the base, deg

    [signals]                # optional
    fold = "fold"            # bridge fold angle, deg
    rotation = "rot"         # bridge rotation, deg
    carriage = "x_carriage"  # carriage position, m
    phase = "phase"          # movement phase index 0..4 (idle, move_carriage, fold, ...)

Any column entry may be a number instead of a name: a constant in the mapping's units
(e.g. ``piston = 0.0`` for a leg the export does not model). What the mapping leaves out
is filled with constants: inclination-cylinder pressures 0 Pa, strokes 0 m, angles 0 deg,
carriage 0 m, phase 0 (``idle``), no slipping; the true force and the ground compression,
which nothing can stand in for, are NaN (the truth files then say "unknown").

A ``[legs.<LEG>]`` table may name a leg of the machine configuration instead of a
simulated leg (``legs``: config leg -> simulated leg, :class:`~sim_bridge.leg_map.LegMap`),
so a mapping written for a machine with other leg names needs no translation.

Samples are linearly interpolated onto the grid ``0, dt_s, 2 dt_s, ...`` from the first
time stamp (the phase is held, not interpolated). A .mat file holds one variable per
column (vectors; MATLAB ``-v7`` or older, since scipy cannot read ``-v7.3``). Every
problem (a missing column, a non-numeric cell, time not increasing) raises
:class:`~daq.errors.ConfigError` naming the file and the key or column.
"""

import csv
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import scipy.io
from scipy.io.matlab import MatReadError

from dbc.errors import ConfigError
from dbc.machine import read_toml
from dbc.toml_table import TomlTable
from sim_bridge.result import BASES, LEGS, PHASES, FloatArray, SimulationResult

TIME_UNITS = {"s": 1.0, "ms": 1e-3}
PRESSURE_UNITS = {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "bar": 1e5}
FORCE_UNITS = {"N": 1.0, "kN": 1e3}
DEFAULT_DT_S = 0.01
#: Most samples the uniform grid may have (per column, 8 bytes each): dt_s = 1e-9 asked
#: numpy for 7.45 GiB (MemoryError), 1e-300 for more than it can index (ValueError).
MAX_GRID_SAMPLES = 10_000_000

Columns = Mapping[str, FloatArray]


def load_external(
    data_path: str | Path, mapping_path: str | Path, legs: Mapping[str, str] | None = None
) -> SimulationResult:
    """Read an export and its mapping into a :class:`SimulationResult`; ``legs``: the
    config leg -> simulated leg names the mapping's leg tables may use."""
    mapping = read_toml(mapping_path)
    columns = read_columns(data_path)
    return build_result(columns, mapping, str(mapping_path), str(data_path), legs)


def read_columns(path: str | Path) -> dict[str, FloatArray]:
    """The numeric columns of a ``.csv`` or ``.mat`` file, by name."""
    suffix = Path(path).suffix.lower()
    if suffix == ".mat":
        return _read_mat(path)
    if suffix == ".csv":
        return _read_csv(path)
    raise ConfigError(path, "", f"unknown input format {suffix!r}; give a .csv or a .mat file")


def _read_csv(path: str | Path) -> dict[str, FloatArray]:
    try:
        with open(path, newline="", encoding="utf-8-sig") as file:
            rows = [row for row in csv.reader(file) if row and any(cell.strip() for cell in row)]
    except FileNotFoundError as exc:
        raise ConfigError(path, "", "no such file") from exc
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ConfigError(path, "", f"cannot read it as CSV: {exc}") from exc
    if len(rows) < 2:
        raise ConfigError(path, "", "needs a header row and at least one row of numbers")
    header = [name.strip() for name in rows[0]]
    data: dict[str, list[float]] = {name: [] for name in header if name}
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise ConfigError(
                path, f"line {line}", f"{len(row)} cells, the header has {len(header)}"
            )
        for name, cell in zip(header, row, strict=True):
            if name:
                data[name].append(_number(path, line, name, cell))
    return {name: np.asarray(values, dtype=np.float64) for name, values in data.items()}


def _number(path: str | Path, line: int, column: str, cell: str) -> float:
    text = cell.strip()
    if not text:
        return math.nan
    try:
        return float(text)
    except ValueError:
        raise ConfigError(
            path, f"line {line}", f"column {column!r}: not a number: {text!r}"
        ) from None


def _read_mat(path: str | Path) -> dict[str, FloatArray]:
    try:
        variables = scipy.io.loadmat(str(path), squeeze_me=True)
    except FileNotFoundError as exc:
        raise ConfigError(path, "", "no such file") from exc
    except NotImplementedError as exc:  # scipy's answer to HDF5-based v7.3 files
        raise ConfigError(path, "", "a MATLAB v7.3 file; save it with save(..., '-v7')") from exc
    except (OSError, ValueError, TypeError, MatReadError) as exc:
        raise ConfigError(path, "", f"cannot read it as a MATLAB .mat file: {exc}") from exc
    columns: dict[str, FloatArray] = {}
    for name, value in variables.items():
        if name.startswith("__"):
            continue
        array = np.asarray(value)
        if array.ndim <= 1 and array.dtype.kind in "fiub":
            columns[name] = np.atleast_1d(array).astype(np.float64)
    return columns


def _lookup(table: TomlTable, key: str, columns: Columns, data_source: str) -> FloatArray:
    """The column ``table[key]`` names, checked to hold only finite numbers."""
    name = table.string(key)
    if name not in columns:
        known = ", ".join(sorted(columns)[:12]) or "no numeric columns"
        raise table.error(key, f"no column {name!r} in {data_source}; it has: {known}")
    values = columns[name]
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise table.error(key, f"column {name!r}: sample {bad[0]} is not a finite number")
    return values


class _Grid:
    """Mapped columns, resampled onto the uniform grid ``time_s[0] + k * dt_s``."""

    def __init__(self, columns: Columns, data_source: str, time_s: FloatArray, dt_s: float):
        self.columns = columns
        self.data_source = data_source
        self.time_s = time_s
        steps = int((time_s[-1] - time_s[0]) / dt_s + 1e-9)
        self.grid_s = time_s[0] + dt_s * np.arange(steps + 1)

    def raw(self, table: TomlTable, key: str) -> FloatArray:
        value = table.data[key]
        if isinstance(value, bool) or not isinstance(value, (str, int, float)):
            raise table.error(key, f"must be a column name or a number, got {value!r}")
        if not isinstance(value, str):  # nan and inf were sent; 10**400 an OverflowError
            return np.full(self.time_s.shape, table.finite(key, value))
        values = _lookup(table, key, self.columns, self.data_source)
        if values.shape != self.time_s.shape:
            raise table.error(
                key,
                f"column {value!r} has {values.size} values, the time column {self.time_s.size}",
            )
        return values

    def get(self, table: TomlTable, key: str, scale: float, default: float) -> FloatArray:
        """The mapped column times ``scale`` on the grid, or ``default`` when unmapped."""
        if key not in table:
            return np.full(self.grid_s.shape, default)
        resampled: FloatArray = np.interp(self.grid_s, self.time_s, self.raw(table, key) * scale)
        return resampled

    def held(self, table: TomlTable, key: str, default: float) -> FloatArray:
        """Like :meth:`get`, but holding the previous sample instead of interpolating."""
        if key not in table:
            return np.full(self.grid_s.shape, default)
        index = np.searchsorted(self.time_s, self.grid_s + 1e-9, side="right") - 1
        held: FloatArray = self.raw(table, key)[np.clip(index, 0, self.time_s.size - 1)]
        return held


def _scale(table: TomlTable, unit_key: str, scale_key: str, units: Mapping[str, float]) -> float:
    if unit_key in table and scale_key in table:
        raise table.error(scale_key, f"give {unit_key} or {scale_key}, not both")
    if scale_key in table:
        scale = table.number(scale_key)
        if not scale > 0:  # a negative pressure scale sent every pressure negated
            raise table.error(scale_key, f"must be > 0 (a factor to SI units), got {scale:g}")
        return scale
    unit = table.string(unit_key, next(iter(units)))
    if unit not in units:
        raise table.error(unit_key, f"unknown unit {unit!r}; expected one of {', '.join(units)}")
    return units[unit]


def _leg_tables(legs: TomlTable, config_legs: Mapping[str, str]) -> list[TomlTable | None]:
    """The table of each simulated leg, in LEGS order: named after it, or after the
    config leg that plays it (``config_legs``: config leg -> simulated leg). A simulated
    leg no config leg plays (a machine of fewer legs) may be left out: None, never sent."""
    legs.reject_unknown((*LEGS, *config_legs))
    names: dict[str, str] = {}
    for name in legs.data:
        simulated = config_legs.get(name, name)
        if simulated in names:
            raise legs.error(name, f"maps {simulated} again (legs.{names[simulated]} does)")
        names[simulated] = name
    played = [leg for leg in LEGS if leg in config_legs.values()] if config_legs else LEGS
    tables: list[TomlTable | None] = []
    for leg in LEGS:
        if leg in names:
            tables.append(legs.table(names[leg]))
        elif leg not in played:
            tables.append(None)
        else:
            named = {s: c for c, s in reversed(list(config_legs.items()))}  # the first one
            every = ", ".join(named.get(p, p) for p in played)
            raise legs.error(
                named.get(leg, leg),
                f"missing; map every leg the machine plays ({every}), a number for none",
            )
    return tables


def build_result(
    columns: Columns,
    mapping: dict[str, Any],
    source: str,
    data_source: str,
    legs: Mapping[str, str] | None = None,
) -> SimulationResult:
    """A :class:`SimulationResult` from named ``columns`` per the parsed ``mapping``;
    ``legs``: config leg -> simulated leg, for leg tables named after config legs."""
    root = TomlTable(mapping, source)
    root.reject_unknown(("input", "legs", "bases", "signals"))
    head = root.table("input")
    head.reject_unknown(
        ("time", "time_unit", "time_scale", "pressure_unit", "pressure_scale",
         "force_unit", "force_scale", "dt_s")
    )  # fmt: skip
    time_scale = _scale(head, "time_unit", "time_scale", TIME_UNITS)
    pressure_scale = _scale(head, "pressure_unit", "pressure_scale", PRESSURE_UNITS)
    force_scale = _scale(head, "force_unit", "force_scale", FORCE_UNITS)
    dt_s = head.number("dt_s", DEFAULT_DT_S)
    if dt_s <= 0:
        raise head.error("dt_s", f"must be > 0, got {dt_s}")
    time_s = _lookup(head, "time", columns, data_source) * time_scale
    if time_s.size < 2 or np.any(np.diff(time_s) <= 0):
        raise head.error("time", "the time column must increase strictly over 2+ samples")
    samples = (time_s[-1] - time_s[0]) / dt_s
    if not samples <= MAX_GRID_SAMPLES:
        raise head.error(
            "dt_s",
            f"{dt_s:g} s over the export's {time_s[-1] - time_s[0]:g} s makes {samples:.3g} "
            f"samples, more than {MAX_GRID_SAMPLES:,}: give a larger dt_s (the bus takes "
            "the legs every 10 ms)",
        )
    data = _Grid(columns, data_source, time_s, dt_s)
    n = data.grid_s.size
    if n < 2:
        raise head.error("dt_s", f"{dt_s} s leaves fewer than 2 samples in the export")

    leg_tables = _leg_tables(root.table("legs"), legs or {})
    per_leg: dict[str, list[FloatArray]] = {"piston": [], "rod": [], "force": [], "stroke": []}
    for table in leg_tables:
        if table is None:  # not played: filled as a leg the export does not model
            table = TomlTable({"piston": 0.0, "rod": 0.0}, source, "legs")
        table.reject_unknown(per_leg)
        for key in ("piston", "rod"):
            if key not in table:
                raise table.error(key, "missing: the column of this chamber pressure")
        per_leg["piston"].append(data.get(table, "piston", pressure_scale, 0.0))
        per_leg["rod"].append(data.get(table, "rod", pressure_scale, 0.0))
        per_leg["force"].append(data.get(table, "force", force_scale, math.nan))
        per_leg["stroke"].append(data.get(table, "stroke", 1.0, 0.0))

    bases = root.table("bases", required=False)
    bases.reject_unknown(BASES)
    per_base: dict[str, list[FloatArray]] = {"piston": [], "rod": [], "inclination": []}
    for base in BASES:
        table = bases.table(base, required=False)
        table.reject_unknown(per_base)
        per_base["piston"].append(data.get(table, "piston", pressure_scale, 0.0))
        per_base["rod"].append(data.get(table, "rod", pressure_scale, 0.0))
        per_base["inclination"].append(data.get(table, "inclination", 1.0, 0.0))

    signals = root.table("signals", required=False)
    signals.reject_unknown(("fold", "rotation", "carriage", "phase"))
    phase = data.held(signals, "phase", 0.0)
    if np.any((phase < 0) | (phase >= len(PHASES)) | (phase != np.round(phase))):
        raise signals.error("phase", f"must hold whole numbers 0..{len(PHASES) - 1}")

    return SimulationResult(
        t_s=data.grid_s - data.grid_s[0],
        p_piston_Pa=np.column_stack(per_leg["piston"]),
        p_rod_Pa=np.column_stack(per_leg["rod"]),
        force_true_N=np.column_stack(per_leg["force"]),
        ground_compression_m=np.full((n, len(LEGS)), math.nan),
        slipping=np.zeros((n, len(LEGS)), dtype=np.bool_),
        incl_p_piston_Pa=np.column_stack(per_base["piston"]),
        incl_p_rod_Pa=np.column_stack(per_base["rod"]),
        stroke_m=np.column_stack(per_leg["stroke"]),
        inclination_deg=np.column_stack(per_base["inclination"]),
        fold_deg=data.get(signals, "fold", 1.0, 0.0),
        rotation_deg=data.get(signals, "rotation", 1.0, 0.0),
        carriage_m=data.get(signals, "carriage", 1.0, 0.0),
        phase=phase.astype(np.int_),
    )
