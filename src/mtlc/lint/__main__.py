"""`python -m mtlc.lint PATH...`: the same as `mtlc lint PATH...`."""

import sys

from mtlc.lint.command import main

sys.exit(main())
