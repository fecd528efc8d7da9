"""portal-daq service: SocketCAN in, decoded and checked frames, estimates out.

Importing this package opens nothing; the service's resources are built in
``daq.__main__`` and passed in.
"""
