"""The project's CAN database, shipped with the package so an installed service finds it,
and the installed version that the service's and the simulator's ``--version`` print."""

from importlib import metadata
from pathlib import Path

#: The pressure-sensor and machine-state interface of the portal advancing mechanism.
DEFAULT_DBC_PATH = Path(__file__).with_name("portal_sensors.dbc")


def installed_version() -> str:
    """The installed distribution's version (``unknown`` when run from a bare source tree)."""
    try:
        return metadata.version("portal-daq")
    except metadata.PackageNotFoundError:
        return "unknown"
