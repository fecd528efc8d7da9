"""Writing a campaign report: the table as CSV, one summary page with its picture.

``campaign.csv``: every :class:`~daq.report.campaign.CampaignRow`, columns
:data:`~daq.report.campaign.COLUMNS`, floats in full precision (``repr``), NaN as an
empty cell. ``campaign.html``: self-contained (the picture embedded, as in the single
report): per recording its cycles, highest peak, longest time above the limit,
invalid share and weight residual; per machine and foot the same over the campaign;
``campaign_peaks.png``: every foot-cycle's peak and near-constant pressure per foot.
(Parquet is not written: pyarrow would be a heavy dependency for one more format; the
CSV loads into pandas, polars or a spreadsheet as it is.)
"""

import csv
import html
import math
from collections.abc import Iterable, Sequence
from dataclasses import astuple
from datetime import UTC, datetime
from itertools import groupby
from pathlib import Path

import numpy as np

from daq.report.campaign import COLUMNS, CampaignRow
from daq.report.figures import _figure, png_bytes
from daq.report.page import STYLE, Picture, _number, _picture, _table

CSV_NAME = "campaign.csv"
PAGE_NAME = "campaign.html"
PEAKS_NAME = "campaign_peaks.png"


def write_csv(rows: Iterable[CampaignRow], path: Path) -> None:
    with open(path, "w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out)
        writer.writerow(COLUMNS)
        for row in rows:
            writer.writerow([_cell(value) for value in astuple(row)])


def _cell(value: object) -> str:
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    return str(value)


def _max(values: Iterable[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return max(finite) if finite else math.nan


def _fraction(rows: Sequence[CampaignRow]) -> float:
    """Invalid estimates over all estimates of ``rows``."""
    estimates = sum(r.estimates for r in rows)
    invalid = sum(r.invalid_fraction * r.estimates for r in rows if r.estimates)
    return invalid / estimates if estimates else math.nan


def recording_rows(rows: Sequence[CampaignRow]) -> list[list[str]]:
    """Per recording (flagged when cut short): machine, cycles, duration, highest peak
    (foot, cycle), longest time above the limit, invalid share, the range of the cycles'
    median weight residuals."""
    table = []
    for name, group in groupby(rows, key=lambda r: r.recording):
        members = list(group)
        cycles = {r.cycle_start_s: r for r in members}.values()
        top = max(
            members, key=lambda r: r.peak_pressure_Pa if math.isfinite(r.peak_pressure_Pa) else -1
        )
        residuals = [c.weight_residual_median_N for c in cycles]
        table.append(
            [
                name + ("" if members[0].complete else " (cut short: its end is missing)"),
                members[0].machine_id,
                str(len(cycles)),
                _number(sum(c.cycle_duration_s for c in cycles)),
                f"{_number(top.peak_pressure_Pa, 1e3)} ({top.leg}, {_cycle(top.cycle)})",
                _number(_max(r.time_above_limit_s for r in members)),
                _number(100 * _fraction(members), digits=2),
                f"{_number(min(residuals, default=math.nan), 1e3, 2)} .. "
                f"{_number(_max(residuals), 1e3, 2)}"
                if any(math.isfinite(v) for v in residuals)
                else "n/a",
            ]
        )
    return table


def foot_rows(rows: Sequence[CampaignRow]) -> list[list[str]]:
    """Per machine and foot over the campaign: foot-cycles, highest and median peak,
    highest near-constant pressure, total time above the limit, invalid share."""
    table = []
    key = lambda r: (r.machine_id, r.leg)  # noqa: E731
    for (machine_id, leg), group in groupby(sorted(rows, key=key), key=key):
        members = list(group)
        peaks = np.array([r.peak_pressure_Pa for r in members])
        finite = peaks[np.isfinite(peaks)]
        table.append(
            [
                machine_id,
                leg,
                str(len(members)),
                _number(_max(peaks.tolist()), 1e3),
                _number(float(np.median(finite)) if finite.size else math.nan, 1e3),
                _number(_max(r.near_constant_pressure_Pa for r in members), 1e3),
                _number(sum(r.time_above_limit_s for r in members)),
                _number(100 * _fraction(members), digits=2),
            ]
        )
    return table


def peaks_picture(rows: Sequence[CampaignRow]) -> Picture:
    """Every foot-cycle's peak (dots) and near-constant pressure (crosses) per foot."""
    legs = list(dict.fromkeys(r.leg for r in rows))
    figure = _figure(11.0, 5.0)
    axes = figure.subplots()
    jitter = np.random.default_rng(0)  # fixed: the same picture for the same table
    for index, leg in enumerate(legs):
        mine = [r for r in rows if r.leg == leg]
        x = index + jitter.uniform(-0.25, 0.25, len(mine))
        axes.scatter(x, [r.peak_pressure_Pa / 1e3 for r in mine], s=14, color=f"C{index}")
        near = [r.near_constant_pressure_Pa / 1e3 for r in mine]
        axes.scatter(x, near, s=18, marker="x", color=f"C{index}", alpha=0.6)
    limits = sorted({r.pressure_limit_Pa for r in rows})
    for limit_Pa in limits:
        axes.axhline(limit_Pa / 1e3, color="tab:red", linewidth=0.8, linestyle=(0, (4, 3)))
    axes.set_xticks(range(len(legs)), legs)
    axes.set_ylabel("contact pressure / kPa")
    axes.grid(True, axis="y", alpha=0.3)
    axes.set_title(
        "Peak (dots) and near-constant (crosses) contact pressure of every foot-cycle; "
        f"dashed: limit {', '.join(f'{v / 1e3:g}' for v in limits)} kPa",
        fontsize=10,
    )
    return Picture(
        PEAKS_NAME, "Peak and near-constant pressure per foot and cycle", png_bytes(figure)
    )


def render_campaign_page(
    rows: Sequence[CampaignRow], picture: Picture, runs: int, empty: int = 0
) -> str:
    machines = sorted({r.machine_id for r in rows})
    cycles = len({(r.recording, r.cycle_start_s) for r in rows})
    made = f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC"
    left_out = f" {empty} more recordings hold nothing (no frame, no estimate): left out."
    left_out *= bool(empty)
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>portal-daq campaign report</title>
<style>{STYLE}</style></head><body>
<h1>Campaign report: {runs} recordings, {len(machines)} machines, {cycles} cycles</h1>
<p class=note>Machines: {html.escape(", ".join(machines))}. Made {made}.{left_out} The full table
(per recording, cycle and foot) is <a href="{CSV_NAME}">{CSV_NAME}</a>.</p>
<h2>Recordings</h2>
{
        _table(
            [
                "recording",
                "machine",
                "cycles",
                "duration s",
                "highest peak kPa",
                "longest above limit s",
                "invalid %",
                "weight residual kN (cycle medians)",
            ],
            recording_rows(rows),
            text_columns=2,
        )
    }
<h2>Feet over the campaign</h2>
{
        _table(
            [
                "machine",
                "foot",
                "foot-cycles",
                "highest peak kPa",
                "median peak kPa",
                "highest near-constant kPa",
                "above limit s (sum)",
                "invalid %",
            ],
            foot_rows(rows),
            text_columns=2,
        )
    }
{_picture(picture)}
<p class=note>Peak and near-constant pressure (the best mean over the estimator's window)
and the time above the limit per cycle come from the estimator's own metrics tracker, as
in the single report; the weight residual is the sum of the forces of the feet in contact
minus the machine's weight, at the instants where every foot is valid.</p>
</body></html>
"""


def _cycle(count: int) -> str:
    return "whole recording" if count < 0 else f"cycle {count}"


def write_campaign(
    rows: Sequence[CampaignRow], out_dir: Path, runs: int, empty: int = 0
) -> list[Path]:
    """Write the CSV, the picture and the page into ``out_dir`` (created); page last."""
    out_dir.mkdir(parents=True, exist_ok=True)
    picture = peaks_picture(rows)
    table = out_dir / CSV_NAME
    write_csv(rows, table)
    image = out_dir / PEAKS_NAME
    image.write_bytes(picture.png)
    page = out_dir / PAGE_NAME
    page.write_text(render_campaign_page(rows, picture, runs, empty), encoding="utf-8")
    return [table, image, page]
