"""Judging the results against the targets, and the markdown table for the README."""

from typing import Any

TARGET_P99_MS = 2.0
TARGET_RATIO = 5.0
#: Systems in the order of the table, with their labels.
LABELS = {
    "pipeline": "service pipeline",
    "pipeline_tuned": "service pipeline, earlier defaults (1 MiB chunks, 5 ms switch interval)",
    "baseline": "naive baseline",
}


def targets_met(pipeline: dict[str, Any], ratio: float, rate_hz: float) -> dict[str, bool]:
    """The issue's targets: keeps up with ``rate_hz`` (throughput at least that, the paced
    rate held, every estimate delivered and recorded, nothing dropped or bad), p99 under
    2 ms while paced, and at least 5x the baseline's frames/s."""
    paced = pipeline["paced"]
    counters = pipeline["counters"]
    complete = (
        paced["leg_estimates_received"] == paced["leg_estimates_expected"]
        and pipeline["throughput"]["leg_estimates_received"]
        == pipeline["throughput"]["leg_estimates_expected"]
        and not any(counters.get("dropped", {}).values())
        and not counters.get("bad")
        and recorded_everything(pipeline)
    )
    p99_ms = paced["latency_ms"]["p99"]
    return {
        "keeps_up_with_saturated_bus": pipeline["throughput"]["frames_per_s"] >= rate_hz
        and paced["frames_per_s"] >= 0.98 * rate_hz
        and complete,
        "p99_latency_under_2ms_at_rate": p99_ms is not None and p99_ms < TARGET_P99_MS,
        "at_least_5x_baseline": ratio >= TARGET_RATIO,
    }


def recorded_everything(pipeline: dict[str, Any]) -> bool:
    """Every frame offered is in the recording's ``/can/raw`` batches, and every estimate."""
    offered, recording = pipeline["offered"], pipeline["recording"]
    return (
        recording["raw_frames"] == offered["frames"]
        and recording["messages"].get("leg") == offered["leg_frames"]
    )


def _ms(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def markdown_table(results: dict[str, Any]) -> str:
    """One row per system and mode, the ratio and targets, then the machine line."""
    setup = results["setup"]
    rate = setup["rate_hz"]
    lines = [
        "| system | mode | frames/s | latency median (ms) | p99 (ms) | p99.9 (ms) | max (ms) "
        "| p99 from due time (ms) | estimates received | CPU (us/frame) |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for system, label in LABELS.items():
        if system not in results:
            continue
        for mode in ("throughput", "paced"):
            r = results[system][mode]
            latency = r["latency_ms"]
            due = r.get("latency_from_due_ms", {}).get("p99")
            mode_label = "as fast as taken" if mode == "throughput" else f"paced {rate:,.0f}/s"
            lines.append(
                f"| {label} | {mode_label} | {r['frames_per_s']:,.0f} "
                f"| {_ms(latency['median'])} | {_ms(latency['p99'])} | {_ms(latency['p99_9'])} "
                f"| {_ms(latency['max'])} | {_ms(due)} "
                f"| {r['leg_estimates_received']:,}/{r['leg_estimates_expected']:,} "
                f"| {r['cpu_us_per_frame']['total']:.0f} |"
            )
    machine = results["machine"]
    pinned = (
        f"process pinned to CPU {setup['pinned_cpu']}, latency probe on CPU {setup['probe_cpu']}"
        if setup["pinned_cpu"] is not None
        else "not pinned"
    )
    lines += [""]
    for suffix, label in (("", "as deployed"), ("_tuned", "earlier defaults")):
        if f"targets{suffix}" not in results:
            continue
        verdicts = ", ".join(
            f"{name.replace('_', ' ')}: {'yes' if met else 'NO'}"
            for name, met in results[f"targets{suffix}"].items()
        )
        lines.append(
            f"Service pipeline, {label}: {results[f'ratio_frames_per_s{suffix}']:.2f}x the "
            f"baseline's frames/s; targets: {verdicts}."
        )
    lines += [
        "",
        f"Machine: {machine['cpu']}, {machine['cores']} cores, Python {machine['python']}, "
        f"Linux {machine['kernel']}; {machine['date'][:10]}; {pinned}; "
        f"frames fed through the {setup['feed_description']}.",
    ]
    return "\n".join(lines)
