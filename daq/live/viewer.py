"""What a viewer takes from the service's configuration file: prefix, legs, limits, staleness.

A viewer reads the same TOML file as the service (``--config``), so that the
key prefix, the leg names and the pressure limit cannot disagree with it.

>>> from daq.service_config import load_service_config
>>> viewer = viewer_config(load_service_config("deploy/portal-daq.example.toml"))  # doctest: +SKIP
>>> viewer.prefix, viewer.pressure_limit_Pa, viewer.status_stale_s  # doctest: +SKIP
('portal/pam-proto-1', 200000.0, 3.0)
"""

from dataclasses import dataclass

from daq.service_config import ServiceConfig

#: Status is stale after this many status periods without one.
STATUS_STALE_PERIODS = 3.0
#: Ground is stale after this many ground periods without one ...
GROUND_STALE_PERIODS = 5.0
#: ... but never sooner than this.
GROUND_STALE_MIN_S = 1.0


@dataclass(frozen=True, slots=True)
class ViewerConfig:
    """The settings of a live viewer, all from the service configuration."""

    #: The config file, for messages.
    source: str
    machine_id: str
    #: The service's Zenoh key prefix, e.g. ``portal/pam-proto-1``.
    prefix: str
    #: Leg names in the order of the config file.
    legs: tuple[str, ...]
    #: ``[estimator] pressure_limit_Pa``: the soil-pressure limit drawn on every bar and plot.
    pressure_limit_Pa: float
    #: No ``<prefix>/status`` for this long: shown as stale.
    status_stale_s: float
    #: No ``<prefix>/ground`` for this long: shown as stale.
    ground_stale_s: float
    #: ``[stability] warning_margin_m``: a smaller margin is a warning; None when the
    #: machine config has no ``[stability]`` table.
    warning_margin_m: float | None = None

    def key(self, suffix: str) -> str:
        return f"{self.prefix}/{suffix}"


def viewer_config(config: ServiceConfig) -> ViewerConfig:
    publish = config.publish
    stability = config.machine.stability
    return ViewerConfig(
        source=config.source,
        machine_id=config.machine.machine_id,
        prefix=config.zenoh.key_prefix,
        legs=tuple(config.machine.legs),
        pressure_limit_Pa=config.machine.estimator.pressure_limit_Pa,
        status_stale_s=STATUS_STALE_PERIODS * publish.status_period_s,
        ground_stale_s=max(GROUND_STALE_MIN_S, GROUND_STALE_PERIODS / publish.ground_rate_hz),
        warning_margin_m=stability.warning_margin_m if stability is not None else None,
    )
