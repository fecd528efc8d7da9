"""``portal-daq calibrate RECORDING... [--config FILE] [--out calibration.toml] [--channel CH]``.

A RECORDING is a service recording (MCAP files or directories: every run of the service
among them one recording) or a CAN log (with ``--config``).

Fits each leg's ``force_gain`` and ``force_offset_N`` to the weight balance at the
quasi-static instants of the recordings (:mod:`estimator.calibration`), writes the TOML
snippet (``--out``, default ``calibration.toml``) and, beside it, ``calibration.html``
with ``calibration.png``; prints the figures and every refusal, one line each. Exit
status: 0 written; 2 bad configuration; 1 a recording that cannot be read, or nothing
identifiable (one line saying why, nothing written).
"""

import argparse
import logging
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from daq.output_file import refuse_an_input
from daq.subcommand import PROG, Subcommand, add_channel_option, fail
from dbc.errors import ConfigError, DbcError, PortalDaqError


def calibrate_main(args: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog=f"{PROG} calibrate",
        description="Per-leg gain and offset of eq. (4) from the weight balance at the "
        "quasi-static instants of recordings; writes a TOML snippet for the machine config "
        "and a page with the weight residual before and after.",
    )
    parser.add_argument(
        "recording",
        type=Path,
        nargs="+",
        help="service recordings (.mcap files or directories: each run one recording, a "
        "rotated run's files chained), or CAN logs (candump .log, .asc, .blf, ...: need "
        "--config)",
    )
    parser.add_argument("--config", type=Path, help="machine config (default: the embedded one)")
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("calibration.toml"),
        help="the TOML snippet to write, its page (.html, .png) beside it [%(default)s]",
    )
    add_channel_option(parser, "calibrate from")
    options = parser.parse_args(args)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    from daq.calibrate.data import machine_for, read_instants  # numpy/scipy only here
    from daq.calibrate.output import rms_N, summary_lines, toml_snippet, write_page
    from estimator.calibration import fit_calibration

    try:
        refuse_an_input(options.out, options.recording)
        machine = machine_for(options.recording, options.config)
        instants = read_instants(options.recording, machine, options.channel)
    except (ConfigError, DbcError) as exc:
        return fail(exc, 2)
    except (PortalDaqError, OSError) as exc:
        return fail(exc, 1)
    if not len(instants.t_s):
        return fail(f"{instants.why_none()}: nothing to calibrate", 1)
    config = machine[0]
    geometry = [config.legs[leg].geometry for leg in instants.legs]
    lever = np.column_stack(
        [
            (instants.force_N[:, i] - g.calibrated_term_N) / g.force_gain
            for i, g in enumerate(geometry)
        ]
    )
    calibration = fit_calibration(
        lever,
        instants.contact,
        np.array([g.weight_term_N for g in geometry]),
        config.weight_N,
        instants.legs,
        prior_gain=np.array([g.force_gain for g in geometry]),
        prior_offset_N=np.array([g.force_offset_N for g in geometry]),
    )
    lines = summary_lines(calibration, len(instants.t_s), instants.total)
    for line in lines:
        sys.stderr.write(f"{PROG} calibrate: {line}\n")
    if not (calibration.gain_identified.any() or calibration.offset_identified.any()):
        return fail("nothing identifiable from these recordings: nothing written", 1)
    if rms_N(calibration.residual_after_N) > rms_N(calibration.residual_before_N):
        # What is identified alone, with the rest as configured, fits worse: the data
        # determine it only together with what they leave open.
        return fail(
            "the identifiable parameters alone do not improve the weight balance: nothing written",
            1,
        )
    try:
        options.out.parent.mkdir(parents=True, exist_ok=True)
        options.out.write_text(toml_snippet(calibration, lines))
        page = write_page(calibration, instants.t_s, lines, options.out.parent)
    except OSError as exc:
        return fail(f"{options.out}: cannot write it: {exc.strerror or exc}", 1)
    sys.stdout.write(f"{options.out}\n{page}\n")
    return 0


SUBCOMMAND = Subcommand(
    "calibrate", "per-leg gain and offset from recordings (weight balance)", calibrate_main
)
