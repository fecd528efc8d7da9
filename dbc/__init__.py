"""The project's CAN database, shipped with the package so an installed service finds it."""

from pathlib import Path

#: The pressure-sensor and machine-state interface of the portal advancing mechanism.
DEFAULT_DBC_PATH = Path(__file__).with_name("portal_sensors.dbc")
