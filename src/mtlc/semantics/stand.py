"""Where a walk to a site stops: on a floor spot, or in front of a site that is worked at.

A walk goes to its site's ground point. For a spot on the floor (`panel_front`, `bench_front`)
that is where the body stands. For a site above the floor it is not: `carry(both, bench_top,
14 kg)` (walk to the destination, then move the part onto it) stood the manikin on the bench's
footprint and put the battery 75 cm up inside its own belly, and `carry(left, s0)` to a site
1 m up put the hand 118 mm into the trunk (MT0514), kept there for the 20 m walk that followed.
A person stops in front of what they work at.

So a walk to a site higher than ``FLOOR_SPOT`` above the ground stops ``WORK_DISTANCE`` from
the site's ground point, horizontally: along the site's normal where the normal faces sideways
(at least ``SIDEWAYS`` of it horizontal: a panel's bolt, a rack's latch), else on the side the
walk comes from (a bench top's upward normal says nothing of where to stand), and arrives
facing the site unless the walk names its own `facing`.

``WORK_DISTANCE`` is a modelling choice taken from the stand spots of this project's own
examples and procedures, which put the pelvis 0.20-0.56 m from the work (0.30 at the avionics
trolley, 0.40 at the fuel filter, 0.50-0.52 at the rack and the access panel): 0.35 m is
inside the forward reach of the 1st-percentile woman at bench height and keeps the forearms
clear of the trunk. It does not depend on the manikin: the front end times walks, and the
same task must take the same time for every manikin it is linted with.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

FLOOR_SPOT = 0.05  # m: a site this high above the ground or lower is a place to stand on
HEIGHT_EPS = 1e-9  # m: heights within this of FLOOR_SPOT are at it (a difference's rounding)
WORK_DISTANCE = 0.35  # m, horizontally from the site's ground point to the pelvis
SIDEWAYS = 0.5  # a normal at least this horizontal (30 deg from vertical) says where "in front" is

Point = Sequence[float]


def stand_point(
    site: Point, normal: Point | None, start: Point, ground: float
) -> tuple[tuple[float, float, float], bool]:
    """Where a walk from ``start`` to the site at ``site`` (its ``normal``) stops, at the
    ground's height, and whether that is in front of the site rather than on it."""
    x, z = float(site[0]), float(site[2])
    # a site stated FLOOR_SPOT above the ground is a floor spot whatever the subtraction's last
    # bit (1.05 - 1.0 is 0.05000000000000004: hypothesis found it)
    if float(site[1]) - ground <= FLOOR_SPOT + HEIGHT_EPS:
        return (x, ground, z), False
    if normal is not None and math.hypot(normal[0], normal[2]) >= SIDEWAYS * math.hypot(*normal):
        dx, dz = float(normal[0]), float(normal[2])
    else:
        dx, dz = float(start[0]) - x, float(start[2]) - z
        if math.hypot(dx, dz) < 1e-9:
            dx, dz = 0.0, -1.0  # from under the site: behind it, facing +Z as at the start
    norm = math.hypot(dx, dz)
    return (x + WORK_DISTANCE * dx / norm, ground, z + WORK_DISTANCE * dz / norm), True
