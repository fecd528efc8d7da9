"""Calibrating the legs from the weight balance: a gain and an offset per leg.

Pure computation (numpy, scipy). Eq. (4) rests on design values (lever lengths, cylinder
angle, leg weight) and on transducers that have zero offsets. Per leg ``i`` the model is

    F_i = k_i L_i + w_i + b_i,    L_i = F_cyl,i (l_r sin a - l_z cos a) / l_b

(``L_i`` the design lever term, ``w_i = (l_gb / l_b) F_gLeg`` the leg's weight term).
At a quasi-static instant the feet in contact carry the machine's weight:
``sum over legs in contact (k_i L_i + b_i) = m g - sum w_i``. Over many such instants
with different load distributions this is a linear least-squares problem in ``k`` and
``b``, solved with bounds (``scipy.optimize.lsq_linear``) and a weak pull towards 1 and
0, which decides only what the data leave open.

**Quasi-static instants** (:func:`quasi_static`): on a regular grid of snapshots (all
legs' latest estimates, like ``<prefix>/ground``), an instant counts when, over the
window around it, every leg is valid, no foot touches down or lifts off, and no leg's
filtered force changes by more than ``max_change_N``. Then accelerations and cylinder
friction are small and the vertical balance holds.

**Identifiability**: the balance only sees sums over the feet in contact. A gain is
identified when the load distribution varied enough to separate it from the others
(the data matrix, columns scaled to unit length, has no near-null direction through
it: singular values below ``1 / max_condition`` of the largest count as null). Offsets
of feet that are always down together are identified only as their sum, and a common scale of
their gains trades against that sum: a foot in the air (it carries nothing: ``k L + w + b
= 0``) pins its offset. Parameters the data leave open keep their configured value and
are reported with the reason; the others are fitted with those held fixed.
"""

import math
from array import array
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import lsq_linear

from estimator.leg import LegEstimate

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Gains are searched within these bounds.
GAIN_BOUNDS = (0.5, 1.5)
#: Offsets are searched within +- this.
OFFSET_BOUND_N = 50e3
#: Weight of the pull towards gain 1 (N per unit of gain) and offset 0 (per N): weak
#: against the balance's residuals of some hundred newtons at each of many instants.
GAIN_PULL_N = 100.0
OFFSET_PULL = 0.01
#: Directions of the scaled data matrix with a singular value below the largest /
#: this are taken as not determined by the data.
MAX_CONDITION = 1e3
#: A parameter whose share of the undetermined directions exceeds this is not identified.
NULL_SHARE = 1e-3
#: Nor one whose standard error exceeds this: 1 % on a gain at three standard errors ...
GAIN_SE_MAX = 0.0033
#: ... and 100 N on an offset.
OFFSET_SE_MAX_N = 100.0


@dataclass(frozen=True)
class Snapshots:
    """All legs' latest estimates on a regular grid: rows are instants, columns legs."""

    legs: tuple[str, ...]
    t_s: FloatArray
    #: Filtered foot force as the estimator gave it (its calibration applied).
    force_N: FloatArray
    valid: BoolArray
    contact: BoolArray


def snapshots(
    estimates: Iterable[LegEstimate], legs: Sequence[str], period_s: float, stale_s: float
) -> Snapshots:
    """Sample a stream of leg estimates (in frame order) every ``period_s``: each leg's
    latest estimate, invalid once older than ``stale_s``.

    A silence longer than the stale time (a gap, or the clock stepped forward: set from
    1970, say) is one snapshot with every leg stale, not one every ``period_s`` across
    it (56 years of them filled the memory); a step back of the clock by more than the
    stale time starts the sampling again at the new time, every leg stale until heard
    (before, nothing was sampled until the frame times caught up).
    """
    index = {leg: i for i, leg in enumerate(legs)}
    n = len(legs)
    latest_t = np.full(n, -np.inf)
    force = np.full(n, np.nan)
    valid = np.zeros(n, dtype=bool)
    contact = np.zeros(n, dtype=bool)
    # Kept flat (8 bytes a force, 1 a flag): hours of snapshots stay a few MB.
    rows_t = array("d")
    rows_force = array("d")
    rows_flags = bytearray()  # per row: valid then contact, one byte per leg each
    next_t = None
    for estimate in estimates:
        i = index.get(estimate.leg)
        if i is None:
            continue
        t = estimate.t_s
        if next_t is None or t < next_t - period_s - stale_s:  # the first, or a step back
            latest_t[:] = -np.inf  # heard after the new time
            next_t = t
        while t >= next_t:
            fresh = next_t - latest_t <= stale_s
            rows_t.append(next_t)
            rows_force.extend(force)
            rows_flags.extend((valid & fresh).tobytes() + contact.tobytes())
            next_t += period_s
            if not fresh.any() and t - next_t > period_s:  # silent: on to the next frame
                next_t += period_s * math.floor((t - next_t) / period_s)
        latest_t[i] = t
        force[i] = estimate.force_N
        valid[i] = estimate.valid
        contact[i] = estimate.contact
    flags = np.frombuffer(bytes(rows_flags), dtype=bool).reshape(len(rows_t), 2, n)
    return Snapshots(
        legs=tuple(legs),
        t_s=np.array(rows_t),
        force_N=np.array(rows_force).reshape(len(rows_t), n),
        valid=flags[:, 0].copy(),
        contact=flags[:, 1].copy(),
    )


def quasi_static(snaps: Snapshots, window: int, max_change_N: float) -> BoolArray:
    """The instants whose ``window`` snapshots either side show every leg valid, no
    contact change and no leg's force changing by more than ``max_change_N``."""
    m = len(snaps.t_s)
    good = np.zeros(m, dtype=bool)
    for j in range(window, m - window):
        span = slice(j - window, j + window + 1)
        if not snaps.valid[span].all():
            continue
        contact = snaps.contact[span]
        if not (contact == contact[0]).all() or not contact[0].any():
            continue
        force = snaps.force_N[span]
        good[j] = bool((force.max(axis=0) - force.min(axis=0) <= max_change_N).all())
    return good


@dataclass(frozen=True)
class Calibration:
    """The fitted gains and offsets, what the data identify, and the residuals."""

    legs: tuple[str, ...]
    #: Gains and offsets to use: fitted where identified, the prior elsewhere.
    gain: FloatArray
    offset_N: FloatArray
    gain_identified: BoolArray
    offset_identified: BoolArray
    #: Rank of the data matrix (of 2 x legs) and its condition (largest / smallest kept
    #: singular value, columns scaled to unit length).
    rank: int
    condition: float
    #: One line per group of parameters the data cannot determine, saying why.
    refusals: tuple[str, ...]
    #: Weight residual (sum of the forces in contact - weight) per instant, N.
    residual_before_N: FloatArray
    residual_after_N: FloatArray
    #: Per instant and leg, the force before and after calibration (NaN in the air).
    force_before_N: FloatArray
    force_after_N: FloatArray


def fit_calibration(
    lever_N: FloatArray,
    contact: BoolArray,
    weight_term_N: FloatArray,
    weight_N: float,
    legs: Sequence[str],
    prior_gain: FloatArray | None = None,
    prior_offset_N: FloatArray | None = None,
) -> Calibration:
    """Fit ``k`` and ``b`` to the balance at the given instants.

    ``lever_N`` (instants x legs): the design lever term ``L_i``; ``contact``: the feet
    down; ``weight_term_N`` (legs): ``w_i``; ``prior_gain``/``prior_offset_N``: the
    calibration the recording was made with (the "before", and what a parameter the
    data cannot determine keeps; 1 and 0 by default). Two kinds of equations: per
    instant the balance of the feet down, and per foot in the air ``k L + w + b = 0``
    (it carries nothing).
    """
    n = lever_N.shape[1]
    gain0 = np.ones(n) if prior_gain is None else np.asarray(prior_gain, dtype=np.float64)
    offset0 = (
        np.zeros(n) if prior_offset_N is None else np.asarray(prior_offset_N, dtype=np.float64)
    )
    down = contact.astype(np.float64)
    balance = np.hstack([np.where(contact, lever_N, 0.0), down])
    air_rows, air_cols = np.nonzero(~contact)
    air = np.zeros((air_rows.size, 2 * n))
    air[np.arange(air_rows.size), air_cols] = lever_N[air_rows, air_cols]
    air[np.arange(air_rows.size), n + air_cols] = 1.0
    data = np.vstack([balance, air])
    target = np.r_[weight_N - down @ weight_term_N, -weight_term_N[air_cols]]

    pull = np.diag(np.r_[np.full(n, GAIN_PULL_N), np.full(n, OFFSET_PULL)])
    solution = lsq_linear(
        np.vstack([data, pull]),
        np.r_[target, np.full(n, GAIN_PULL_N), np.zeros(n)],
        bounds=(
            np.r_[np.full(n, GAIN_BOUNDS[0]), np.full(n, -OFFSET_BOUND_N)],
            np.r_[np.full(n, GAIN_BOUNDS[1]), np.full(n, OFFSET_BOUND_N)],
        ),
    )
    fitted = solution.x
    identified, determined, rank, condition = _identifiable(data, target - data @ fitted)
    # A parameter the data determine, held by its bound: the balance asks for more than a
    # calibration may correct, and the others are fitted around the wrong value. Nothing
    # is identified; the refusal names it (the residual it leaves made every parameter
    # look loose). (One in an undetermined direction may drift to a bound: no matter.)
    at_bound = (solution.active_mask != 0) & determined
    if at_bound.any():
        identified[:] = False
    # What the data leave open (or determine too loosely) keeps its prior value.
    x = np.where(identified, fitted, np.r_[gain0, offset0])
    gain, offset = x[:n], x[n:]

    def forces(k: FloatArray, b: FloatArray) -> FloatArray:
        return np.where(contact, k * lever_N + weight_term_N + b, np.nan)

    before, after = forces(gain0, offset0), forces(gain, offset)
    return Calibration(
        legs=tuple(legs),
        gain=gain,
        offset_N=offset,
        gain_identified=identified[:n],
        offset_identified=identified[n:],
        rank=rank,
        condition=condition,
        refusals=_bound_refusals(legs, fitted, at_bound)
        or _refusals(legs, identified[:n], identified[n:], np.asarray(contact.any(axis=0))),
        residual_before_N=np.nansum(before, axis=1) - weight_N,
        residual_after_N=np.nansum(after, axis=1) - weight_N,
        force_before_N=before,
        force_after_N=after,
    )


def _identifiable(
    data: FloatArray, residual_N: FloatArray
) -> tuple[BoolArray, BoolArray, int, float]:
    """Which parameters the data identify, which they determine (the first test alone),
    the rank and the condition.

    Two tests: the parameter takes no part in a near-null direction of the data matrix
    (columns scaled to unit length; singular values below the largest / ``MAX_CONDITION``),
    and its standard error, from the residual scatter, is below ``GAIN_SE_MAX`` or
    ``OFFSET_SE_MAX_N`` (a direction that is determined only through small terms, e.g.
    the legs' weight, is determined only loosely).
    """
    rows, columns = data.shape
    norms = np.linalg.norm(data, axis=0)
    used = norms > 0
    identified = np.zeros(columns, dtype=bool)
    determined = np.zeros(columns, dtype=bool)
    if not used.any():
        return identified, determined, 0, float("inf")
    scaled = data[:, used] / norms[used]
    _, singular, vt = np.linalg.svd(scaled, full_matrices=False)
    rank = int((singular >= singular[0] / MAX_CONDITION).sum())
    # A parameter's share of the undetermined directions: those of a small singular
    # value and those no equation reaches (fewer equations than parameters), i.e. all
    # but the determined ones (the directions together are orthonormal).
    share = 1.0 - (vt[:rank] ** 2).sum(axis=0)
    if rows > rank:
        # Covariance of the scaled parameters within the determined directions.
        sigma_N = float(np.sqrt((residual_N**2).sum() / (rows - rank)))
        covariance = (vt[:rank].T / singular[:rank] ** 2) @ vt[:rank]
        standard_error = sigma_N * np.sqrt(np.diag(covariance)) / norms[used]
    else:  # no equation to spare: the fit is exact whatever the noise, its scatter unknown
        standard_error = np.full(scaled.shape[1], np.inf)
    limit = np.r_[np.full(columns // 2, GAIN_SE_MAX), np.full(columns // 2, OFFSET_SE_MAX_N)]
    determined[used] = share <= NULL_SHARE
    identified[used] = determined[used] & (standard_error <= limit[used])
    return identified, determined, rank, float(singular[0] / singular[rank - 1])


def _bound_refusals(
    legs: Sequence[str], fitted: FloatArray, at_bound: BoolArray
) -> tuple[str, ...]:
    """One line per kind of parameter held by its bound (none: the fit is free)."""
    n = len(legs)
    lines = []
    for key, kind, (low, high), unit in (
        ("force_gain", slice(0, n), GAIN_BOUNDS, ""),
        ("force_offset_N", slice(n, 2 * n), (-OFFSET_BOUND_N, OFFSET_BOUND_N), " N"),
    ):
        held = [
            f"{leg} at {value:g}"
            for leg, value, bound in zip(legs, fitted[kind], at_bound[kind], strict=True)
            if bound
        ]
        if held:
            lines.append(
                f"{key} of {', '.join(held)} stopped at the fit's bound ({low:g}..{high:g}{unit}): "
                "the weight balance asks for more than a calibration corrects; check that "
                "leg's geometry, transducers and units in the config (nothing is identified "
                "while a parameter is held there)"
            )
    return tuple(lines)


def _refusals(
    legs: Sequence[str], gain_ok: BoolArray, offset_ok: BoolArray, carried: BoolArray
) -> tuple[str, ...]:
    lines = []
    idle = [leg for leg, c in zip(legs, carried, strict=True) if not c]
    if idle:
        lines.append(f"{', '.join(idle)}: never carried load: gain not identifiable")
    gains = [leg for leg, ok, c in zip(legs, gain_ok, carried, strict=True) if c and not ok]
    if gains and len(gains) == len(legs) - len(idle):
        lines.append(
            "gains are not identifiable: the load distribution never changed enough, or "
            "their common scale trades against the offsets (no foot in the air at a steady "
            "instant)"
        )
    elif gains:
        lines.append(
            f"force_gain of {', '.join(gains)} not identifiable: the load distribution did "
            "not separate them, or their common scale trades against their offsets (no "
            "instant with them in the air)"
        )
    offsets = [leg for leg, ok in zip(legs, offset_ok, strict=True) if not ok]
    if offsets:
        lines.append(
            f"force_offset_N of {', '.join(offsets)} not identifiable from these instants: "
            "seen only in sums over feet down together, or trading against the gains"
        )
    return tuple(lines)
