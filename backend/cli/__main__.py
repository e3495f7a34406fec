"""``python -m backend.cli``: the same as the ``quasitune`` command."""

import sys

from backend.cli import main

if __name__ == "__main__":      # a process the bench's pool spawns imports this module too
    sys.exit(main())
