"""Writing the calibration: the TOML snippet for the machine config, and the page.

The snippet holds, per leg, the ``force_gain`` and ``force_offset_N`` the data
identify (the others are left out, so the configured values stay), headed by comments
with where they go (each leg's table of the config: pasted below it, TOML refuses a
table declared twice), the figures and the refusals. The page (``calibration.html`` with
``calibration.png`` beside it and embedded) shows the weight residual over the
quasi-static instants before and after, and per leg the parameters and the mean force
before and after.
"""

import base64
import html
import math
from pathlib import Path

import numpy as np

from estimator.calibration import Calibration


def rms_N(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2))) if values.size else math.nan


def summary_lines(calibration: Calibration, instants: int, total: int) -> list[str]:
    """The figures, one line each (for the snippet's head, the page and the terminal)."""
    c = calibration
    return [
        f"{instants} quasi-static instants of {total} snapshots; data rank {c.rank} of "
        f"{2 * len(c.legs)}, condition {c.condition:.0f}",
        f"weight residual RMS over them: {rms_N(c.residual_before_N):.0f} N before, "
        f"{rms_N(c.residual_after_N):.0f} N after",
        *c.refusals,
    ]


def toml_snippet(calibration: Calibration, lines: list[str]) -> str:
    """Per-leg ``[legs.<LEG>]`` tables with the identified keys, for the machine config."""
    out = [
        "# portal-daq calibrate: add each table's keys to that leg's [legs.<LEG>] table in",
        "# the machine config (not below it: TOML takes a table once, the config has each)",
    ]
    out += [f"# {line}" for line in lines]
    c = calibration
    for i, leg in enumerate(c.legs):
        keys = []
        if c.gain_identified[i]:
            keys.append(f"force_gain = {c.gain[i]:.5f}")
        if c.offset_identified[i]:
            keys.append(f"force_offset_N = {c.offset_N[i]:.1f}")
        out += ["", f"[legs.{leg}]"] + (
            keys or ["# nothing identified: keep the configured values"]
        )
    return "\n".join(out) + "\n"


def write_page(
    calibration: Calibration, t_s: np.ndarray, lines: list[str], directory: Path
) -> Path:
    """``calibration.png`` and ``calibration.html`` in ``directory``; returns the page."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c = calibration
    directory.mkdir(parents=True, exist_ok=True)
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6.5), constrained_layout=True)
    order = np.arange(len(t_s))
    top.plot(order, c.residual_before_N / 1e3, ".", label="before", color="#d62728", ms=4)
    top.plot(order, c.residual_after_N / 1e3, ".", label="after", color="#1a7f37", ms=4)
    top.axhline(0.0, color="#667085", lw=0.8)
    top.set_xlabel("quasi-static instant (in time order)")
    top.set_ylabel("weight residual / kN")
    top.set_title("Sum of the forces in contact minus the weight")
    top.legend()
    x = np.arange(len(c.legs))
    before = [_rms_leg(c.force_before_N[:, i], c.force_after_N[:, i]) for i in x]
    bottom.bar(
        x - 0.2, [b[0] / 1e3 for b in before], 0.4, label="mean force before", color="#d62728"
    )
    bottom.bar(
        x + 0.2, [b[1] / 1e3 for b in before], 0.4, label="mean force after", color="#1a7f37"
    )
    bottom.set_xticks(x, c.legs)
    bottom.set_ylabel("mean force in contact / kN")
    bottom.set_title("Per leg, over the instants it is down")
    bottom.legend(loc="lower center")
    picture = directory / "calibration.png"
    figure.savefig(picture, dpi=110)
    plt.close(figure)
    rows = "".join(
        f"<tr><td>{html.escape(leg)}</td><td>{c.gain[i]:.4f}</td>"
        f"<td>{'yes' if c.gain_identified[i] else 'no (kept)'}</td>"
        f"<td>{c.offset_N[i]:.0f}</td><td>{'yes' if c.offset_identified[i] else 'no (kept)'}</td>"
        f"<td>{before[i][0] / 1e3:.2f}</td><td>{before[i][1] / 1e3:.2f}</td></tr>"
        for i, leg in enumerate(c.legs)
    )
    encoded = base64.b64encode(picture.read_bytes()).decode()
    page = directory / "calibration.html"
    page.write_text(
        "<!doctype html><html lang=en><meta charset=utf-8><title>portal-daq calibration</title>"
        "<style>body{font:14px sans-serif;margin:20px}td,th{padding:3px 10px;text-align:right}"
        "td:first-child{text-align:left}</style><h1>Leg calibration</h1>"
        + "".join(f"<p>{html.escape(line)}</p>" for line in lines)
        + "<table><tr><th>leg</th><th>force_gain</th><th>identified</th><th>force_offset_N</th>"
        "<th>identified</th><th>mean force before / kN</th><th>after / kN</th></tr>"
        + rows
        + f'</table><p><a href="calibration.png"><img alt="weight residual before and after" '
        f'src="data:image/png;base64,{encoded}"></a></p></html>\n'
    )
    return page


def _rms_leg(before: np.ndarray, after: np.ndarray) -> tuple[float, float]:
    down = np.isfinite(before)
    if not down.any():
        return math.nan, math.nan
    return float(before[down].mean()), float(after[down].mean())
