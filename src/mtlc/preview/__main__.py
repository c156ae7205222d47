"""`python -m mtlc.preview {preview,serve} FILE ...` until the commands are wired into `mtlc`."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from mtlc.preview.command import EXIT_USAGE, add_preview_parsers, run_preview_command
from mtlc.semantics.expand import DEFAULT_BUDGET


def _frontend_options(p: argparse.ArgumentParser) -> None:
    """The CLI's shared options (FILE, -I, --expansion-budget, --manikin, --format)."""
    from mtlc.cli import _budget, _manikin

    p.add_argument("files", nargs="+", type=Path, metavar="FILE", help=".mtask files")
    p.add_argument("-I", dest="include", action="append", type=Path, default=[], metavar="DIR")
    p.add_argument("--expansion-budget", type=_budget, default=DEFAULT_BUDGET, metavar="N")
    p.add_argument("--manikin", type=_manikin, metavar="POP:SEX:PCT")
    p.add_argument("--format", choices=("text", "json"), default="text")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mtlc.preview")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    add_preview_parsers(sub, _frontend_options)
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    return run_preview_command(args)


if __name__ == "__main__":
    sys.exit(main())
