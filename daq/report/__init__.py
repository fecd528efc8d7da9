"""Test-run reports from the service's recordings: ``portal-daq report FILE.mcap``.

Pure computation apart from plotting and file I/O:

- :mod:`~daq.report.tracks`: the recording's messages as arrays (legs, machine state,
  truth, counts); :mod:`~daq.report.cycles`: cycle split and per-cycle soil metrics;
  :mod:`~daq.report.deviation`: matching estimates to simulation truth, statistics;
  :mod:`~daq.report.content`: all of it for one recording (:func:`analyse`);
- :mod:`~daq.report.figures` (matplotlib, Agg) and :mod:`~daq.report.page` (HTML)
  draw it;
- :mod:`~daq.report.loading` reads the MCAP file, :mod:`~daq.report.output` writes
  the PNGs and the page, :mod:`~daq.report.command` is the command line.

Importing this package loads neither numpy nor matplotlib.
"""

from daq.report.command import ReportOptions, report, report_main

__all__ = ["ReportOptions", "report", "report_main"]
