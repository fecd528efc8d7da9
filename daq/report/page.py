"""The report as one self-contained HTML page (pure: content and PNG bytes in, text out).

Every picture is embedded as a base64 ``data:`` URI, so the page alone can be mailed or
archived; each also links to its PNG file next to the page (relative ``href``) for
full-size viewing. No scripts, fonts or style sheets from elsewhere.
"""

import base64
import html
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

from daq.report.content import ReportContent, log_time
from daq.report.figures import PAPER_ABS50_N, PAPER_ABS95_N
from estimator.settings import EstimatorSettings

STYLE = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1400px; color: #222; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 1.8em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: right; }
th { background: #f0f0f0; } td.text, th.text { text-align: left; }
img { max-width: 100%; border: 1px solid #ddd; }
.note { color: #555; font-size: 0.9em; }
"""


@dataclass(frozen=True, slots=True)
class Picture:
    """One PNG of the report: its file name (next to the page), caption and bytes."""

    file_name: str
    caption: str
    png: bytes


def _number(value: float, scale: float = 1.0, digits: int = 1) -> str:
    return f"{value / scale:.{digits}f}" if math.isfinite(value) else "n/a"


def _time(t_s: float) -> str:
    return log_time(t_s) or f"{datetime.fromtimestamp(t_s, UTC):%Y-%m-%d %H:%M:%S.%f}"[:-3] + " UTC"


def _table(header: Sequence[str], rows: Iterable[Sequence[str]], text_columns: int = 1) -> str:
    def row(cells: Sequence[str], tag: str) -> str:
        return (
            "<tr>"
            + "".join(
                f"<{tag}{' class=text' if i < text_columns else ''}>{html.escape(c)}</{tag}>"
                for i, c in enumerate(cells)
            )
            + "</tr>"
        )

    body = "\n".join(row(cells, "td") for cells in rows)
    return f"<table>\n{row(header, 'th')}\n{body}\n</table>"


def _counts(counts: Mapping[str, int]) -> str:
    return ", ".join(f"{name} {count}" for name, count in counts.items()) or "none"


def _picture(picture: Picture) -> str:
    data = base64.b64encode(picture.png).decode("ascii")
    name = html.escape(picture.file_name, quote=True)
    caption = html.escape(picture.caption)
    return (
        f'<figure><a href="{name}"><img src="data:image/png;base64,{data}" alt="{caption}">'
        f'</a><figcaption class=note>{caption} (<a href="{name}">{name}</a>)</figcaption>'
        "</figure>"
    )


def header_rows(content: ReportContent) -> list[tuple[str, str]]:
    """(item, value) rows of the header table."""
    recording = content.recording
    counts = recording.counts
    source = "recomputed from /can/raw (none recorded)" if recording.recomputed else "recorded"
    return [
        ("machine", recording.machine_id),
        ("file", recording.name + ("" if recording.complete else " (cut short: no summary)")),
        ("first frame", _time(recording.start_t_s)),
        ("last frame", _time(recording.end_t_s)),
        ("duration", f"{recording.duration_s:.2f} s"),
        ("clock steps back (or set from before 2000)", _steps(counts.clock_steps)),
        ("frames", str(counts.frames)),
        (
            "frames lost before processing",
            f"{counts.kernel_dropped + counts.rx_dropped} ({counts.kernel_dropped} by the "
            f"kernel: receive buffer full; {counts.rx_dropped} by the service's queue)",
        ),
        ("decoded frames per message", _counts(counts.messages)),
        ("bad frames by kind", _counts(counts.bad)),
        ("frames lost on the bus (by rolling counters)", str(counts.frames_lost)),
        ("leg estimates", f"{counts.estimates} ({source})"),
        ("invalid estimates by reason", _counts(counts.invalid)),
        ("legs silent (no estimate for longer than the stale time)", _silences(content)),
        ("bus state changes", str(counts.bus_events)),
        (
            "recording gaps (write errors, recorder's queue full)",
            _gaps(counts.recording_gaps, counts.recording_lost_s),
        ),
        ("simulation truth samples", str(counts.truth_samples)),
        ("cycles", str(len(content.cycles))),
    ]


def _silences(content: ReportContent) -> str:
    return (
        ", ".join(
            f"{leg} {count}x, {seconds:.2f} s{_slow(content, leg)}"
            for leg, (count, seconds) in content.silences.items()
        )
        or "none"
    )


def _slow(content: ReportContent, leg: str) -> str:
    """Why a leg sent regularly is silent at every step: its cycle time is too short."""
    step_s = content.slow_legs.get(leg)
    machine = content.recording.machine
    if step_s is None or machine is None or leg not in machine.legs:
        return ""
    config = machine.legs[leg]
    chamber = config.trigger_chamber
    return (
        f" (at every step: it is sent every {step_s * 1e3:.3g} ms, over its stale time of "
        f"{content.gap_after_s[leg] * 1e3:.3g} ms, {content.settings.stale_after_cycles:g} x "
        f"the cycle time of {chamber.message}, {config.cycle_time_s * 1e3:.3g} ms: the "
        f"median, contact and near-constant window restarted at each sample; "
        f"set {config.cycle_time_key})"
    )


def _steps(count: int) -> str:
    return f"{count} (the times before each joined to the times after)" if count else "0"


def _gaps(count: int, lost_s: float) -> str:
    return f"{count} ({lost_s:.1f} s not recorded)" if count else "0"


def metrics_rows(content: ReportContent) -> list[list[str]]:
    time = content.time
    return [
        [
            row.cycle.label,
            row.leg,
            _number(row.metrics.peak_pressure_Pa, 1e3),
            _number(time.at(row.metrics.peak_t_s), digits=2),
            _number(row.metrics.near_constant_pressure_Pa, 1e3),
            _number(time.at(row.metrics.near_constant_t_s), digits=2),
            _number(row.metrics.time_above_limit_s, digits=2),
            str(row.metrics.samples),
        ]
        for row in content.metrics
    ]


def deviation_rows(content: ReportContent) -> list[list[str]]:
    """Per leg: stance and swing sample counts, the stance statistics and the verdict on
    them, the swing deviations' 95 % and maximum."""
    rows = []
    for leg, stats in content.deviations.items():
        swing = content.swing_deviations[leg]
        within = stats.abs50_N <= PAPER_ABS50_N and stats.abs95_N <= PAPER_ABS95_N
        rows.append(
            [
                leg,
                str(stats.samples),
                str(swing.samples),
                _number(stats.median_N, 1e3, 3),
                _number(stats.mean_N, 1e3, 3),
                _number(stats.abs50_N, 1e3, 3),
                _number(stats.abs95_N, 1e3, 3),
                _number(stats.max_abs_N, 1e3, 3),
                _number(stats.mean_true_N, 1e3, 1),
                ("yes" if within else "no") if stats.samples else "n/a",
                _number(stats.published_abs95_N, 1e3, 3),
                _number(swing.abs95_N, 1e3, 3),
                _number(swing.max_abs_N, 1e3, 3),
            ]
        )
    return rows


def cycle_rows(content: ReportContent) -> list[list[str]]:
    """Per cycle: its start (wall clock), and its length on the wall and in the machine's
    own time (they differ when the cycle was played slower or faster)."""
    time = content.time
    return [
        [
            c.label,
            _time(c.start_s),
            _number(c.duration_s, digits=2),
            _number(time.before(c.end_s) - time.at(c.start_s), digits=2),
        ]
        for c in content.cycles
    ]


def render_page(content: ReportContent, pictures: Mapping[str, Picture]) -> str:
    """The HTML page; ``pictures`` by role: ``pressure``, ``force``, ``cycles`` and, with
    truth, ``comparison`` and ``deviation``."""
    recording = content.recording
    settings = content.settings
    state = recording.state_signals
    times = (
        f"Times in s of the machine's time in cycle ({state.message}), as in the paper's "
        "figures; the wall clock is in the header."
        if content.time.in_cycle
        else f"Times in s since the first frame (no {state.message} recorded)."
    )
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(recording.machine_id)}: {html.escape(recording.name)}</title>",
        f"<style>{STYLE}</style></head><body>",
        f"<h1>Test run report: {html.escape(recording.machine_id)}, "
        f"{html.escape(recording.name)}</h1>",
        _table(("item", "value"), header_rows(content), text_columns=2),
        "<h2>Contact pressure and ground force per foot</h2>",
        f"<p class=note>Filtered estimates (eq. 4 through the {_live_filter(settings)}; "
        "pressure = force / foot area) as recorded; invalid samples and missing frames "
        "are gaps. A foot the estimator sees off the ground has no soil pressure: drawn "
        "at 0 kPa (the force picture keeps the cylinder-derived force). Shaded: movement phases"
        + (
            "; cycles laid over one another. "
            if content.time.in_cycle
            else "; dotted vertical lines: cycle starts. "
        )
        + f"{times}</p>",
    ]
    parts += [_picture(pictures[role]) for role in ("pressure", "force") if role in pictures]
    parts += [
        "<h2>Soil pressure per cycle</h2>",
        f"<p class=note>Cycles from {state.message} ({state.cycle_count}); without it the whole "
        f"recording is one. Near-constant: the highest mean over a sliding "
        f"{settings.near_constant_window_s:g} s window (needs a cycle of at least that "
        f"long); time above the limit of {settings.pressure_limit_Pa / 1e3:g} kPa. "
        f"{times}</p>",
        _table(
            ("cycle", "start", "wall duration / s", "cycle duration / s"),
            cycle_rows(content),
            text_columns=2,
        ),
        _table(
            (
                "cycle",
                "leg",
                "peak / kPa",
                "at / s",
                "near-constant / kPa",
                "window end / s",
                "above limit / s",
                "valid samples",
            ),
            metrics_rows(content),
            text_columns=2,
        ),
    ]
    if "cycles" in pictures:
        parts.append(_picture(pictures["cycles"]))
    parts.append("<h2>Calculated vs. simulated ground force</h2>")
    if content.deviations:
        parts += [
            "<p class=note>Each valid estimate matched to the simulation truth sample "
            "nearest in time (within half a sample period, the truth's or the leg's, whichever "
            "is shorter); deviation = calculated - "
            "true force. Calculated: eq. (4) with the median centred on the frame, like the "
            "paper's offline filter (the running median "
            f"{(settings.median_window - 1) // 2} samples later). The paper (section 3.4) "
            f"finds, for the legs on the ground, 50 % within ±{PAPER_ABS50_N / 1e3:g} kN and "
            f"95 % within ±{PAPER_ABS95_N / 1e3:g} kN. So the statistics and the verdict are "
            "over the <b>stance</b> samples, where the true force is above the contact "
            f"threshold of {settings.contact_on_N / 1e3:g} kN; the <b>swing</b> samples (leg "
            "lifted: its cylinder carries the leg's own inertia and friction, which eq. (4) "
            "does not model) are counted and shown apart. 'live': the same for the values "
            f"as published live by the configured filter ({_live_filter(settings)}).</p>",
            _table(
                (
                    "leg",
                    "stance samples",
                    "swing samples",
                    "median / kN",
                    "mean / kN",
                    "50 % |dev| <= kN",
                    "95 % |dev| <= kN",
                    "max |dev| / kN",
                    "mean true force / kN",
                    "within paper bounds (stance)",
                    f"95 % |dev| live ({settings.filter}) <= kN",
                    "swing: 95 % |dev| <= kN",
                    "swing: max |dev| / kN",
                ),
                deviation_rows(content),
            ),
        ]
        parts += [_picture(pictures[r]) for r in ("comparison", "deviation") if r in pictures]
    parts += [f"<p class=note>{html.escape(note)}</p>" for note in [truth_note(content)] if note]
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def truth_note(content: ReportContent) -> str:
    """What the comparison leaves out: the truth altogether, or legs of the recording it
    does not name (truth recorded with another machine config, say); '' when nothing.

    A truth that names none of the recording's legs was told "No simulation truth in
    this recording", under a header counting its samples."""
    truth = content.recording.truth
    legs = list(content.recording.legs)
    if not len(truth):
        return "No simulation truth (/sim/truth) in this recording."
    if not content.comparisons:
        return (
            f"The simulation truth (/sim/truth, {len(truth)} samples) is of the legs "
            f"{', '.join(truth.force_true_N) or 'none'}, none of them a leg of this "
            f"recording ({', '.join(legs) or 'none'}): nothing to compare (truth of "
            "another machine config?)."
        )
    missing = [leg for leg in legs if leg not in content.comparisons]
    return f"No simulation truth for {', '.join(missing)}: not compared." if missing else ""


def _live_filter(settings: EstimatorSettings) -> str:
    """The live filter in words, with its delay."""
    if settings.filter == "hampel":
        return (
            f"causal Hampel filter, window {settings.hampel_window}, k = {settings.hampel_k:g}: "
            "no delay"
        )
    return (
        f"running median of {settings.median_window}: "
        f"{(settings.median_window - 1) // 2} samples of delay"
    )
