"""Stability margin: centre of pressure against the support polygon of the feet in contact.

Pure computation. The feet's plan positions (x, y in one frame, metres) come from the
machine's kinematics (:mod:`estimator.kinematics`); the forces from the estimator.

- **Centre of pressure**: the force-weighted mean of the positions of the valid feet in
  contact. With the machine at rest it is the vertical projection of its centre of
  gravity; while it accelerates, that of the resultant of weight and inertial forces.
- **Support polygon**: the convex hull of those feet (``scipy.spatial.ConvexHull``).
- **Margin**: the signed distance from the centre of pressure to the nearest edge of the
  polygon: positive inside, negative outside (then the distance to the polygon). The
  machine tips about that edge when the margin reaches zero.

Undefined (None) with fewer than three feet in contact, any invalid leg (an invalid leg
may carry load nobody sees), feet on one line, or no positive total force.
"""

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from estimator.kinematics import Point
from estimator.leg import LegEstimate


@dataclass(frozen=True, slots=True)
class Stability:
    """Where the load is against the feet that carry it."""

    #: Centre of pressure (force-weighted foot positions), m.
    cop_m: Point
    #: Signed distance from the centre of pressure to the nearest polygon edge, m;
    #: negative outside.
    margin_m: float
    #: The feet in contact, in the estimator's leg order.
    legs: tuple[str, ...]
    #: Corners of the support polygon, counter-clockwise, m.
    polygon_m: tuple[Point, ...]
    #: Every foot's plan position (in contact or not), m: for plan views.
    feet_m: Mapping[str, Point]


def support_polygon(points: Iterable[Point]) -> tuple[Point, ...] | None:
    """The convex hull's corners, counter-clockwise; None for fewer than three points
    or points on one line.

    >>> support_polygon([(0.0, 0.0), (2.0, 0.0), (1.0, 0.5), (0.0, 2.0)])
    ((0.0, 0.0), (2.0, 0.0), (0.0, 2.0))
    """
    xy = np.asarray(list(points), dtype=np.float64)
    if len(xy) < 3:
        return None
    try:
        hull = ConvexHull(xy)
    except QhullError:
        return None  # all on one line (or repeated): no area to stand on
    # In 2-D, qhull lists the vertices counter-clockwise; start at the lowest corner
    # (then leftmost), so that the same feet give the same polygon in any order.
    order = [int(i) for i in hull.vertices]
    first = min(range(len(order)), key=lambda k: (xy[order[k], 1], xy[order[k], 0]))
    order = order[first:] + order[:first]
    return tuple((float(xy[i, 0]), float(xy[i, 1])) for i in order)


def signed_margin_m(point: Point, polygon: tuple[Point, ...]) -> float:
    """Signed distance from ``point`` to the nearest edge of the convex, counter-clockwise
    ``polygon``: positive inside, negative outside.

    >>> signed_margin_m((1.0, 1.0), ((0.0, 0.0), (4.0, 0.0), (4.0, 3.0), (0.0, 3.0)))
    1.0
    >>> signed_margin_m((7.0, 7.0), ((0.0, 0.0), (4.0, 0.0), (4.0, 3.0), (0.0, 3.0)))
    -5.0
    """
    px, py = point
    inside_m = math.inf  # the smallest distance to an edge's line, inside
    outside_m = math.inf  # the smallest distance to an edge segment
    outside = False
    for (ax, ay), (bx, by) in zip(polygon, polygon[1:] + polygon[:1], strict=True):
        ex, ey = bx - ax, by - ay
        length_m = math.hypot(ex, ey)
        # Counter-clockwise: the interior lies to the left of each edge.
        left_m = (ex * (py - ay) - ey * (px - ax)) / length_m
        if left_m < 0:
            outside = True
        inside_m = min(inside_m, left_m)
        along = max(0.0, min(1.0, ((px - ax) * ex + (py - ay) * ey) / length_m**2))
        outside_m = min(outside_m, math.hypot(px - ax - along * ex, py - ay - along * ey))
    return -outside_m if outside else inside_m


def stability(estimates: Iterable[LegEstimate], feet_m: Mapping[str, Point]) -> Stability | None:
    """The centre of pressure, support polygon and margin of the valid feet in contact;
    None when undefined (see the module docstring). Legs without a position in
    ``feet_m`` are not judged."""
    legs: list[str] = []
    points: list[Point] = []
    forces_N: list[float] = []
    for estimate in estimates:
        position = feet_m.get(estimate.leg)
        if position is None:
            continue
        if not estimate.valid:
            return None
        if estimate.contact:
            legs.append(estimate.leg)
            points.append(position)
            forces_N.append(estimate.force_N)
    total_N = math.fsum(forces_N)
    if len(legs) < 3 or not total_N > 0:
        return None
    polygon = support_polygon(points)
    if polygon is None:
        return None
    cop = (
        math.fsum(f * p[0] for f, p in zip(forces_N, points, strict=True)) / total_N,
        math.fsum(f * p[1] for f, p in zip(forces_N, points, strict=True)) / total_N,
    )
    return Stability(
        cop_m=cop,
        margin_m=signed_margin_m(cop, polygon),
        legs=tuple(legs),
        polygon_m=polygon,
        feet_m=dict(feet_m),
    )
