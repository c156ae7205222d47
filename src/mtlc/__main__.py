"""`python -m mtlc` runs the command-line interface."""

from mtlc.cli import main

raise SystemExit(main())
