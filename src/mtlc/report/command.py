"""The `mtlc report` command (wired into `mtlc` by the CLI, and `python -m mtlc.report`).

Exit codes as everywhere in mtlc: 0 the report was made (unreachable sites are its content,
not an error), 1 errors in the input, 2 a usage or internal error, 130 interrupted (Ctrl-C).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from mtlc.diagnostics.render import render_text, report_internal_error, terminal_safe, use_color
from mtlc.executor import add_jobs, parse_jobs
from mtlc.frontend import FrontendOptions, add_motion_budget, run_frontend
from mtlc.lint.manikins import ManikinError, parse_selection
from mtlc.output import write_outputs
from mtlc.report.analysis import Report, analyse_tasks
from mtlc.report.csvout import render_csv
from mtlc.report.html import render_html
from mtlc.report.terminal import render_terminal
from mtlc.semantics.modules import probe

EXIT_OK, EXIT_ERRORS, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130
DEFAULT_MANIKINS = "all"


class ReportUsageError(ValueError):
    """A bad option value (exit 2)."""


def add_report_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add `report` to the CLI's subparsers."""
    p = subparsers.add_parser(
        "report",
        help="reach, RULA and predicted time for a population of manikins (terminal, HTML, CSV)",
        description="For each task: every site reached or the shortfall, the worst RULA score, "
        "the MTM-1 time split into MIL-HDBK-472 activities, per manikin, and the share of the "
        "population that reaches each site.",
    )
    configure_parser(p)
    return p


def configure_parser(p: argparse.ArgumentParser) -> None:
    p.add_argument("files", nargs="+", type=Path, metavar="FILE", help=".mtask files")
    p.add_argument("-I", dest="include", action="append", type=Path, default=[], metavar="DIR",
                   help="also look for used modules in DIR")  # fmt: skip
    add_motion_budget(p)
    p.add_argument("--task", metavar="NAME", help="only this task (default: every task)")
    p.add_argument("--manikins", metavar="WHICH", default=DEFAULT_MANIKINS,
                   help="'all' (default: the 14 GB 10000-88 manikins), 'extremes' or "
                   "POP:SEX:PCT[,POP:SEX:PCT...], as for mtlc lint")  # fmt: skip
    p.add_argument("--full", action="store_true",
                   help="kept for old scripts: every manikin is always compiled in full")  # fmt: skip
    add_jobs(p)
    p.add_argument("--sex-ratio", metavar="MALE:FEMALE", default="1:1",
                   help="weights of men and women in the combined share (default 1:1)")  # fmt: skip
    p.add_argument("-o", "--output", type=Path, metavar="HTML",
                   help="also write the report as a self-contained HTML page")  # fmt: skip
    p.add_argument("--csv", type=Path, metavar="CSV",
                   help="also write the report as one CSV table (columns: docs/report.md)")  # fmt: skip


def parse_ratio(text: str) -> dict[str, float]:
    """'MALE:FEMALE' weights, e.g. '1:1' or '3:1'; not negative, not both zero."""
    parts = text.split(":")
    try:
        male, female = (float(p) for p in parts)
    except ValueError:
        raise ReportUsageError(f"--sex-ratio {text!r}: expected MALE:FEMALE, e.g. 1:1") from None
    if not (male >= 0 and female >= 0 and male + female > 0) or float("inf") in (male, female):
        raise ReportUsageError(f"--sex-ratio {text!r}: weights are finite, >= 0, not both 0")
    return {"male": male, "female": female}


def run_report_command(args: argparse.Namespace) -> int:
    try:
        selection = parse_selection(args.manikins)
        ratio = parse_ratio(args.sex_ratio)
        jobs = parse_jobs(args.jobs)
    except (ManikinError, ReportUsageError, ValueError) as exc:
        sys.stderr.write(f"mtlc report: {exc}\n")
        return EXIT_USAGE
    missing = [str(p) for p in args.files if not probe(p, Path.is_file)]
    if missing:
        sys.stderr.write(f"mtlc report: no such file: {terminal_safe(', '.join(missing))}\n")
        return EXIT_USAGE
    try:
        return _report(args, selection, ratio, jobs)
    except KeyboardInterrupt:  # the workers are stopped by the executor
        sys.stderr.write("mtlc report: interrupted\n")
        return EXIT_INTERRUPTED
    except Exception as exc:  # a bug: one line and exit 2, never a bare traceback
        report_internal_error("report", exc)
        return EXIT_USAGE


def _report(args: argparse.Namespace, selection: tuple, ratio: dict[str, float], jobs: int) -> int:  # type: ignore[type-arg]
    options = FrontendOptions(include_dirs=tuple(args.include), motion_budget=args.motion_budget)
    program = run_frontend(list(args.files), options)
    if program.diagnostics:
        text = render_text(program.diagnostics, program.sources, color=use_color(sys.stderr))
        sys.stderr.write(text)
    if program.sink.has_errors:
        return EXIT_ERRORS
    timelines = [t for t in program.timelines if args.task in (None, t.task)]
    if not timelines:
        sys.stderr.write(f"mtlc report: no task named {args.task!r}\n" if args.task else
                         "mtlc report: no task in the files\n")  # fmt: skip
        return EXIT_USAGE
    tasks = analyse_tasks(timelines, selection, jobs=jobs, motion_budget=args.motion_budget)
    report = Report(tasks, selection, ratio)
    files: dict[Path, str | bytes] = {}
    if args.output is not None:
        files[args.output] = render_html(report)
    if args.csv is not None:
        files[args.csv] = render_csv(report)
    failed = write_outputs(files, "mtlc report")
    if failed is not None:
        return failed
    sys.stdout.write(render_terminal(report, color=use_color(sys.stdout)))
    for path in files:
        sys.stderr.write(f"wrote {terminal_safe(str(path))}\n")
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="mtlc report", description=__doc__)
    configure_parser(parser)
    return run_report_command(parser.parse_args(argv))
