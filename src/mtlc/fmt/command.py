"""`mtlc fmt [--check | --diff] PATH...`: format files in place, or say which would change.

Exit codes, as for every mtlc command: 0 clean (nothing to change, or everything written),
1 a file has syntax errors or (with --check/--diff) would change, 2 a usage or internal error.
"""

from __future__ import annotations

import argparse
import difflib
import io
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mtlc.diagnostics import Diagnostic, DiagnosticSink
from mtlc.diagnostics.render import render_json, render_text, use_color
from mtlc.fmt import format_source
from mtlc.output import write_outputs
from mtlc.semantics.modules import (
    MAX_FILE_BYTES,
    decode_source,
    probe,
    read_bounded_stream,
    read_source,
)

EXIT_OK, EXIT_ERRORS, EXIT_USAGE = 0, 1, 2
STDIN = "-"
STDIN_NAME = "<stdin>"


@dataclass
class _Outcome:
    display: str
    original: str
    formatted: str | None  # None: refused (see the diagnostics)


def add_fmt_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register `fmt` on the CLI's subparsers (``parser.add_subparsers(...)``)."""
    fmt = subparsers.add_parser(
        "fmt",
        help="format .mtask files canonically (keeps comments, never changes meaning)",
        description="Format .mtask files in place. Directories are searched for *.mtask; "
        "`-` reads standard input and writes standard output.",
    )
    fmt.add_argument("paths", nargs="+", metavar="PATH", help=".mtask files, folders, or -")
    mode = fmt.add_mutually_exclusive_group()
    mode.add_argument(
        "--check", action="store_true", help="write nothing; list the files that would change"
    )
    mode.add_argument(
        "--diff", action="store_true", help="write nothing; print what would change as a diff"
    )
    fmt.add_argument(
        "--format",
        choices=("text", "json"),
        default="text",
        help="how diagnostics are printed (json: versioned, for tools)",
    )
    return fmt


def run_fmt_command(args: argparse.Namespace) -> int:
    sink = DiagnosticSink()
    sources: dict[str, str] = {}
    outcomes = [_format_one(path, sink, sources) for path in _expand(args.paths)]
    done = [o for o in outcomes if o is not None]
    changed = [o for o in done if o.formatted is not None and o.formatted != o.original]
    _report(sink.items, sources, args.format)
    if args.check or args.diff:
        _show_changes(changed, diff=args.diff)
    else:
        failed = _write([o for o in changed if o.display != STDIN_NAME])
        if failed is not None:
            return failed
        for o in done:
            if o.display == STDIN_NAME and o.formatted is not None:
                sys.stdout.write(o.formatted)
    if any(d.code == "MT0900" for d in sink.items):
        return EXIT_USAGE
    if sink.has_errors or ((args.check or args.diff) and changed):
        return EXIT_ERRORS
    return EXIT_OK


def _expand(paths: list[str]) -> list[str]:
    """Files to format: each path given, and each *.mtask under a folder, in sorted order;
    a file reached twice (also through a symlink) is formatted once."""
    found: list[str] = []
    for raw in paths:
        path = Path(raw)
        if raw != STDIN and probe(path, Path.is_dir):
            found.extend(p.as_posix() for p in sorted(path.rglob("*.mtask")) if p.is_file())
        else:
            found.append(raw if raw == STDIN else path.as_posix())
    by_file: dict[str, str] = {}
    for name in found:
        by_file.setdefault(name if name == STDIN else os.path.realpath(name), name)
    return list(by_file.values())


def _format_one(raw: str, sink: DiagnosticSink, sources: dict[str, str]) -> _Outcome | None:
    if raw == STDIN:
        display = STDIN_NAME
        stream = getattr(sys.stdin, "buffer", None)  # a text stream has none (tests, embedding)
        if stream is None:
            stream = io.BytesIO(sys.stdin.read(MAX_FILE_BYTES + 1).encode("utf-8", "surrogatepass"))
        data = read_bounded_stream(stream, display, sink)
        decoded = decode_source(data, display, sink) if data is not None else None
        if decoded is None:
            return None
        text = decoded
    else:
        display = Path(raw).as_posix()
        read = read_source(Path(raw), display, sink)
        if read is None:
            return None
        text = read
    sources[display] = text
    result = format_source(text, display)
    sink.items.extend(result.diagnostics)
    return _Outcome(display, text, result.text)


def _report(diagnostics: list[Diagnostic], sources: dict[str, str], fmt: str) -> None:
    if fmt == "json":
        sys.stderr.write(render_json(diagnostics))
    elif diagnostics:
        sys.stderr.write(render_text(diagnostics, sources, color=use_color(sys.stderr)))


def _show_changes(changed: list[_Outcome], *, diff: bool) -> None:
    for outcome in changed:
        assert outcome.formatted is not None
        if diff:
            sys.stdout.write(unified_diff(outcome.original, outcome.formatted, outcome.display))
        else:
            sys.stdout.write(f"{outcome.display}\n")
    if changed:
        count = len(changed)
        sys.stderr.write(f"{count} file{'s' if count != 1 else ''} would be reformatted\n")


def unified_diff(original: str, formatted: str, display: str) -> str:
    """A patch that `patch` and `git apply` take: lines are what ends in `\\n` (as for them; a
    CR, form feed or U+2028 is just a character of its line), a last line without one is
    marked, and an absolute path is not given an `a/` prefix (which would read `a//tmp/...`)."""
    old, new = _patch_lines(original), _patch_lines(formatted)
    relative = not display.startswith("/")
    before, after = (f"a/{display}", f"b/{display}") if relative else (display, display)
    out = []
    for line in difflib.unified_diff(old, new, before, after):
        out.append(line if line.endswith("\n") else line + "\n\\ No newline at end of file\n")
    return "".join(out)


def _patch_lines(text: str) -> list[str]:
    lines = text.split("\n")
    return [line + "\n" for line in lines[:-1]] + ([lines[-1]] if lines[-1] else [])


def _write(changed: list[_Outcome]) -> int | None:
    """The changed files are written together, atomically: all of them or none (then the exit
    code). A symlink is written through to its file, which keeps its permissions."""
    files: dict[Path, str | bytes] = {}
    for outcome in changed:
        assert outcome.formatted is not None
        files[Path(outcome.display)] = outcome.formatted
    failed = write_outputs(files, "mtlc fmt")
    if failed is not None:
        return failed
    for path in files:
        sys.stderr.write(f"reformatted {path.as_posix()}\n")
    return None
