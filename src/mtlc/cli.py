"""The command line: the only module that reads argv or prints.

Exit codes, for every command: 0 clean, 1 errors in the input, 2 a usage or internal error.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import os
import sys
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from mtlc import __version__
from mtlc.diagnostics import CODES, DiagnosticSink, Span
from mtlc.diagnostics.render import render_json, render_text, terminal_safe, use_color
from mtlc.output import OutputError, safe_file_name, write_outputs
from mtlc.resources import resource_dir

# Each command's modules are imported when it runs (and, for `mtlc fmt`, only fmt's parser is
# built): `mtlc fmt` needs the parser and printer, not the motion passes, numpy and scipy that
# the other commands load (start-up was 1-2 s of every `mtlc fmt`).
if TYPE_CHECKING:
    from mtlc.frontend import FrontendOptions, Program
    from mtlc.ir.model import MotionIR
    from mtlc.metrics import Metrics
    from mtlc.passes import MotionOptions
    from mtlc.semantics.timeline import ManikinSpec

EXIT_OK, EXIT_ERRORS, EXIT_USAGE = 0, 1, 2


class UsageError(Exception):
    pass


def _manikin(text: str) -> ManikinSpec:
    """`--manikin gb10000_1988:female:5`"""
    parts = text.split(":")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(
            "expected POPULATION:SEX:PERCENTILE, e.g. gb10000_1988:female:5"
        )
    pop, sex, pct = parts
    from mtlc.semantics import builtins as B
    from mtlc.semantics.timeline import ManikinSpec

    if pop not in B.POPULATIONS:
        raise argparse.ArgumentTypeError(
            f"unknown population {pop!r}; one of {', '.join(B.POPULATIONS)}"
        )
    if sex not in B.SEXES:
        raise argparse.ArgumentTypeError("sex is male or female")
    pct = pct.removeprefix("p")
    if not pct.isdigit() or int(pct) not in B.POPULATIONS[pop]:
        allowed = ", ".join(str(p) for p in B.POPULATIONS[pop])
        raise argparse.ArgumentTypeError(f"percentile must be one of {allowed}")
    return ManikinSpec(pop, sex, int(pct))


def _fps(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError("expected a number of frames per second") from None
    if not 1 <= value <= 1000:
        raise argparse.ArgumentTypeError("must be between 1 and 1000")
    return value


def _budget(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError("expected a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError("must be at least 1")
    return value


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The command line; with ``only`` (a command's name), the same with no other command: its
    arguments, help and errors are the same, and it imports only what that command's own
    options need (`mtlc explain` and `mtlc fmt` no numpy, `mtlc check` no motion passes or
    scipy: start-up was 1-2 s of every command, issue 21). ``only=""``: no command at all (for
    `mtlc --version`)."""
    parser, sub = _top_parser()
    for command, add in _SUBPARSERS:
        if only is None or only == command:
            add(sub)
    return parser


def _top_parser() -> tuple[argparse.ArgumentParser, argparse._SubParsersAction]:
    parser = argparse.ArgumentParser(
        prog="mtlc",
        description="Maintenance Task Language Compiler: maintenance procedures to virtual-human motion.",
    )
    parser.add_argument("--version", action="version", version=f"mtlc {__version__}")
    return parser, parser.add_subparsers(dest="command", metavar="COMMAND")


# Each command's one-line help, as its own parser gives it (tests/test_cli.py compares them):
# `mtlc`, `mtlc -h` and `mtlc --help` list the commands with these alone, without importing any
# command's modules (numpy, scipy and the motion passes: 0.4 s of CPU, issue 21).
COMMAND_SUMMARIES: dict[str, str] = {
    "check": "parse, resolve, type-check and expand task files",
    "compile": "compile task files into motion outputs",
    "explain": "show the documentation page of a diagnostic code",
    "lint": "check task files and their motion for a population of manikins (for CI)",
    "report": "reach, RULA and predicted time for a population of manikins (terminal, HTML, CSV)",
    "fmt": "format .mtask files canonically (keeps comments, never changes meaning)",
    "preview": "see the motion: a self-contained HTML page and/or a PNG contact sheet",
    "serve": "stream the motion to a browser; recompile on save and when a site is dragged",
}
_LISTING_WORDS = ([], ["-h"], ["--help"])  # the command lines that only list the commands


def listing_parser() -> argparse.ArgumentParser:
    """The command line as `mtlc --help` shows it: every command, none of their options."""
    parser, sub = _top_parser()
    for command, summary in COMMAND_SUMMARIES.items():
        sub.add_parser(command, help=summary)
    return parser


def _frontend_options(p: argparse.ArgumentParser) -> None:
    from mtlc.frontend import add_motion_budget
    from mtlc.semantics.expand import DEFAULT_BUDGET

    p.add_argument("files", nargs="+", type=Path, metavar="FILE", help=".mtask files")
    p.add_argument(
        "-I", dest="include", action="append", type=Path, default=[], metavar="DIR",
        help="also look for used modules in DIR (after the file's own folder)",
    )  # fmt: skip
    p.add_argument(
        "--expansion-budget", type=_budget, default=DEFAULT_BUDGET, metavar="N",
        help=f"most primitives a task may expand into (default {DEFAULT_BUDGET:,})",
    )  # fmt: skip
    add_motion_budget(p)
    p.add_argument(
        "--manikin", type=_manikin, metavar="POP:SEX:PCT",
        help="override every task's manikin, e.g. gb10000_1988:female:5",
    )  # fmt: skip
    p.add_argument(
        "--format", choices=("text", "json"), default="text",
        help="how diagnostics are printed (json: versioned, for tools)",
    )  # fmt: skip


def _add_check(sub: argparse._SubParsersAction) -> None:
    check = sub.add_parser("check", help="parse, resolve, type-check and expand task files")
    _frontend_options(check)
    check.add_argument(
        "--dump", choices=("ast", "timeline"), help="print the AST or the expanded timeline as JSON"
    )


def _add_compile(sub: argparse._SubParsersAction) -> None:
    from mtlc.codegen import DEFAULT_TARGET, TA_MODES, TARGET_CHOICES  # compile loads them anyway
    from mtlc.passes.context import DEFAULT_FPS

    compile_ = sub.add_parser("compile", help="compile task files into motion outputs")
    _frontend_options(compile_)
    compile_.add_argument("-o", "--output", type=Path, default=Path("out"), metavar="DIR",
                          help="output folder (default: out)")  # fmt: skip
    compile_.add_argument("--target", choices=TARGET_CHOICES, default=DEFAULT_TARGET,
                          help="what to write: jackscript (default: one Python module per file, a function per task), "
                          "bvh, ir (the keyframe IR as JSON), all three, or timeline (the expanded timeline, front end only)")  # fmt: skip
    compile_.add_argument("--ta", choices=TA_MODES, default="keyframes",
                          help="JackScript: approach (TA) segments as explicit keyframes (default, replays exactly) "
                          "or as Jack reach commands solved by Jack's own IK")  # fmt: skip
    compile_.add_argument("--source-map", action="store_true",
                          help="JackScript: also write MODULE.py.map.json, script lines to .mtask source spans")  # fmt: skip
    compile_.add_argument("--metrics", action="store_true",
                          help="print motion metrics per task (penetration, skating, balance, contact error, limits, smoothness)")  # fmt: skip
    compile_.add_argument("--fps", type=_fps, default=DEFAULT_FPS, metavar="N",
                          help=f"frames per second of the sampled motion (default {DEFAULT_FPS:g})")  # fmt: skip
    compile_.add_argument("--walk-clip", type=Path, default=None, metavar="FILE",
                          help="a BVH walking clip: the walks take its gait, adapted to each task (seed 004)")  # fmt: skip


def _add_explain(sub: argparse._SubParsersAction) -> None:
    explain = sub.add_parser("explain", help="show the documentation page of a diagnostic code")
    explain.add_argument("code", metavar="CODE", help="e.g. MT0201")


def _add_lint(sub: argparse._SubParsersAction) -> None:
    from mtlc.lint.command import add_lint_parser

    add_lint_parser(sub)


def _add_report(sub: argparse._SubParsersAction) -> None:
    from mtlc.report.command import add_report_parser

    add_report_parser(sub)


def _add_fmt(sub: argparse._SubParsersAction) -> None:
    from mtlc.fmt.command import add_fmt_parser

    add_fmt_parser(sub)


def _add_preview(sub: argparse._SubParsersAction) -> None:
    from mtlc.preview.command import add_preview_parsers

    add_preview_parsers(sub, _frontend_options)


# in the order `mtlc --help` lists them (preview adds `preview` and `serve`)
_SUBPARSERS: list[tuple[str, Callable[[argparse._SubParsersAction], None]]] = [
    ("check", _add_check),
    ("compile", _add_compile),
    ("explain", _add_explain),
    ("lint", _add_lint),
    ("report", _add_report),
    ("fmt", _add_fmt),
    ("preview", _add_preview),  # and `serve`
]


def _only(words: list[str]) -> str | None:
    """Which command's parser alone parses ``words`` the same as the whole command line."""
    if words[:1] == ["--version"]:
        return ""
    command = "preview" if words[:1] == ["serve"] else (words[0] if words else "")
    return command if command in dict(_SUBPARSERS) else None


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; ``argv`` None: the process's own command line, which ends after it."""
    code = run_command(sys.argv[1:] if argv is None else list(argv))
    if argv is None:
        # The process exits next: its last garbage collection would walk every token, node and
        # primitive still alive (0.5 s of CPU after a 20,000-line `mtlc check`) to free memory
        # the exit frees anyway. Frozen objects are left out of it; nothing else changes.
        gc.freeze()
    return code


def run_command(words: list[str]) -> int:
    """One command's work and exit code (``main`` without the end of the process)."""
    parser = listing_parser() if words in _LISTING_WORDS else build_parser(only=_only(words))
    args = parser.parse_args(words)
    if args.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    try:
        if args.command == "explain":
            return cmd_explain(args.code)
        if args.command == "fmt":
            from mtlc.fmt.command import run_fmt_command

            return run_fmt_command(args)
        if args.command == "lint":
            from mtlc.lint.command import run_lint_command

            return run_lint_command(args)
        if args.command == "report":
            from mtlc.report.command import run_report_command

            return run_report_command(args)
        if args.command in ("preview", "serve"):
            from mtlc.preview.command import run_preview_command

            return run_preview_command(args)
        return cmd_frontend(args)
    except UsageError as exc:
        sys.stderr.write(f"mtlc: {exc}\n")
        return EXIT_USAGE
    except OutputError as exc:  # a command that writes without write_outputs (preview)
        sys.stderr.write(f"mtlc: {terminal_safe(str(exc))}\n")
        return EXIT_USAGE
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # `mtlc check ... | head`: the reader left; not an error of ours
        with contextlib.suppress(OSError):
            sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - silence the flush at exit
        return EXIT_OK
    except Exception as exc:  # a bug: report it as a diagnostic, never as a bare traceback
        if os.environ.get("MTLC_DEBUG"):
            traceback.print_exc()
        sink = DiagnosticSink()
        sink.report(
            "MT0900",
            f"internal error: {type(exc).__name__}: {exc}",
            Span.whole_file(str(getattr(args, "files", ["<command line>"])[0])),
            help="this is a bug in mtlc; rerun with MTLC_DEBUG=1 for the trace and report it",
        )
        if getattr(args, "format", "text") == "json":
            sys.stdout.write(render_json(sink.items))
        else:
            sys.stderr.write(render_text(sink.items, {}, color=use_color(sys.stderr)))
        return EXIT_USAGE


def _options(args: argparse.Namespace) -> FrontendOptions:
    from mtlc.frontend import FrontendOptions

    return FrontendOptions(
        include_dirs=tuple(args.include),
        expansion_budget=args.expansion_budget,
        motion_budget=args.motion_budget,
        manikin=args.manikin,
    )


def _report(program: Program, fmt: str, stdout_taken: bool) -> None:
    diags = program.diagnostics
    if fmt == "json":
        # with --dump the document owns stdout; the diagnostics then go to stderr
        (sys.stderr if stdout_taken else sys.stdout).write(render_json(diags))
    elif diags:
        sys.stderr.write(render_text(diags, program.sources, color=use_color(sys.stderr)))


def _summary(program: Program) -> None:
    tasks = len(program.timelines)
    prims = sum(len(t.primitives) for t in program.timelines)
    sys.stderr.write(
        f"ok: {len(program.roots)} file{'s' if len(program.roots) != 1 else ''}, "
        f"{tasks} task{'s' if tasks != 1 else ''}, {prims:,} primitives\n"
    )


def cmd_frontend(args: argparse.Namespace) -> int:
    from mtlc.frontend import run_frontend

    program = run_frontend(list(args.files), _options(args))
    if args.command == "check":
        return cmd_check(args, program)
    return cmd_compile(args, program)


def cmd_check(args: argparse.Namespace, program: Program) -> int:
    _report(program, args.format, stdout_taken=bool(args.dump))
    failed = program.sink.has_errors
    if args.format == "text" and not failed and not args.dump:
        _summary(program)
    if args.dump == "ast":
        from mtlc.syntax.dump import dump_module

        for module in program.roots:
            sys.stdout.write(dump_module(module.tree))
    elif args.dump == "timeline" and not failed:
        docs = [t.as_dict() for t in program.timelines]
        sys.stdout.write(json.dumps(docs, indent=1, ensure_ascii=False) + "\n")
    return EXIT_ERRORS if failed else EXIT_OK


def cmd_compile(args: argparse.Namespace, program: Program) -> int:
    """Front end, then the motion passes and generators; every output is written, or none."""
    from mtlc.codegen import GenerateOptions, expand_target, generate_file, stem_of
    from mtlc.metrics import compute_metrics, render_metrics
    from mtlc.passes import run_motion

    files: dict[Path, str | bytes] = {}
    measured: list[tuple[str, Metrics]] = []
    clip = getattr(args, "walk_clip", None)
    if clip is not None and not program.sink.has_errors and args.target != "timeline":
        from mtlc.passes.bvh_clip import checked_clip

        checked_clip(clip, program.sink)  # MT0503 before any motion is solved
    if not program.sink.has_errors:
        if args.target == "timeline":
            named = {
                f"{stem_of(t.file)}.{t.task}.timeline.json": t.to_json() for t in program.timelines
            }
            _claim(files, args.output, named, "timeline")
        else:
            options = GenerateOptions(expand_target(args.target), args.ta, args.source_map)
            by_file: dict[str, list[MotionIR]] = {}
            for timeline in program.timelines:
                ir = run_motion(timeline, program.sink, _motion_options(args))
                by_file.setdefault(timeline.file, []).append(ir)
                if args.metrics:
                    measured.append((timeline.task, compute_metrics(ir)))
            for file, irs in by_file.items():
                _claim(files, args.output, generate_file(stem_of(file), irs, options), file)
    _report(program, args.format, stdout_taken=False)
    if program.sink.has_errors:
        return EXIT_ERRORS  # nothing is written: existing outputs stay as they were
    failed = write_outputs(files)
    if failed is not None:
        return failed
    if args.format == "text":
        _summary(program)
        for path in files:
            print(f"wrote {terminal_safe(str(path))}")
    if measured:
        sys.stdout.write(render_metrics(measured))
    return EXIT_OK


def _claim(
    files: dict[Path, str | bytes], folder: Path, named: dict[str, str | bytes], source: str
) -> None:
    """Add outputs under safe names (``safe_file_name``: no newline, U+2028 or U+202E from a
    file or task name reaches the file system), refusing two that would write the same file
    (one would be lost), whether the names were equal or became equal once made safe."""
    for name, data in named.items():
        target = folder / safe_file_name(name)
        if target in files:
            shown = terminal_safe(str(target))
            raise UsageError(
                f"two outputs would both be written to {shown} (the second from "
                f"{terminal_safe(source)}); give the files or the tasks different names, or "
                "compile them into different folders"
            )
        files[target] = data


def _motion_options(args: argparse.Namespace) -> MotionOptions:
    from mtlc.passes import MotionOptions

    return MotionOptions(fps=args.fps, walk_clip=getattr(args, "walk_clip", None))


def cmd_explain(code: str) -> int:
    code = code.upper()
    if code not in CODES:
        sys.stderr.write(f"mtlc: no diagnostic code {code}; codes run from MT0001 to MT0900\n")
        return EXIT_USAGE
    page = resource_dir("diagnostics") / f"{code}.md"
    if page.is_file():
        sys.stdout.write(page.read_text(encoding="utf-8"))
    else:
        c = CODES[code]
        sys.stdout.write(f"# {c.code}: {c.name}\n\n{c.summary}\n")
    return EXIT_OK
