"""Streaming estimator of one leg: sample in, filtered foot force and soil pressure out."""

from dataclasses import dataclass, replace

from estimator.contact import ContactDetector
from estimator.equations import contact_pressure_Pa, foot_force_N
from estimator.filters import make_filter
from estimator.geometry import LegGeometry
from estimator.metrics import SoilMetrics, SoilMetricsTracker
from estimator.records import fast_init
from estimator.settings import EstimatorSettings
from estimator.validity import STALE, sample_faults

NAN = float("nan")


@fast_init
@dataclass(frozen=True, slots=True)
class LegSample:
    """One leg sample: both chamber pressures and what the CAN layer's checks found."""

    #: Frame time (kernel time stamp), Unix seconds.
    t_s: float
    #: Piston (cap-end) chamber pressure.
    p_piston_Pa: float
    #: Rod (annulus) chamber pressure.
    p_rod_Pa: float
    #: Why the frames behind this sample cannot be trusted (``crc``, ``counter``,
    #: ``counter_repeat``, ``status_<value>``, ``rod_stale``, ...); empty when fine.
    faults: tuple[str, ...] = ()


@fast_init
@dataclass(frozen=True, slots=True)
class LegEstimate:
    """The estimator's answer for one leg after a sample (or a staleness check)."""

    leg: str
    #: Frame time of the sample this estimate is based on (NaN before any frame).
    t_s: float
    #: The configured filter (running median or Hampel) over the valid raw forces (eq. 4);
    #: NaN before the first valid sample.
    force_N: float
    #: Eq. (4) on this sample alone, unfiltered (NaN before any frame).
    force_raw_N: float
    #: Eq. (5) on the filtered force.
    pressure_Pa: float
    p_piston_Pa: float
    p_rod_Pa: float
    #: Foot on the ground (hysteresis on the filtered force).
    contact: bool
    valid: bool
    #: Why the estimate is invalid (see :mod:`estimator.validity`); empty when valid.
    reasons: tuple[str, ...]


class LegEstimator:
    """Feeds one leg's samples through eq. (4), validity, filter, contact and metrics.

    Invalid samples are reported (with their raw force) but never enter the
    filter, the contact detector or the soil metrics. When a sample's frame time is
    more than :attr:`stale_after_s` past the leg's last valid sample (an outage),
    the filter and the contact state restart: what they hold describes the foot as
    it was. A frame time that steps back (the wall clock stepped) restarts nothing,
    unless the bus time (:class:`~estimator.machine.BusClock`, given by the machine)
    since that sample is longer: the leg was silent across the step while the other
    messages went on.
    """

    def __init__(
        self, name: str, leg: LegGeometry, settings: EstimatorSettings, cycle_time_s: float
    ) -> None:
        if not cycle_time_s > 0:
            raise ValueError(f"cycle_time_s of leg {name} must be > 0, got {cycle_time_s!r}")
        self.name = name
        self.leg = leg
        self.settings = settings
        #: No frame for longer than this makes the leg's estimate stale.
        self.stale_after_s = settings.stale_after_s(cycle_time_s)
        self._filter = make_filter(settings)
        #: Frame time of the last valid sample (NaN: none since the start or a restart).
        self._last_valid_t_s = NAN
        #: ... and the bus time at it.
        self._last_valid_bus_s = NAN
        #: Samples that came more than :attr:`stale_after_s` past the last valid one, so
        #: the filter and the contact restarted (outages; at most samples of a leg sent
        #: less often than its cycle time says: :meth:`MachineEstimator.restarting_legs`).
        self.restarts = 0
        self._contact = ContactDetector(settings.contact_on_N, settings.contact_off_N)
        self._metrics = SoilMetricsTracker(
            settings.pressure_limit_Pa, settings.near_constant_window_s, self.stale_after_s
        )
        self._last = LegEstimate(
            leg=name,
            t_s=NAN,
            force_N=NAN,
            force_raw_N=NAN,
            pressure_Pa=NAN,
            p_piston_Pa=NAN,
            p_rod_Pa=NAN,
            contact=False,
            valid=False,
            reasons=(STALE,),
        )

    @property
    def metrics(self) -> SoilMetrics:
        return self._metrics.metrics

    @property
    def valid_samples(self) -> int:
        """Valid samples since the start (or :meth:`reset_metrics`)."""
        return self._metrics.samples

    def reset_metrics(self) -> None:
        """Restart the soil metrics (e.g. per movement cycle); the filter keeps its state."""
        self._metrics.reset()

    def update(self, sample: LegSample, bus_s: float = NAN) -> LegEstimate:
        """Take one received sample and return the leg's new estimate; ``bus_s`` is the
        bus time at it (NaN: none, a step back of the frame time restarts nothing)."""
        t_s, p_piston_Pa, p_rod_Pa = sample.t_s, sample.p_piston_Pa, sample.p_rod_Pa
        reasons = sample_faults(
            p_piston_Pa=p_piston_Pa,
            p_rod_Pa=p_rod_Pa,
            faults=sample.faults,
            settings=self.settings,
        )
        force_raw_N = foot_force_N(p_piston_Pa, p_rod_Pa, self.leg)
        gap_s = t_s - self._last_valid_t_s
        if gap_s > self.stale_after_s or (  # after an outage, or one across a step back
            gap_s < 0.0 and bus_s - self._last_valid_bus_s > self.stale_after_s
        ):
            self.restarts += 1
            self._filter.clear()
            self._contact.reset()
            self._last_valid_t_s = NAN
        if reasons:
            force_N = self._filter.value
            contact = self._contact.in_contact
        else:
            force_N = self._filter.push(force_raw_N)
            contact = self._contact.update(force_N)
            self._last_valid_t_s = t_s
            self._last_valid_bus_s = bus_s
        pressure_Pa = contact_pressure_Pa(force_N, self.leg.A_foot_m2)
        if not reasons:
            self._metrics.add(t_s, pressure_Pa)
        # Positional, in the fields' order (leg, t_s, force_N, force_raw_N, pressure_Pa,
        # p_piston_Pa, p_rod_Pa, contact, valid, reasons): keywords cost more per frame.
        self._last = estimate = LegEstimate(
            self.name,
            t_s,
            force_N,
            force_raw_N,
            pressure_Pa,
            p_piston_Pa,
            p_rod_Pa,
            contact,
            not reasons,
            reasons,
        )
        return estimate

    def snapshot(self, age_s: float) -> LegEstimate:
        """The latest estimate, judged ``age_s`` after its sample: stale if that is longer
        than :attr:`stale_after_s`. The age is measured by the caller on a clock that
        does not step (see :mod:`estimator.machine`)."""
        last = self._last
        if STALE in last.reasons or not age_s > self.stale_after_s:
            return last
        return replace(last, valid=False, reasons=(*last.reasons, STALE))
