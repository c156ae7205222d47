"""The report's tables as rows of text, shared by the terminal, HTML and CSV outputs so that
the three always say the same thing. Units are converted here, once: mm, s, %."""

from __future__ import annotations

from dataclasses import dataclass

from mtlc.lint.manikins import SWEEP_POPULATION
from mtlc.lint.rules.visibility import HIDDEN_SHARE
from mtlc.report.access import AccessRow, access_rows, groups, populations
from mtlc.report.analysis import FAILED, ManikinResult, Report, TaskResult
from mtlc.report.maintenance import CATEGORIES
from mtlc.report.population import Share
from mtlc.semantics.timeline import ManikinSpec
from mtlc.semantics.types import TMU_SECONDS

REACHED, SHORT, UNKNOWN = "✓", "✗", "–"
SEX_WORDS = {"female": "women", "male": "men"}


@dataclass(frozen=True)
class Table:
    title: str
    header: tuple[str, ...]
    rows: list[tuple[str, ...]]
    note: str = ""
    # per row and column: "ok", "bad" or "" (how HTML and the terminal colour the cell)
    marks: list[tuple[str, ...]] | None = None


def short_label(spec: ManikinSpec, many_populations: bool) -> str:
    """F5, M95 (with the population in front when the report mixes populations)."""
    s = f"{spec.sex[0].upper()}{spec.percentile}"
    return (
        f"{spec.population} {s}" if many_populations or spec.population != SWEEP_POPULATION else s
    )


def percent(share: Share) -> str:
    if share.exact:
        return f"{share.low * 100:.1f} %"
    return f"{share.low * 100:.1f}–{share.high * 100:.1f} %"


def ratio_text(ratio: dict[str, float]) -> str:
    return ":".join(f"{ratio[s]:g}" for s in ratio)


def task_heading(task: TaskResult) -> str:
    title = f" — {task.title}" if task.title else ""
    return f"task {task.task}{title} ({task.file}:{task.line})"


def manikin_table(task: TaskResult) -> Table:
    header = ("manikin", "stature", "compiled", "sites reached", "shortfall", "worst RULA",
              "where", "MTM-1 time")  # fmt: skip
    rows, marks = [], []
    for m in task.manikins:
        rows.append(
            (
                m.label,
                f"{m.stature * 1000:.0f} mm",
                m.method,
                _reached_count(task, m),
                _shortfalls(task, m),
                _rula(m),
                _rula_where(m),
                "—" if m.time is None else f"{m.time:.2f} s",
            )
        )
        bad = "bad" if m.method == FAILED or any(m.reached(g) is False for g in task.goals) else ""
        marks.append(("", "", "", bad, bad, _rula_mark(m), "", ""))
    note = (
        "compiled: full = every motion pass for this manikin; failed = its compile stopped (the "
        "reason is printed). The MTM-1 time is this manikin's: a walk's steps take the time of "
        "its body's gait (the split below is the task's own manikin's)."
    )
    return Table("Manikins", header, rows, note, marks)


def _reached_count(task: TaskResult, m: ManikinResult) -> str:
    if m.method == FAILED:
        return f"failed: {m.error}"
    n = sum(1 for g in task.goals if m.reached(g))
    return f"{n}/{len(task.goals)}"


def _shortfalls(task: TaskResult, m: ManikinResult) -> str:
    short = [
        f"{g.site} ({g.hand}, line {g.line}) {m.distance[g] * 1000:.0f} mm"
        for g in task.goals
        if m.reached(g) is False
    ]
    return "; ".join(short) or ("" if m.method == FAILED else "none")


def _rula(m: ManikinResult) -> str:
    if m.rula is None:
        return UNKNOWN
    return f"{m.rula.score} (action level {m.rula.action_level})"


def _rula_mark(m: ManikinResult) -> str:
    if m.rula is None:
        return ""
    return "bad" if m.rula.score >= 5 else "ok" if m.rula.score <= 2 else ""


def _rula_where(m: ManikinResult) -> str:
    r = m.rula
    if r is None:
        return ""
    return f"{r.time:.2f} s, line {r.line}, {r.side} side, {r.where}"


def time_table(task: TaskResult) -> Table:
    split = task.time
    rows = []
    for name in CATEGORIES:
        s = split.seconds[name]
        if s > 0:
            share = s / split.total * 100 if split.total > 0 else 0.0
            rows.append((name, f"{s:.2f} s", f"{s / TMU_SECONDS:.0f}", f"{share:.1f} %"))
    rows.append(("total", f"{split.total:.2f} s", f"{split.total_tmu:.0f}", "100.0 %"))
    note = (
        "Predicted from MTM-1 (and the durations the task states); each moment goes to the "
        "activity of the step the task line calls (MIL-HDBK-472 elemental activities, "
        "docs/report.md), parallel steps share their time."
    )
    return Table("Predicted time (MIL-HDBK-472 split)", ("activity", "time", "TMU", "share"),
                 rows, note)  # fmt: skip


def access_table(task: TaskResult, ratio: dict[str, float]) -> Table:
    many = len(populations(task)) > 1
    share_cols = [f"{p + ' ' if many else ''}{SEX_WORDS[s]}" for p, s in groups(task)]
    both_cols = [
        f"{p + ' ' if many else ''}combined {ratio_text(ratio)}" for p in populations(task)
    ]
    header = ("site", "hand", "line", *(short_label(m.spec, many) for m in task.manikins),
              *share_cols, *both_cols)  # fmt: skip
    rows, marks = [], []
    for row in access_rows(task, ratio):
        cells = [_cell(ok, short) for ok, short in zip(row.reached, row.shortfall, strict=True)]
        marks.append(("", "", "", *(_mark(ok) for ok in row.reached), *([""] * (len(share_cols)
                      + len(both_cols)))))  # fmt: skip
        rows.append(
            (
                *_goal_cells(row),
                *cells,
                *(_share_cell(row.shares[k], row.bands[k]) for k in groups(task)),
                *(percent(row.combined[p]) for p in populations(task)),
            )
        )
    sexes = " and ".join(ratio)
    note = (
        f"{REACHED} reached (within 1 mm); {SHORT} N: the hand stays N mm short; {UNKNOWN} not "
        "measured. A manikin at percentile p stands for its sex from halfway to the percentile "
        "below to halfway to the one above (docs/accessibility.md); a range means some "
        f"percentiles were not measured. Combined: {sexes} weighted {ratio_text(ratio)}."
    )
    return Table("Accessibility across the population", header, rows, note, marks)


def _share_cell(share: Share, band: str) -> str:
    """The share, and which percentiles reach when that is not all or none of them."""
    return percent(share) if band in ("all", "none") else f"{percent(share)} ({band})"


def _goal_cells(row: AccessRow) -> tuple[str, str, str]:
    g = row.goal
    if g is None:
        return ("every site", "", "")
    return (g.site, g.hand, str(g.line))


def _cell(ok: bool | None, short: float | None) -> str:
    if ok is None:
        return UNKNOWN
    if ok:
        return REACHED
    return SHORT if short is None else f"{SHORT} {short * 1000:.0f}"


def _mark(ok: bool | None) -> str:
    return "" if ok is None else "ok" if ok else "bad"


def prototype_table(task: TaskResult) -> Table | None:
    """With equipment geometry: per goal and manikin, the share of the site the eyes see
    (MT0611) and the tightest opening on the way (MT0610); None without geometry."""
    if not any(m.seen or m.opening for m in task.manikins):
        return None
    many = len(populations(task)) > 1
    header = ("site", "hand", "line", *(short_label(m.spec, many) for m in task.manikins))
    rows, marks = [], []
    for g in task.goals:
        cells, cell_marks = [], []
        for m in task.manikins:
            seen, opening = m.seen.get(g), m.opening.get(g)
            text = UNKNOWN if seen is None else f"{seen * 100:.0f} %"
            bad = seen is not None and seen < HIDDEN_SHARE
            if opening is not None:
                free, need, part = opening
                what = "" if part.endswith("hand") else f" {part.split(' ', 1)[-1]}"
                text += f" · {free * 1000:.0f}/{need * 1000:.0f}{what}"
                bad = bad or free < need
            cells.append(text)
            cell_marks.append("bad" if bad else "")
        rows.append((g.site, g.hand, str(g.line), *cells))
        marks.append(("", "", "", *cell_marks))
    note = (
        "With the scene's models and solids. N %: the least share of the site the eyes see at "
        f"the reach's end and over the work (lint MT0611 under {HIDDEN_SHARE * 100:.0f} %). "
        "· A/B: an opening on the way lets a hand A mm broad through where the manikin's is B "
        "mm (a forearm or tool: named; lint MT0610 when A < B; docs/collision.md, access "
        "openings)."
    )
    return Table("Sight and access openings on the prototype", header, rows, note, marks)


def task_tables(task: TaskResult, report: Report) -> list[Table]:
    tables = [manikin_table(task), time_table(task)]
    if task.goals:
        tables.append(access_table(task, report.ratio))
        prototype = prototype_table(task)
        if prototype is not None:
            tables.append(prototype)
    return tables
