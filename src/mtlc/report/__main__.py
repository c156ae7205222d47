"""`python -m mtlc.report FILE...`: the same as `mtlc report FILE...`."""

import sys

from mtlc.report.command import main

sys.exit(main())
