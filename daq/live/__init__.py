"""What the live viewers (``portal-daq monitor``, ``portal-daq dashboard``) share.

The service's latest values as received over Zenoh (:mod:`daq.live.state`, pure),
the viewer's settings drawn from the service config (:mod:`daq.live.viewer`), the
Zenoh session of a viewer (:mod:`daq.live.session`), the subscription feeding
the state (:mod:`daq.live.feed`) and the command-line plumbing both commands
share (:mod:`daq.live.command`). Importing this package opens nothing.
"""
