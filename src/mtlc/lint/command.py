"""The `mtlc lint` command: argument parsing and the exit code (the only place lint prints).

Exit codes: 0 clean, 1 findings at or above the failing severity, 2 usage or internal error,
130 interrupted (Ctrl-C).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from mtlc.diagnostics import Severity
from mtlc.diagnostics.render import report_internal_error, use_color
from mtlc.executor import add_jobs, parse_jobs
from mtlc.frontend import add_motion_budget
from mtlc.lint.config import ConfigError, LintConfig, codes_of, load_config
from mtlc.lint.engine import lint_paths
from mtlc.lint.manikins import ManikinError, parse_selection
from mtlc.lint.output import FORMATS, RENDERERS, render_text
from mtlc.output import write_outputs
from mtlc.semantics.modules import probe

EXIT_OK, EXIT_FINDINGS, EXIT_USAGE = 0, 1, 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report Ctrl-C


def add_lint_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    p = subparsers.add_parser(
        "lint",
        help="check task files and their motion for a population of manikins (for CI)",
        description="Everything `mtlc check` reports, plus motion rules, for each manikin.",
    )
    configure_parser(p)
    return p


def configure_parser(p: argparse.ArgumentParser) -> None:
    p.add_argument("paths", nargs="+", type=Path, metavar="PATH", help=".mtask files or folders")
    p.add_argument(
        "-I",
        dest="include",
        action="append",
        type=Path,
        default=[],
        metavar="DIR",
        help="also look for used modules in DIR",
    )
    add_motion_budget(p)
    p.add_argument(
        "--manikins",
        metavar="WHICH",
        default=None,
        help="'extremes' (default: gb10000_1988:female:5 and :male:95), 'all' (the 14 "
        "GB 10000-88 manikins) or POP:SEX:PCT[,POP:SEX:PCT...]",
    )
    add_jobs(p)
    p.add_argument(
        "--select",
        metavar="CODES",
        default=None,
        help="only these codes, rule names or prefixes, comma-separated (e.g. MT06,MT0501)",
    )
    p.add_argument(
        "--ignore",
        metavar="CODES",
        default=None,
        help="leave out these codes, rule names or prefixes, comma-separated",
    )
    p.add_argument("--format", choices=FORMATS, default="text", help="output format")
    p.add_argument(
        "--fail-on",
        choices=[s.value for s in Severity],
        default=None,
        help="lowest severity that makes the exit code 1 (default: warning)",
    )
    p.add_argument(
        "--exit-zero",
        action="store_true",
        help="exit 0 even when there are findings (usage errors still exit 2)",
    )
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE",
        help="a pyproject.toml or mtlc.toml (default: the nearest one upwards)",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        metavar="FILE",
        help="write the report to FILE instead of standard output",
    )


def run_lint_command(args: argparse.Namespace) -> int:
    try:
        config = with_selection(load_config(Path.cwd(), args.config), args.select, args.ignore)
        manikins = parse_selection(args.manikins or config.manikins)
        jobs = parse_jobs(args.jobs)
    except (ConfigError, ManikinError, ValueError) as exc:
        sys.stderr.write(f"mtlc lint: {exc}\n")
        return EXIT_USAGE
    missing = [p for p in args.paths if not probe(p, Path.exists)]
    if missing:
        sys.stderr.write(f"mtlc lint: no such file or folder: {', '.join(map(str, missing))}\n")
        return EXIT_USAGE
    try:
        return _lint(args, config, manikins, jobs)
    except KeyboardInterrupt:  # the workers are stopped by the executor
        sys.stderr.write("mtlc lint: interrupted\n")
        return EXIT_INTERRUPTED
    except Exception as exc:  # a bug: one line and exit 2, never a bare traceback
        report_internal_error("lint", exc)
        return EXIT_USAGE


def with_selection(config: LintConfig, select: str | None, ignore: str | None) -> LintConfig:
    """The command line's --select / --ignore over the configuration's."""
    chosen = set(config.select)
    if select:
        chosen = codes_of([w for w in select.split(",") if w.strip()], "--select", None)
    if ignore:
        chosen -= codes_of([w for w in ignore.split(",") if w.strip()], "--ignore", None)
    return dataclasses.replace(config, select=frozenset(chosen))


def _lint(args: argparse.Namespace, config: LintConfig, manikins: tuple, jobs: int) -> int:  # type: ignore[type-arg]
    result = lint_paths(
        list(args.paths),
        config,
        manikins=manikins,
        include_dirs=tuple(args.include),
        motion_budget=args.motion_budget,
        jobs=jobs,
    )
    root = Path.cwd()
    to_file = args.output is not None
    if args.format == "text":
        text = render_text(result, root, color=not to_file and use_color(sys.stdout))
    else:
        text = RENDERERS[args.format](result, root)
    if to_file:
        failed = write_outputs({args.output: text}, "mtlc lint")
        if failed is not None:
            return failed
    else:
        sys.stdout.write(text)
    fail_on = Severity(args.fail_on) if args.fail_on else config.fail_on
    if args.exit_zero or not result.failing(fail_on):
        return EXIT_OK
    return EXIT_FINDINGS


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="mtlc lint", description=__doc__)
    configure_parser(parser)
    return run_lint_command(parser.parse_args(argv))
