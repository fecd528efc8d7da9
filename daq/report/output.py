"""Writing a report: the PNG files and the HTML page into one directory.

:func:`render` draws the pictures (no files); :func:`write_report` writes them and the
page, replacing earlier files of the same names and nothing else.
"""

import logging
from pathlib import Path

from daq.report.content import ReportContent
from daq.report.figures import (
    comparison_figure,
    cycle_metrics_figure,
    deviation_boxplot_figure,
    png_bytes,
    time_series_figure,
)
from daq.report.page import Picture, render_page

logger = logging.getLogger(__name__)

PAGE_NAME = "report.html"


def render(content: ReportContent) -> dict[str, Picture]:
    """Every picture the content allows, by role (see :func:`daq.report.page.render_page`)."""
    pictures = {
        "pressure": Picture(
            "pressure.png",
            "Contact pressure per foot over time (cf. Figure 7 of the paper)",
            png_bytes(time_series_figure(content, "pressure")),
        ),
        "force": Picture(
            "force.png",
            "Ground force per foot over time (cf. Figure 8)",
            png_bytes(time_series_figure(content, "force")),
        ),
        "cycles": Picture(
            "cycle_pressures.png",
            "Peak and near-constant contact pressure per foot and cycle",
            png_bytes(cycle_metrics_figure(content)),
        ),
    }
    if content.most_loaded is not None:
        pictures["comparison"] = Picture(
            "truth_comparison.png",
            f"Calculated vs. true ground force of {content.most_loaded} (cf. Figure 5)",
            png_bytes(comparison_figure(content)),
        )
        pictures["deviation"] = Picture(
            "truth_deviation.png",
            "Deviation of the calculated from the true force per foot (cf. Figure 6)",
            png_bytes(deviation_boxplot_figure(content)),
        )
    return pictures


def write_report(content: ReportContent, out_dir: Path) -> list[Path]:
    """Write the PNGs and ``report.html`` into ``out_dir`` (created); the paths, page last.

    An :class:`OSError` (directory not writable, disk full) goes to the caller.
    """
    pictures = render(content)
    page = render_page(content, pictures)
    written: list[Path] = []
    out_dir.mkdir(parents=True, exist_ok=True)
    for picture in pictures.values():
        path = out_dir / picture.file_name
        path.write_bytes(picture.png)
        written.append(path)
    path = out_dir / PAGE_NAME
    path.write_text(page, encoding="utf-8")
    written.append(path)
    logger.info("wrote %d files to %s", len(written), out_dir)
    return written
