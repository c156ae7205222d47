"""The report in the terminal: rich tables, coloured only on a terminal (NO_COLOR honoured).

Every text goes through ``terminal_safe``: a title holding ESC, NUL or U+202E is shown with
those characters as escapes (``\\u{1b}``), never sent to the terminal to obey."""

from __future__ import annotations

import io

from rich.console import Console
from rich.table import Table as RichTable
from rich.text import Text

from mtlc.diagnostics.render import terminal_safe
from mtlc.report.analysis import Report
from mtlc.report.tables import Table, ratio_text, task_heading, task_tables

WIDTH = 200  # not a terminal: wide enough for the 14-manikin table without wrapping
STYLES = {"ok": "green", "bad": "bold red", "": ""}


def render_terminal(report: Report, *, color: bool, width: int | None = None) -> str:
    """Every task's tables as text (with ANSI colours when ``color``); ``width`` None: the
    terminal's width, or 200 columns when the output is not a terminal."""
    out = io.StringIO()
    console = Console(
        file=out,
        width=width or (None if color else WIDTH),
        color_system="standard" if color else None,
        force_terminal=color,
        no_color=not color,
        highlight=False,
        emoji=False,
        soft_wrap=False,
    )
    sweep = "every manikin compiled in full"
    console.print(
        Text(
            f"mtlc report: {len(report.selection)} manikins ({sweep}); "
            f"sex ratio male:female {ratio_text(report.ratio)}"
        )
    )
    for task in report.tasks:
        console.print()
        console.print(Text(terminal_safe(task_heading(task)), style="bold"))
        for table in task_tables(task, report):
            console.print(_rich(table))
            console.print(Text(terminal_safe(table.note), style="dim"))
    return out.getvalue()


def _rich(table: Table) -> RichTable:
    t = RichTable(title=Text(terminal_safe(table.title)), title_justify="left", show_lines=False)
    for k, name in enumerate(table.header):
        t.add_column(Text(terminal_safe(name)), overflow="fold", no_wrap=k == 0)
    marks = table.marks or [("",) * len(table.header)] * len(table.rows)
    for row, mark in zip(table.rows, marks, strict=True):
        t.add_row(
            *(Text(terminal_safe(c), style=STYLES[m]) for c, m in zip(row, mark, strict=True))
        )
    return t
