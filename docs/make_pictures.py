"""Redraw the README's pictures of the simulated cycle: ``docs/cycle.png`` and
``docs/report-example.png``.

``.venv/bin/python docs/make_pictures.py`` (about a minute). The cycle plot is what
``portal-sim plot`` draws. The report example is a real report of one simulated cycle:
the model's cycle played frame by frame through the service's pipeline into a service
recording (MCAP, with the simulation truth and the machine state), as ``portal-daq run``
records it live, then ``portal-daq report``'s Figures 5 and 6, stacked. (The dashboard's
screenshot comes from its Chromium test, see the README.)
"""

import sys
import tempfile
from pathlib import Path

import numpy as np
from matplotlib import image

from daq.frames import RawFrame
from daq.mcap_file import CONFIG_ATTACHMENT, DBC_ATTACHMENT, McapFile
from daq.pipeline import Pipeline
from daq.report import ReportOptions, report
from dbc.encoding import FrameEncoder
from dbc.machine import load_machine_config
from sim_bridge.__main__ import cli as portal_sim
from sim_bridge._args import DEFAULT_CONFIG
from sim_bridge.frames import FrameBuilder
from sim_bridge.model import simulate
from sim_bridge.params import ModelParams
from sim_bridge.playout import Playout
from sim_bridge.schedule import instants, schedule
from sim_bridge.truth import truth_sample

DOCS = Path(__file__).resolve().parent
#: 2026-01-01 00:00:00 UTC: the recording's first frame.
T0_S = 1_767_225_600.0


def record_cycle(path: Path) -> None:
    """One simulated cycle through the pipeline into a service recording with truth."""
    config, database = load_machine_config(DEFAULT_CONFIG)
    result = simulate(ModelParams(leg=next(iter(config.legs.values())).geometry))
    builder = FrameBuilder(config, database)
    playout = Playout(result, builder, FrameEncoder(database, config.protection))
    pipeline = Pipeline.from_config(config, database)
    feet_m2 = {leg: config.legs[leg].geometry.A_foot_m2 for leg in config.legs}
    attachments = {
        CONFIG_ATTACHMENT: DEFAULT_CONFIG.read_bytes(),
        DBC_ATTACHMENT: config.dbc_path.read_bytes(),
    }
    with open(path, "wb") as stream, McapFile(stream, database) as mcap:
        mcap.start(attachments, T0_S)
        last_row = None
        end_ns = playout.timeline.cycle_ns
        for instant in instants(schedule(playout.cycles, end_sim_ns=end_ns)):
            t_s = round(T0_S + instant.sim_t_ns / 1e9, 6)
            position, outgoing = playout.frames(instant)
            for item in outgoing:
                frame = RawFrame(t_s, item.frame.arbitration_id, False, item.frame.data)
                mcap.write_result(pipeline.process(frame))
            if (position.cycle, position.row) != last_row:
                last_row = (position.cycle, position.row)
                mcap.write_truth(truth_sample(result, position, t_s, feet_m2).as_json())


def main() -> int:
    if portal_sim(["plot", "--out", str(DOCS / "cycle.png"), "-q"]) != 0:
        return 1
    with tempfile.TemporaryDirectory() as work:
        recording = Path(work) / "pam-proto-1_20260101T000000.000Z.mcap"
        record_cycle(recording)
        report(ReportOptions(recording, Path(work) / "report"))
        parts = [image.imread(Path(work) / "report" / name)
                 for name in ("truth_comparison.png", "truth_deviation.png")]  # fmt: skip
        image.imsave(DOCS / "report-example.png", np.vstack(parts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
