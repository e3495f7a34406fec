"""``python -m backend.cli``: the same as the ``quasitune`` command."""

import sys

from backend.cli import main

sys.exit(main())
