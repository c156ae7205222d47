"""MTM-1 element times, from the tables carried in mtlc/data/time_standards.

Sources: the MTM-1 data card (reach, move, turn; inch card for R and M), as cited on the first
lines of each CSV. Times are in TMU (1 TMU = 0.036 s). Distances between the card's rows are
interpolated linearly, as the card prescribes; beyond 30 in the card's per-inch increment applies.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from functools import cache

from mtlc.resources import data_path

INCH = 0.0254
PACE_LENGTH_M = 0.75  # a normal walking pace for MTM's W-P element (per pace, not per stride)


@dataclass(frozen=True)
class DistanceTable:
    inches: tuple[float, ...]
    columns: dict[str, tuple[float, ...]]
    per_inch_over_30: dict[str, float]

    def tmu(self, column: str, distance_m: float) -> float:
        d = max(0.0, distance_m) / INCH
        xs, ys = self.inches, self.columns[column]
        if d <= xs[0]:
            return ys[0]
        if d >= xs[-1]:
            return ys[-1] + (d - xs[-1]) * self.per_inch_over_30[column]
        for i in range(1, len(xs)):
            if d <= xs[i]:
                f = (d - xs[i - 1]) / (xs[i] - xs[i - 1])
                return ys[i - 1] + f * (ys[i] - ys[i - 1])
        raise AssertionError("unreachable")


def _rows(name: str) -> list[dict[str, str]]:
    with data_path("time_standards", name).open(encoding="utf-8") as f:
        lines = [ln for ln in f if not ln.startswith("#")]
    return list(csv.DictReader(lines))


@cache
def reach_move_table() -> DistanceTable:
    rows = _rows("mtm1_reach_move.csv")
    cols = [c for c in rows[0] if c != "distance_in"]
    body = [r for r in rows if r["distance_in"] != "per_in_over_30"]
    extra = next(r for r in rows if r["distance_in"] == "per_in_over_30")
    return DistanceTable(
        inches=tuple(float(r["distance_in"]) for r in body),
        columns={c: tuple(float(r[c]) for r in body) for c in cols},
        per_inch_over_30={c: float(extra[c]) for c in cols},
    )


@cache
def turn_table() -> tuple[tuple[float, ...], dict[str, tuple[float, ...]]]:
    rows = _rows("mtm1_turn.csv")
    angles = tuple(float(r["angle_deg"]) for r in rows)
    return angles, {c: tuple(float(r[c]) for r in rows) for c in ("T-S", "T-M", "T-L")}


@cache
def other_codes() -> dict[str, float]:
    return {r["code"]: float(r["tmu"]) for r in _rows("mtm1_other.csv")}


_REACH_COLUMN = {"A": "R-A", "B": "R-B", "C": "R-CD", "D": "R-CD", "E": "R-E"}


def reach_tmu(case: str, distance_m: float) -> float:
    return reach_move_table().tmu(_REACH_COLUMN[case], distance_m)


def move_tmu(case: str, distance_m: float) -> float:
    return reach_move_table().tmu(f"M-{case}", distance_m)


def turn_tmu(angle_rad: float, load_kg: float) -> float:
    """Turn of the hand about the forearm; turns past 180° are taken as whole 180° turns plus the rest."""
    angles, cols = turn_table()
    column = "T-S" if load_kg <= 1.0 else "T-M" if load_kg <= 5.0 else "T-L"
    ys = cols[column]
    deg = abs(math.degrees(angle_rad))
    whole, rest = divmod(deg, 180.0)
    total = whole * ys[-1]
    if rest > 1e-9 or whole == 0:
        r = max(rest, angles[0])
        for i in range(1, len(angles)):
            if r <= angles[i]:
                f = (r - angles[i - 1]) / (angles[i] - angles[i - 1])
                total += ys[i - 1] + f * (ys[i] - ys[i - 1])
                break
    return total


def code_tmu(code: str) -> float:
    return other_codes()[code]


def walk_tmu(distance_m: float) -> float:
    """W-P per started pace; an infinite distance takes infinite time (which the duration's
    range check reports) instead of overflowing `ceil`."""
    if not math.isfinite(distance_m):
        return math.inf
    paces = math.ceil(max(0.0, distance_m) / PACE_LENGTH_M - 1e-9)
    return paces * code_tmu("W-P")


GRASP_CODES = {"G1C": "G1C1"}  # the card's G1C has sub-cases by size; G1C1 is the common one


def grasp_tmu(case: str) -> float:
    return code_tmu(GRASP_CODES.get(case, case))
