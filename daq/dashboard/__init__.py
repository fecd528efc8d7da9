"""``portal-daq dashboard``: a live web page of the service, from Zenoh.

:mod:`~daq.dashboard.history` keeps the last minute of contact pressures (pure),
:mod:`~daq.dashboard.api` builds the JSON documents (pure),
:mod:`~daq.dashboard.server` subscribes and serves them with the page
(``static/index.html``, no external assets), :mod:`~daq.dashboard.cli` parses
the command line.
"""
