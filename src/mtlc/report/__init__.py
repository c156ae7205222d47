"""`mtlc report`: reach, RULA and predicted time of a task for a population of manikins, in the
terminal, as CSV and as a self-contained HTML page (docs/report.md, docs/accessibility.md)."""

from mtlc.report.analysis import Report, TaskResult, analyse_task
from mtlc.report.command import add_report_parser, run_report_command

__all__ = ["Report", "TaskResult", "add_report_parser", "analyse_task", "run_report_command"]
