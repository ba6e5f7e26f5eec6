"""``python -m rrfrei.app ...``: the ``rrfrei`` command."""

import sys

from rrfrei.app.cli import main

if __name__ == "__main__":  # guarded: spawned / forkserver workers import this module as __mp_main__
    sys.exit(main())
