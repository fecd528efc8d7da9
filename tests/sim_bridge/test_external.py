"""External co-simulation exports (CSV, MATLAB .mat) load as SimulationResults, or fail clearly."""

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from dbc.errors import ConfigError
from sim_bridge.external import load_external
from sim_bridge.result import LEGS

MAPPING = """
[input]
time = "time_ms"
time_unit = "ms"
pressure_unit = "bar"
force_unit = "kN"
dt_s = 0.01

[legs]
{legs}

[bases.SB1]
inclination = "incl1"

[signals]
phase = "phase"
fold = 12.5
"""


def leg_tables(with_force: bool = True) -> str:
    tables = []
    for i, leg in enumerate(LEGS):
        force = f', force = "F{i}"' if with_force else ""
        tables.append(f'{leg} = {{ piston = "pA{i}", rod = "pB{i}"{force} }}')
    return "\n".join(tables)


def export_columns(n: int = 51) -> dict[str, np.ndarray]:
    """Samples every 20 ms (to be resampled onto 10 ms), pressures in bar, forces in kN."""
    t_ms = np.arange(n) * 20.0
    columns = {"time_ms": t_ms, "incl1": np.linspace(-2, 2, n), "phase": (t_ms >= 500) * 2.0}
    for i in range(len(LEGS)):
        columns[f"pA{i}"] = 100.0 + i + t_ms / 100
        columns[f"pB{i}"] = np.full(n, 8.0)
        columns[f"F{i}"] = 50.0 + i + 0 * t_ms
    return columns


def write_csv(path: Path, columns: dict[str, np.ndarray]) -> Path:
    names = list(columns)
    lines = [",".join(names)]
    for row in range(len(columns[names[0]])):
        lines.append(",".join(repr(float(columns[name][row])) for name in names))
    path.write_text("\n".join(lines) + "\n")
    return path


def write_mapping(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "mapping.toml"
    path.write_text(text)
    return path


def check(result, with_force: bool = True) -> None:  # type: ignore[no-untyped-def]
    assert len(result) == 101 and result.dt_s == pytest.approx(0.01)
    assert result.t_s[0] == 0.0 and result.t_s[-1] == pytest.approx(1.0)
    # pA0 = 100 bar + t_ms/100 bar, linear: at 0.33 s, 103.3 bar.
    assert result.p_piston_Pa[33, 0] == pytest.approx(103.3e5)
    assert result.p_piston_Pa[33, 5] == pytest.approx(108.3e5)
    assert np.all(result.p_rod_Pa == pytest.approx(8e5))
    if with_force:
        assert result.force_true_N[10, 3] == pytest.approx(53e3)
    else:
        assert np.all(np.isnan(result.force_true_N))
    assert result.inclination_deg[50, 0] == pytest.approx(0.0, abs=1e-12)
    assert np.all(result.inclination_deg[:, 1] == 0.0)  # not mapped: 0
    assert np.all(result.fold_deg == 12.5)  # a constant from the mapping
    assert list(result.phase[[0, 49, 50, 100]]) == [0, 0, 2, 2]  # held, not interpolated
    assert np.all(result.stroke_m == 0.0) and not result.slipping.any()
    assert np.all(np.isnan(result.ground_compression_m))


def test_a_csv_export_loads(tmp_path: Path) -> None:
    data = write_csv(tmp_path / "export.csv", export_columns())
    check(load_external(data, write_mapping(tmp_path, MAPPING.format(legs=leg_tables()))))


def test_a_mat_export_loads(tmp_path: Path) -> None:
    data = tmp_path / "export.mat"
    columns = export_columns()
    columns["time_ms"] = columns["time_ms"][:, None]  # MATLAB column vectors are fine too
    scipy.io.savemat(data, columns)
    mapping = write_mapping(tmp_path, MAPPING.format(legs=leg_tables(with_force=False)))
    check(load_external(data, mapping), with_force=False)


def refused(tmp_path: Path, mapping: str, columns: dict | None = None, csv_text: str | None = None):  # type: ignore[no-untyped-def]
    data = tmp_path / "export.csv"
    if csv_text is not None:
        data.write_text(csv_text)
    else:
        write_csv(data, export_columns() if columns is None else columns)
    with pytest.raises(ConfigError) as info:
        load_external(data, write_mapping(tmp_path, mapping))
    return str(info.value)


def test_a_missing_column_is_named(tmp_path: Path) -> None:
    mapping = MAPPING.format(legs=leg_tables()).replace('"pB3"', '"p_rod_3"')
    message = refused(tmp_path, mapping)
    assert "mapping.toml: legs.SB2_F1.rod: no column 'p_rod_3' in " in message
    assert "export.csv; it has: F0, F1" in message


def test_a_missing_leg_is_named(tmp_path: Path) -> None:
    legs = "\n".join(line for line in leg_tables().splitlines() if not line.startswith("SB2_F3"))
    message = refused(tmp_path, MAPPING.format(legs=legs))
    assert "legs.SB2_F3: missing; map every leg the machine plays (SB1_F1, " in message


#: A four-legged machine's legs and the simulated legs they play (SB1_F1, SB2_F1 unplayed).
FOUR_LEGS = {"FL": "SB1_F2", "FR": "SB1_F3", "RL": "SB2_F2", "RR": "SB2_F3"}


def four_leg_tables() -> str:
    """The mapping's leg tables of FOUR_LEGS, named as the config does, reading the
    columns of the simulated leg each plays."""
    return "\n".join(
        f'{leg} = {{ piston = "pA{LEGS.index(s)}", rod = "pB{LEGS.index(s)}", '
        f'force = "F{LEGS.index(s)}" }}'
        for leg, s in FOUR_LEGS.items()
    )


def test_a_machine_of_fewer_legs_maps_only_the_legs_it_plays(tmp_path: Path) -> None:
    # A four-legged config plays four of the six simulated legs: its mapping names those
    # (by the config's leg names) and no others. It was refused: "legs.SB1_F1: missing;
    # map every leg", a leg no config leg plays and the mapping cannot name.
    data = write_csv(tmp_path / "export.csv", export_columns())
    result = load_external(
        data, write_mapping(tmp_path, MAPPING.format(legs=four_leg_tables())), FOUR_LEGS
    )
    assert result.p_piston_Pa[33, 1] == pytest.approx(104.3e5)  # FL plays SB1_F2: pA1
    assert result.force_true_N[10, 5] == pytest.approx(55e3)  # RR plays SB2_F3: F5
    for unplayed in (0, 3):  # SB1_F1, SB2_F1: never sent
        assert np.all(result.p_piston_Pa[:, unplayed] == 0.0)
        assert np.all(np.isnan(result.force_true_N[:, unplayed]))


def test_a_played_leg_missing_is_named_as_the_config_names_it(tmp_path: Path) -> None:
    legs = "\n".join(line for line in four_leg_tables().splitlines() if not line.startswith("RL"))
    data = write_csv(tmp_path / "export.csv", export_columns())
    with pytest.raises(ConfigError) as info:
        load_external(data, write_mapping(tmp_path, MAPPING.format(legs=legs)), FOUR_LEGS)
    assert "legs.RL: missing; map every leg the machine plays (FL, FR, RL, RR)" in str(info.value)


def test_a_missing_pressure_key_is_named(tmp_path: Path) -> None:
    legs = leg_tables().replace('piston = "pA2", ', "")
    assert "legs.SB1_F3.piston: missing" in refused(tmp_path, MAPPING.format(legs=legs))


def test_an_unknown_unit_is_named(tmp_path: Path) -> None:
    mapping = MAPPING.format(legs=leg_tables()).replace('"bar"', '"psi"')
    assert "input.pressure_unit: unknown unit 'psi'; expected one of Pa" in refused(
        tmp_path, mapping
    )


def test_a_typo_in_the_mapping_is_refused(tmp_path: Path) -> None:
    mapping = MAPPING.format(legs=leg_tables()).replace("dt_s", "dt")
    assert "input.dt: unknown key" in refused(tmp_path, mapping)


@pytest.mark.parametrize(
    ("old", "new", "key", "reason"),
    [
        # numpy was asked for 7.45 GiB (MemoryError), or more than it indexes (ValueError).
        ("dt_s = 0.01", "dt_s = 1e-9", "input.dt_s", "samples, more than 10,000,000"),
        ("dt_s = 0.01", "dt_s = 1e-300", "input.dt_s", "give a larger dt_s"),
        # Every pressure was sent negated.
        ('pressure_unit = "bar"', "pressure_scale = -1e5", "input.pressure_scale", "> 0"),
        ("fold = 12.5", "fold = nan", "signals.fold", "must be finite"),
        ("fold = 12.5", "fold = -inf", "signals.fold", "must be finite"),
        ("fold = 12.5", f"fold = {10**400}", "signals.fold", "must fit in 64 bits"),
    ],
)
def test_a_mapping_value_that_cannot_be_played_is_refused_naming_the_key(
    tmp_path: Path, old: str, new: str, key: str, reason: str
) -> None:
    csv = write_csv(tmp_path / "export.csv", export_columns())
    mapping = MAPPING.format(legs=leg_tables())
    assert old in mapping
    (tmp_path / "map.toml").write_text(mapping.replace(old, new, 1))
    with pytest.raises(ConfigError) as info:
        load_external(csv, tmp_path / "map.toml")
    assert info.value.key == key
    assert reason in str(info.value)


def test_time_must_increase(tmp_path: Path) -> None:
    columns = export_columns()
    columns["time_ms"][10] = columns["time_ms"][9]
    message = refused(tmp_path, MAPPING.format(legs=leg_tables()), columns)
    assert "input.time: the time column must increase strictly" in message


def test_a_non_number_names_the_line_and_column(tmp_path: Path) -> None:
    text = "time_ms,pA0\n0,1\n20,abc\n"
    message = refused(tmp_path, MAPPING.format(legs=leg_tables()), csv_text=text)
    assert message.endswith("export.csv: line 3: column 'pA0': not a number: 'abc'")


def test_a_gap_in_a_mapped_column_is_refused(tmp_path: Path) -> None:
    columns = export_columns()
    columns["pA1"][7] = math.nan
    message = refused(tmp_path, MAPPING.format(legs=leg_tables()), columns)
    assert "legs.SB1_F2.piston: column 'pA1': sample 7 is not a finite number" in message


def test_an_unknown_format_and_a_missing_file_are_refused(tmp_path: Path) -> None:
    mapping = write_mapping(tmp_path, MAPPING.format(legs=leg_tables()))
    with pytest.raises(ConfigError, match=r"unknown input format '.xlsx'; give a .csv or a .mat"):
        load_external(tmp_path / "export.xlsx", mapping)
    with pytest.raises(ConfigError, match=r"nothere.csv: no such file"):
        load_external(tmp_path / "nothere.csv", mapping)
    with pytest.raises(ConfigError, match=r"nomap.toml: no such file"):
        load_external(tmp_path / "export.csv", tmp_path / "nomap.toml")


@pytest.mark.parametrize("content", [b"this is not MATLAB", bytes(range(256)) * 4, b"x" * 300])
def test_a_broken_mat_file_is_refused(tmp_path: Path, content: bytes) -> None:
    data = tmp_path / "export.mat"
    data.write_bytes(content)
    mapping = write_mapping(tmp_path, MAPPING.format(legs=leg_tables()))
    with pytest.raises(ConfigError, match=r"export.mat: "):
        load_external(data, mapping)
