"""The report as one flat CSV table (columns in docs/report.md): a row per measured number.

Every cell goes through ``csv_cell``: a text a spreadsheet would run as a formula gets a
leading apostrophe (OWASP's CSV-injection rule); numbers stay numbers."""

from __future__ import annotations

import csv
import io
import math

from mtlc.report.access import access_rows, groups, populations
from mtlc.report.analysis import Report, TaskResult
from mtlc.report.maintenance import CATEGORIES
from mtlc.report.population import Share
from mtlc.report.tables import ratio_text

COLUMNS = ("task", "section", "manikin", "method", "sex", "site", "hand", "line", "column",
           "metric", "value", "unit", "note")  # fmt: skip


def render_csv(report: Report) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(COLUMNS)
    for task in report.tasks:
        for row in _task_rows(task, report):
            writer.writerow([csv_cell(row.get(c, "")) for c in COLUMNS])
    return out.getvalue()


FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def csv_cell(text: str) -> str:
    """``text``, with a leading ``'`` when it starts as a formula would (= + - @ tab CR) and is
    not a finite number: `=HYPERLINK(...)` in a title is shown, not run; -0.5 stays -0.5."""
    if not text.startswith(FORMULA_START):
        return text
    try:
        if math.isfinite(float(text)):
            return text
    except ValueError:
        pass
    return "'" + text


def _task_rows(task: TaskResult, report: Report) -> list[dict[str, str]]:
    return [
        *_time_rows(task),
        *_manikin_rows(task),
        *_reach_rows(task),
        *_share_rows(task, report.ratio),
        *_prototype_rows(task),
    ]


def _prototype_rows(task: TaskResult) -> list[dict[str, str]]:
    """With equipment geometry: each goal's share seen and its tightest opening, per manikin."""
    out = []
    for g in task.goals:
        for m in task.manikins:
            base = {"task": task.task, "section": "prototype", "manikin": m.label,
                    "method": m.method, "sex": m.spec.sex, "site": g.site, "hand": g.hand,
                    "line": str(g.line), "column": str(g.column)}  # fmt: skip
            if g in m.seen:
                out.append({**base, "metric": "seen", "value": f"{m.seen[g] * 100:.0f}",
                            "unit": "%", "note": "least share of the site the eyes see"})  # fmt: skip
            if g in m.opening:
                free, need, part = m.opening[g]
                out.append({**base, "metric": "opening", "value": f"{free * 1000:.1f}",
                            "unit": "mm", "note": f"{part} needs {need * 1000:.1f} mm"})  # fmt: skip
    return out


def _time_rows(task: TaskResult) -> list[dict[str, str]]:
    rows = [{"metric": name, "value": f"{task.time.seconds[name]:.3f}"} for name in CATEGORIES]
    rows.append({"metric": "total", "value": f"{task.time.total:.3f}"})
    return [{"task": task.task, "section": "time", "unit": "s", **r} for r in rows]


def _manikin_rows(task: TaskResult) -> list[dict[str, str]]:
    out = []
    for m in task.manikins:
        base = {"task": task.task, "section": "manikin", "manikin": m.label,
                "method": m.method, "sex": m.spec.sex}  # fmt: skip
        out.append({**base, "metric": "stature", "value": f"{m.stature:.3f}", "unit": "m"})
        reached = sum(1 for g in task.goals if m.reached(g))
        out.append({**base, "metric": "sites_reached", "value": str(reached), "unit": "1",
                    "note": m.error or f"of {len(task.goals)}"})  # fmt: skip
        if m.time is not None:
            out.append({**base, "metric": "time", "value": f"{m.time:.3f}", "unit": "s"})
        if m.rula is not None:
            r = m.rula
            where = {
                "line": str(r.line),
                "column": str(r.column),
                "note": f"{r.side} side, {r.where}",
            }
            out.append(
                {**base, **where, "metric": "rula_score", "value": str(r.score), "unit": "1"}
            )
            out.append(
                {**base, **where, "metric": "rula_time", "value": f"{r.time:.3f}", "unit": "s"}
            )
    return out


def _reach_rows(task: TaskResult) -> list[dict[str, str]]:
    out = []
    for g in task.goals:
        for m in task.manikins:
            ok = m.reached(g)
            d = m.distance.get(g)
            out.append(
                {
                    "task": task.task,
                    "section": "reach",
                    "manikin": m.label,
                    "method": m.method,
                    "sex": m.spec.sex,
                    "site": g.site,
                    "hand": g.hand,
                    "line": str(g.line),
                    "column": str(g.column),
                    "metric": "distance",
                    "value": "" if d is None else f"{d * 1000:.1f}",
                    "unit": "mm",
                    "note": "not measured" if ok is None else "reached" if ok else "short",
                }
            )
    return out


def _share_rows(task: TaskResult, ratio: dict[str, float]) -> list[dict[str, str]]:
    out = []
    for row in access_rows(task, ratio):
        g = row.goal
        where = (
            {"site": "*"} if g is None
            else {"site": g.site, "hand": g.hand, "line": str(g.line), "column": str(g.column)}
        )  # fmt: skip
        for pop, sex in groups(task):
            out += _share(task.task, pop, sex, where, row.shares[pop, sex], row.bands[pop, sex])
        for pop in populations(task):
            note = f"male:female {ratio_text(ratio)}"
            out += _share(task.task, pop, "both", where, row.combined[pop], note)
    return out


def _share(
    task: str, population: str, sex: str, where: dict[str, str], share: Share, note: str
) -> list[dict[str, str]]:
    base = {"task": task, "section": "share", "manikin": population, "sex": sex, **where,
            "unit": "1", "note": note}  # fmt: skip
    return [
        {**base, "metric": "share_low", "value": f"{share.low:.4f}"},
        {**base, "metric": "share_high", "value": f"{share.high:.4f}"},
    ]
