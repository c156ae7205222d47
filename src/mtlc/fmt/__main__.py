"""`python -m mtlc.fmt ...`: the `mtlc fmt` command on its own (the same options and exit codes)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from mtlc.fmt.command import EXIT_USAGE, add_fmt_parser, run_fmt_command


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="mtlc")
    add_fmt_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["fmt", *(sys.argv[1:] if argv is None else argv)])
    try:
        return run_fmt_command(args)
    except OSError as err:  # a file that cannot be written: nothing was changed
        sys.stderr.write(f"mtlc fmt: {err}\n")
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
