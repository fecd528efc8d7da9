"""``portal-daq monitor``: a live terminal view of the service, from Zenoh.

:mod:`~daq.monitor.view` renders the latest values to lines (pure),
:mod:`~daq.monitor.app` is the thin curses / plain-text loop,
:mod:`~daq.monitor.cli` parses the command line.
"""
