"""The calibration's outputs: the TOML snippet loads into the machine config; the page.

(The README's picture comes from the simulated walking cycle: test_calibrate_command.py.)
"""

import tomllib
from pathlib import Path

import numpy as np
import pytest

from daq.calibrate.output import summary_lines, toml_snippet, write_page
from dbc.machine import load_machine_config
from estimator.calibration import fit_calibration
from tests.estimator.test_calibration import LEGS, W_TERM_N, WEIGHT_N, instants
from tests.helpers import EXAMPLE_CONFIG, with_leg_keys


def test_snippet_and_page(tmp_path: Path) -> None:
    lever_N, contact, _ = instants()
    fit = fit_calibration(lever_N, contact, W_TERM_N, WEIGHT_N, LEGS)
    lines = summary_lines(fit, len(lever_N), 2 * len(lever_N))
    assert lines[0] == "300 quasi-static instants of 600 snapshots; data rank 12 of 12, " + (
        f"condition {fit.condition:.0f}"
    )
    snippet = toml_snippet(fit, lines)
    # Where the keys go: pasted below the config (as the head said), each [legs.<LEG>]
    # header is a table the config already declares, and TOML refuses the file.
    assert snippet.startswith(
        "# portal-daq calibrate: add each table's keys to that leg's [legs.<LEG>] table in\n"
    )
    with pytest.raises(tomllib.TOMLDecodeError, match="Cannot declare"):
        tomllib.loads(EXAMPLE_CONFIG.read_text() + snippet)
    tables = tomllib.loads(snippet)["legs"]
    assert set(tables) == set(LEGS)
    assert all(set(keys) == {"force_gain", "force_offset_N"} for keys in tables.values())
    (tmp_path / "calibrated.toml").write_text(with_leg_keys(EXAMPLE_CONFIG.read_text(), tables))
    calibrated = load_machine_config(tmp_path / "calibrated.toml")[0]
    gains = [calibrated.legs[leg].geometry.force_gain for leg in LEGS]
    assert np.allclose(gains, fit.gain, atol=1e-5)

    page = write_page(fit, np.arange(len(lever_N)) * 0.1, lines, tmp_path / "page")
    text = page.read_text()
    assert "weight residual RMS over them" in text and "data:image/png;base64," in text
    assert text.count("<tr>") == 1 + len(LEGS)
    picture = tmp_path / "page" / "calibration.png"
    assert picture.stat().st_size > 10_000
