"""``python -m rrfrei.app ...``: the ``rrfrei`` command."""

import sys

from rrfrei.app.cli import main

sys.exit(main())
