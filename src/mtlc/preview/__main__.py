"""`python -m mtlc.preview {preview,serve} FILE ...`: the same as `mtlc preview|serve ...`."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from mtlc.cli import main as cli_main


def main(argv: Sequence[str] | None = None) -> int:
    return cli_main(list(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    sys.exit(main())
