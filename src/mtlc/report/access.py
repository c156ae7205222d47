"""The accessibility table: for every contact goal, who reaches it and what share of the
population that is (mtlc.report.population), per sex and combined."""

from __future__ import annotations

from dataclasses import dataclass

from mtlc.report.analysis import GoalRef, ManikinResult, TaskResult
from mtlc.report.population import Share, band, combined_share, sex_share


@dataclass(frozen=True)
class AccessRow:
    goal: GoalRef | None  # None: the row for every site of the task at once
    reached: tuple[bool | None, ...]  # per manikin of the task, None: not measured
    shortfall: tuple[float | None, ...]  # m, for those not reached
    shares: dict[tuple[str, str], Share]  # (population, sex) -> share of that sex
    bands: dict[tuple[str, str], str]
    combined: dict[str, Share]  # population -> share of both sexes by the stated ratio


def groups(task: TaskResult) -> list[tuple[str, str]]:
    """The (population, sex) pairs the selection measures, in selection order."""
    return list(dict.fromkeys((m.spec.population, m.spec.sex) for m in task.manikins))


def populations(task: TaskResult) -> list[str]:
    return list(dict.fromkeys(m.spec.population for m in task.manikins))


def access_rows(task: TaskResult, ratio: dict[str, float]) -> list[AccessRow]:
    """One row per goal, then (when there are several) one for reaching every goal."""
    rows = [_row(task, g, [m.reached(g) for m in task.manikins]) for g in task.goals]
    if len(task.goals) > 1:
        every = [_all_of([m.reached(g) for g in task.goals]) for m in task.manikins]
        rows.append(_row(task, None, every))
    return [_with_combined(task, r, ratio) for r in rows]


def _all_of(values: list[bool | None]) -> bool | None:
    if any(v is False for v in values):
        return False
    return None if any(v is None for v in values) else True


def _row(task: TaskResult, goal: GoalRef | None, reached: list[bool | None]) -> AccessRow:
    shortfall = tuple(_shortfall(m, goal) for m in task.manikins)
    shares, bands = {}, {}
    for pop, sex in groups(task):
        measured = {
            m.spec.percentile: ok
            for m, ok in zip(task.manikins, reached, strict=True)
            if m.spec.population == pop and m.spec.sex == sex and ok is not None
        }
        shares[pop, sex] = sex_share(pop, measured)
        bands[pop, sex] = band(measured) if measured else "not measured"
    return AccessRow(goal, tuple(reached), shortfall, shares, bands, {})


def _shortfall(m: ManikinResult, goal: GoalRef | None) -> float | None:
    if goal is None:
        return None
    ok = m.reached(goal)
    return None if ok is None or ok else m.distance[goal]


def _with_combined(task: TaskResult, row: AccessRow, ratio: dict[str, float]) -> AccessRow:
    combined = {}
    for pop in populations(task):
        per_sex = {sex: s for (p, sex), s in row.shares.items() if p == pop}
        combined[pop] = combined_share(per_sex, ratio)
    return AccessRow(row.goal, row.reached, row.shortfall, row.shares, row.bands, combined)
