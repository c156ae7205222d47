"""The report as one self-contained HTML page: inline CSS, no script, no external asset.
Every text goes through ``escape``: ``html.escape`` after ``terminal_safe``, so markup is shown
as text and a control or bidi character (U+202E reverses what follows) as its escape."""

from __future__ import annotations

import html

from mtlc.diagnostics.render import terminal_safe
from mtlc.report.analysis import Report
from mtlc.report.tables import Table, ratio_text, task_heading, task_tables

CSS = """
body { font: 14px/1.45 system-ui, sans-serif; margin: 2em auto; max-width: 80em; color: #222; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 2em; } h3 { font-size: 1em; }
table { border-collapse: collapse; margin: .5em 0; }
th, td { border: 1px solid #ccc; padding: .2em .5em; text-align: left; vertical-align: top; }
th { background: #f3f3f3; }
td.ok { background: #e3f4e3; color: #135b13; }
td.bad { background: #fbe3e3; color: #8b1111; font-weight: 600; }
p.note { color: #555; font-size: .9em; max-width: 60em; }
"""


def escape(text: str) -> str:
    """Text from a task file as HTML text: markup and controls inert, visible."""
    return html.escape(terminal_safe(text))


def render_html(report: Report) -> str:
    sweep = "every manikin compiled in full"
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en">',
        '<head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{escape(_title(report))}</title>",
        f"<style>{CSS}</style></head>",
        "<body>",
        f"<h1>{escape(_title(report))}</h1>",
        f"<p>{len(report.selection)} manikins ({escape(sweep)}); sex ratio male:female "
        f"{escape(ratio_text(report.ratio))}.</p>",
    ]
    for task in report.tasks:
        parts.append(f"<h2>{escape(task_heading(task))}</h2>")
        parts.extend(_table(t) for t in task_tables(task, report))
    parts += ["</body>", "</html>", ""]
    return "\n".join(parts)


def _title(report: Report) -> str:
    names = ", ".join(t.title or t.task for t in report.tasks) or "no task"
    return f"mtlc report: {names}"


def _table(table: Table) -> str:
    marks = table.marks or [("",) * len(table.header)] * len(table.rows)
    head = "".join(f"<th>{escape(h)}</th>" for h in table.header)
    body = "\n".join(
        "<tr>" + "".join(_td(c, m) for c, m in zip(row, mark, strict=True)) + "</tr>"
        for row, mark in zip(table.rows, marks, strict=True)
    )
    return (
        f"<h3>{escape(table.title)}</h3>\n<table>\n<thead><tr>{head}</tr></thead>\n"
        f'<tbody>\n{body}\n</tbody>\n</table>\n<p class="note">{escape(table.note)}</p>'
    )


def _td(cell: str, mark: str) -> str:
    cls = f' class="{mark}"' if mark else ""
    return f"<td{cls}>{escape(cell)}</td>"
