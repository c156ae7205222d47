"""The `preview` and `serve` commands (wired into `mtlc` by the CLI, and `python -m mtlc.preview`).

Exit codes as everywhere in mtlc: 0 clean, 1 errors in the input, 2 a usage or internal error.
"""

from __future__ import annotations

import argparse
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mtlc.diagnostics.render import render_json, render_text, terminal_safe, use_color
from mtlc.frontend import FrontendOptions
from mtlc.output import safe_file_name, write_all_or_nothing
from mtlc.passes import MotionOptions
from mtlc.passes.context import DEFAULT_FPS
from mtlc.preview.compile import Compiled, compile_motions
from mtlc.preview.html import render_page

EXIT_OK, EXIT_ERRORS, EXIT_USAGE = 0, 1, 2
DEFAULT_PORT = 8765
POLL_RANGE = (0.01, 3600.0)  # s: `--poll inf` ended the watcher, `--poll nan` spun a core


def poll_seconds(text: str) -> float:
    """``--poll S``: a finite number of seconds in ``POLL_RANGE`` (argparse says why not, exit 2)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, not {text!r}") from None
    lo, hi = POLL_RANGE
    if not lo <= value <= hi:  # also false for nan
        raise argparse.ArgumentTypeError(f"must be between {lo:g} and {hi:g} seconds")
    return value


def port_number(text: str) -> int:
    """``--port N``: 0 (a free port) to 65535."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a port number, not {text!r}") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError("must be between 0 (a free port) and 65535")
    return value


def add_preview_parsers(
    subparsers: Any, frontend_options: Callable[[argparse.ArgumentParser], None]
) -> None:
    """Add `preview` and `serve` to the CLI's subparsers (``frontend_options`` adds FILE, -I...)."""
    preview = subparsers.add_parser(
        "preview", help="see the motion: a self-contained HTML page and/or a PNG contact sheet"
    )
    frontend_options(preview)
    preview.add_argument("-o", "--output", type=Path, metavar="HTML",
                         help="the HTML page to write, for one task (default: <file stem>.<task>.html per task)")  # fmt: skip
    preview.add_argument("--png", type=Path, metavar="PNG",
                         help="also write a contact sheet: key poses front and side, joint angles over time (needs matplotlib)")  # fmt: skip
    _task_and_fps(preview)
    serve = subparsers.add_parser(
        "serve", help="stream the motion to a browser; recompile on save and when a site is dragged"
    )
    frontend_options(serve)
    serve.add_argument("--host", default="127.0.0.1",
                       help="address to listen on (default 127.0.0.1: this machine only)")  # fmt: skip
    serve.add_argument("--port", type=port_number, default=DEFAULT_PORT,
                       help=f"port (default {DEFAULT_PORT}; 0 picks a free one)")  # fmt: skip
    serve.add_argument("--poll", type=poll_seconds, default=0.5, metavar="S",
                       help="how often to look for a saved file, in seconds (0.01 to 3600, default 0.5)")  # fmt: skip
    _task_and_fps(serve)


def _task_and_fps(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--task", metavar="NAME", help="only this task (default: every task; serve: the first)"
    )
    p.add_argument("--fps", type=float, default=DEFAULT_FPS, metavar="N",
                   help=f"frames per second of the sampled motion (default {DEFAULT_FPS:g})")  # fmt: skip


def _options(args: argparse.Namespace) -> FrontendOptions:
    return FrontendOptions(
        include_dirs=tuple(args.include),
        expansion_budget=args.expansion_budget,
        motion_budget=args.motion_budget,
        manikin=args.manikin,
    )


def _report(compiled: Compiled, fmt: str) -> None:
    items = compiled.program.diagnostics
    if fmt == "json":
        sys.stdout.write(render_json(items))
    elif items:
        sources = compiled.program.sources
        sys.stderr.write(render_text(items, sources, color=use_color(sys.stderr)))


def run_preview_command(args: argparse.Namespace) -> int:
    """Run `preview` or `serve` from parsed arguments; returns the exit code."""
    if not 1 <= args.fps <= 1000:
        sys.stderr.write("mtlc: --fps must be between 1 and 1000\n")
        return EXIT_USAGE
    if args.command == "serve":
        return _serve(args)
    return _preview(args)


Target = tuple[Path | None, Path | None]  # a task's page and sheet


class TargetError(ValueError):
    """Outputs that cannot be named as asked (a usage error, exit 2)."""


def _targets(args: argparse.Namespace, compiled: Compiled) -> dict[tuple[str, str], Target]:
    """Where each task's page and sheet go, by (file, task): ``-o``/``--png`` name one task's
    outputs; without them each task's page is ``<file stem>.<task>.html``. Keyed by the task
    name alone, two files' pages silently overwrote each other."""
    many = len(compiled.motions) > 1
    if many and (args.output is not None or args.png is not None):
        tasks = ", ".join(f"{Path(ir.file).name}:{ir.task}" for ir in compiled.motions)
        raise TargetError(
            f"-o/--png name one task's outputs, but there are {len(compiled.motions)} ({tasks});"
            " pick one with --task NAME, or leave out -o and --png to get <file>.<task>.html"
        )
    out: dict[tuple[str, str], Target] = {}
    for ir in compiled.motions:
        html = args.output
        if args.output is None and args.png is None:
            html = Path(safe_file_name(f"{Path(ir.file).stem}.{ir.task}.html"))
        out[(ir.file, ir.task)] = (html, args.png)
    _refuse_collisions(out)
    return out


def _refuse_collisions(targets: dict[tuple[str, str], Target]) -> None:
    """Two tasks writing the same path (same task name in two files of the same stem)."""
    seen: dict[Path, tuple[str, str]] = {}
    for key, paths in targets.items():
        for path in paths:
            if path is None:
                continue
            other = seen.setdefault(path.resolve(), key)
            if other != key:
                raise TargetError(
                    f"{other[0]}:{other[1]} and {key[0]}:{key[1]} would both write {path};"
                    " run them separately with -o"
                )


def _preview(args: argparse.Namespace) -> int:
    motion = MotionOptions(fps=args.fps)
    compiled = compile_motions(list(args.files), _options(args), motion, task=args.task)
    _report(compiled, args.format)
    if not compiled.ok:
        return EXIT_ERRORS
    if not compiled.motions:
        sys.stderr.write(f"mtlc: no task named {args.task!r}\n" if args.task else "mtlc: no task\n")
        return EXIT_USAGE
    files: dict[Path, str | bytes] = {}
    try:
        targets = _targets(args, compiled)
    except TargetError as exc:
        sys.stderr.write(f"mtlc: {terminal_safe(str(exc))}\n")
        return EXIT_USAGE
    for ir, doc in zip(compiled.motions, compiled.documents(), strict=True):
        html, png = targets[(ir.file, ir.task)]
        if html is not None:
            files[html] = render_page(doc)
        if png is not None:
            from mtlc.preview.sheet import MissingMatplotlib, render_sheet

            try:
                files[png] = render_sheet(ir)
            except MissingMatplotlib as exc:
                sys.stderr.write(f"mtlc: {exc}\n")
                return EXIT_USAGE
    write_all_or_nothing(files)
    if args.format == "text":
        for path in files:
            print(f"wrote {terminal_safe(str(path))}")
    return EXIT_OK


def _serve(args: argparse.Namespace) -> int:
    from mtlc.preview.server import MotionHub, PreviewServer

    if not 0 <= args.port <= 65535 or not POLL_RANGE[0] <= args.poll <= POLL_RANGE[1]:
        sys.stderr.write("mtlc: --port must be 0..65535 and --poll 0.01..3600 seconds\n")
        return EXIT_USAGE
    hub = MotionHub(list(args.files), _options(args), MotionOptions(fps=args.fps), task=args.task)
    server = PreviewServer(hub, host=args.host, port=args.port, poll=args.poll)
    try:
        server.start()
    except OSError as exc:
        sys.stderr.write(f"mtlc: cannot listen on {args.host}:{args.port}: {exc.strerror}\n")
        return EXIT_USAGE
    if hub.last_diagnostics is not None:
        sys.stderr.write("mtlc: the first compile failed; fix the file and save it\n")
    names = terminal_safe(", ".join(map(str, args.files)))
    print(f"serving {names} at {server.url} (Ctrl-C stops)", flush=True)
    try:
        threading.Event().wait()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
    return EXIT_OK
