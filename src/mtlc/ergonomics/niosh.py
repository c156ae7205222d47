"""The revised NIOSH lifting equation: recommended weight limit and lifting index of a lift.

Waters, Putz-Anderson & Garg, *Applications Manual for the Revised NIOSH Lifting Equation*, NIOSH
Pub. 94-110 (1994; rev. 2021). RWL = LC · HM · VM · DM · AM · FM · CM with LC = 23 kg; the
multipliers' formulas, valid ranges and out-of-range values follow the manual (summarised in
``docs/lifting.md``); FM and CM are the manual's tables 5 and 7, the package's cited copy in
``mtlc/ergonomics/data/niosh_fm.csv`` and ``niosh_cm.csv`` (sources in each file's first line).

The API takes SI units (m, rad, kg) like the rest of mtlc; the equation is stated in cm and
degrees, so the conversion happens once, in :func:`multipliers`. The lift's geometry (H, V, A)
is measured on the posed manikin by :func:`lift_geometry`.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from functools import cache
from importlib.resources import files

import numpy as np
from numpy.typing import NDArray

from mtlc.body.kinematics import Pose, site_positions
from mtlc.body.skeleton import Skeleton

FloatArray = NDArray[np.float64]

LOAD_CONSTANT_KG = 23.0
V_COLUMN_SPLIT_CM = 75.0  # the tables' columns: hands below / at or above 75 cm (30 in)
DURATIONS = ("1h", "2h", "8h")  # work up to 1 h, over 1 and up to 2 h, over 2 and up to 8 h
COUPLINGS = ("good", "fair", "poor")
# A one-off lift: the table's first row (F <= 0.2 lifts/min), short duration; "fair" coupling
# unless stated: a part with handles that is not a designed container (docs/lifting.md).
DEFAULT_FREQUENCY = 0.2
DEFAULT_DURATION = "1h"
DEFAULT_COUPLING = "fair"
HANDS = ("r_hand", "l_hand")


@dataclass(frozen=True)
class LiftPoint:
    """The geometry at one end of a lift (SI): H and V in m, A in rad."""

    horizontal: float  # from the midpoint between the ankles to the hands' midpoint, on the floor
    vertical: float  # the hands' midpoint above the floor
    asymmetry: float  # of the hands' position from the mid-sagittal plane


@dataclass(frozen=True)
class Multipliers:
    hm: float
    vm: float
    dm: float
    am: float
    fm: float
    cm: float

    @property
    def rwl(self) -> float:
        """The recommended weight limit (kg)."""
        return LOAD_CONSTANT_KG * self.hm * self.vm * self.dm * self.am * self.fm * self.cm


@dataclass(frozen=True)
class LiftAssessment:
    """One end of a lift scored: its multipliers, RWL (kg) and lifting index."""

    end: str  # "origin" or "destination"
    point: LiftPoint
    multipliers: Multipliers
    load: float  # kg

    @property
    def rwl(self) -> float:
        return self.multipliers.rwl

    @property
    def lifting_index(self) -> float:
        """LI = load / RWL; infinite when a multiplier is 0 (the lift is outside the model)."""
        return self.load / self.rwl if self.rwl > 0 else math.inf


# -- the multipliers (cm, degrees, lifts/min, as the manual states them) ------------------------


def horizontal_multiplier(h_cm: float) -> float:
    """HM = 25/H; H below 25 cm counts as 25 (HM 1), beyond 63 cm HM is 0."""
    if h_cm > 63.0:
        return 0.0
    return 25.0 / max(h_cm, 25.0)


def vertical_multiplier(v_cm: float) -> float:
    """VM = 1 − 0.003·|V − 75|, for V from 0 to 175 cm, else 0."""
    if not 0.0 <= v_cm <= 175.0:
        return 0.0
    return 1.0 - 0.003 * abs(v_cm - 75.0)


def distance_multiplier(d_cm: float) -> float:
    """DM = 0.82 + 4.5/D; travel below 25 cm counts as 25 (DM 1), beyond 175 cm DM is 0."""
    if d_cm > 175.0:
        return 0.0
    return min(0.82 + 4.5 / max(d_cm, 25.0), 1.0)


def asymmetry_multiplier(a_deg: float) -> float:
    """AM = 1 − 0.0032·A, for A from 0 to 135°, else 0."""
    if not 0.0 <= a_deg <= 135.0:
        return 0.0
    return 1.0 - 0.0032 * a_deg


def _data_rows(name: str) -> list[dict[str, str]]:
    text = (files("mtlc.ergonomics") / "data" / name).read_text(encoding="utf-8")
    lines = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    return list(csv.DictReader(lines))


@cache
def _frequency_table() -> dict[tuple[str, str], tuple[tuple[float, ...], tuple[float, ...]]]:
    """(duration, column) -> (lifts/min, FM) rows from 0.2 to 15 lifts/min."""
    out: dict[tuple[str, str], tuple[list[float], list[float]]] = {}
    for row in _data_rows("niosh_fm.csv"):
        freq = row["lifts_per_min"]
        if freq.startswith(">"):
            continue  # beyond 15 lifts/min: FM 0, handled by the caller
        duration = row["duration"].removeprefix("<=")
        f = float(freq.removeprefix("<="))
        for column in ("v_lt_75", "v_ge_75"):
            xs, ys = out.setdefault((duration, column), ([], []))
            xs.append(f)
            ys.append(float(row[column]))
    return {k: (tuple(xs), tuple(ys)) for k, (xs, ys) in out.items()}


def frequency_multiplier(lifts_per_min: float, duration: str, v_origin_cm: float) -> float:
    """FM from table 5: below 0.2 lifts/min the 0.2 row, over 15 zero, linear between rows;
    the column by the hands' height at the lift's origin."""
    if duration not in DURATIONS:
        raise ValueError(f"duration is one of {', '.join(DURATIONS)}, not {duration!r}")
    if lifts_per_min > 15.0:
        return 0.0
    column = "v_ge_75" if v_origin_cm >= V_COLUMN_SPLIT_CM else "v_lt_75"
    xs, ys = _frequency_table()[(duration, column)]
    return float(np.interp(max(lifts_per_min, xs[0]), xs, ys))


@cache
def _coupling_table() -> dict[str, tuple[float, float]]:
    return {
        r["coupling"]: (float(r["v_lt_75"]), float(r["v_ge_75"]))
        for r in _data_rows("niosh_cm.csv")
    }


def coupling_multiplier(coupling: str, v_cm: float) -> float:
    """CM from table 7, by the hands' height at the end being scored."""
    if coupling not in COUPLINGS:
        raise ValueError(f"coupling is one of {', '.join(COUPLINGS)}, not {coupling!r}")
    below, above = _coupling_table()[coupling]
    return above if v_cm >= V_COLUMN_SPLIT_CM else below


# -- one lift -----------------------------------------------------------------------------------


def multipliers(
    point: LiftPoint,
    travel: float,
    v_origin: float,
    frequency: float = DEFAULT_FREQUENCY,
    duration: str = DEFAULT_DURATION,
    coupling: str = DEFAULT_COUPLING,
) -> Multipliers:
    """The six multipliers at one end of a lift; ``travel`` and ``v_origin`` in m."""
    h_cm, v_cm = point.horizontal * 100.0, point.vertical * 100.0
    return Multipliers(
        hm=horizontal_multiplier(h_cm),
        vm=vertical_multiplier(v_cm),
        dm=distance_multiplier(abs(travel) * 100.0),
        am=asymmetry_multiplier(math.degrees(point.asymmetry)),
        fm=frequency_multiplier(frequency, duration, v_origin * 100.0),
        cm=coupling_multiplier(coupling, v_cm),
    )


def assess_lift(
    load: float,
    origin: LiftPoint,
    destination: LiftPoint,
    frequency: float = DEFAULT_FREQUENCY,
    duration: str = DEFAULT_DURATION,
    coupling: str = DEFAULT_COUPLING,
) -> tuple[LiftAssessment, LiftAssessment]:
    """The lift scored at its origin and at its destination (the manual scores both when the
    load must be placed with control, as a maintenance part is); the worse is the larger LI."""
    travel = destination.vertical - origin.vertical
    return tuple(  # type: ignore[return-value]
        LiftAssessment(
            end,
            point,
            multipliers(point, travel, origin.vertical, frequency, duration, coupling),
            load,
        )
        for end, point in (("origin", origin), ("destination", destination))
    )


def worst(assessments: tuple[LiftAssessment, ...]) -> LiftAssessment:
    """The end with the largest lifting index (the origin on a tie)."""
    return max(assessments, key=lambda a: a.lifting_index)


# -- geometry on the manikin --------------------------------------------------------------------


def lift_geometry(skel: Skeleton, pose: Pose, ground: float) -> list[LiftPoint]:
    """H, V and A of every posed frame, as the manual measures them.

    The hands' point is the midpoint of the two grip sites; the feet's point the midpoint
    between the ankle joints (the inner ankles' midpoint of a symmetric stance); the
    mid-sagittal line points where the feet point (the mean heel-to-toe direction: the manual's
    neutral body position is set by the feet, not by a twisted trunk).
    """
    hands = site_positions(skel, pose, list(HANDS)).mean(axis=-2)
    ankles = pose.p[..., [skel.joint_index("r_ankle"), skel.joint_index("l_ankle")], :]
    heels = site_positions(skel, pose, ["r_heel", "l_heel"])
    toes = site_positions(skel, pose, ["r_toe", "l_toe"])
    return lift_points(hands, ankles.mean(axis=-2), (toes - heels).mean(axis=-2), ground)


def lift_points(
    hands: FloatArray, ankles: FloatArray, forward: FloatArray, ground: float
) -> list[LiftPoint]:
    """H, V, A from points (..., 3) in world metres, +Y up. H: on the floor, from ``ankles`` to
    ``hands``; V: ``hands`` above ``ground``; A: on the floor, between the line to the hands
    and ``forward`` (0 when the hands are over the ankles)."""
    to_hands = _on_floor(np.asarray(hands, dtype=float) - np.asarray(ankles, dtype=float))
    horizontal = np.atleast_1d(np.linalg.norm(to_hands, axis=-1))
    asymmetry = np.atleast_1d(_floor_angle(to_hands, _on_floor(np.asarray(forward, float))))
    vertical = np.atleast_1d(np.asarray(hands, dtype=float)[..., 1] - ground)
    return [
        LiftPoint(float(h), float(v), float(a))
        for h, v, a in zip(horizontal, vertical, asymmetry, strict=True)
    ]


def _on_floor(v: FloatArray) -> FloatArray:
    out = np.array(v, dtype=float)
    out[..., 1] = 0.0
    return out


def _floor_angle(a: FloatArray, b: FloatArray) -> FloatArray:
    """Unsigned angle (rad) between floor vectors; 0 where either is too short to have one."""
    na = np.linalg.norm(a, axis=-1)
    nb = np.linalg.norm(b, axis=-1)
    cosine = np.einsum("...i,...i->...", a, b) / np.maximum(na * nb, 1e-12)
    angle = np.arccos(np.clip(cosine, -1.0, 1.0))
    return np.where((na < 1e-6) | (nb < 1e-6), 0.0, angle)
